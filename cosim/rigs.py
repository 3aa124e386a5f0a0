"""Sensor rig presets, chosen with the scenario key ``rig`` (``--set rig=kitti``); the scenario's
own ``sensors`` keys are laid over the preset, so any part of it can still be changed.

- ``default``: the rig of ``sensors/`` (64-beam LiDAR, a 1280x720 camera, a front radar).
- ``kitti``: the KITTI recording car (Geiger et al., "Vision meets Robotics: The KITTI
  Dataset", IJRR 2013, figure 3 and the raw data's calibration files): a Velodyne HDL-64E
  1.73 m above the ground, its 64 beams at the HDL-64E's elevations (upper block +2.0 to
  -8.33 deg in 1/3 deg steps, lower block -8.83 to -24.33 deg in 1/2 deg steps, HDL-64E S2
  manual), 10 Hz; two colour cameras (KITTI's cam2 and cam3) 1.65 m high and 0.27 m ahead of
  the LiDAR, 0.06 m left and 0.47 m right of the grey reference camera above it, 1242x375
  pixels with a focal length of 721.5 px (81.4 deg across); no radar. The preset also sets
  ``step_s: 0.1`` (KITTI's 10 Hz) unless the scenario sets it. The LiDAR sweeps in time
  (``sweep: timed``, HDL-64E firing, :mod:`sensors.sweep`); the frame's time and its boxes are at
  the sweep's middle, when the laser faces forward and KITTI's cameras fire. Its intensity reads
  as KITTI's does (``intensity: kitti``, fitted to real KITTI scans: ``sensors.lidar``).
- ``nuscenes``: the nuScenes car (Caesar et al., "nuScenes: A multimodal dataset for
  autonomous driving", CVPR 2020, table 1 and figure 4), mounts and focal lengths from the
  published calibration (v1.0-mini ``calibrated_sensor.json``, log n015,
  singapore-hollandvillage): six 1600x900 cameras at 12 Hz (the focal length of each gives its
  field of view; the principal point is put at the image centre), a 32-beam LIDAR_TOP at the
  HDL-32E's elevations (-30.67 to +10.67 deg in 4/3 deg steps, HDL-32E manual), 20 Hz,
  70 m, 1084 firings per turn, with nuScenes's LiDAR axes (x right, y forward), sweeping in time
  (HDL-32E firing; the frame's time and its boxes at the sweep's end, as nuScenes stamps a sweep
  when its rotation is complete; its LIDAR_TOP files hold the deskewed points, as nuScenes's are
  ego-motion compensated), and five
  Continental ARS 408 radars at 13 Hz (250 m, +-60 deg near field). nuScenes's ego origin is
  the rear axle, ours the footprint centre: every mount moves back by ``NUSCENES_REAR_AXLE_X_M``
  so RADAR_FRONT sits at the front bumper as on the nuScenes car. The preset also turns on
  ``outputs.nuscenes`` and turns off ``outputs.kitti`` (KITTI pairs one camera with one LiDAR
  at the same rate) unless the scenario sets them.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from networks.geometry import rotation_from_quaternion_xyzw, rpy_from_rotation
from sensors.pinhole import EGO_AXES_R_OPTICAL

_UPPER = [2.0 - k / 3.0 for k in range(32)]  # +2.0 .. -8.33
_LOWER = [-8.83 - k / 2.0 for k in range(32)]  # -8.83 .. -24.33
HDL64E_ELEVATIONS_DEG = tuple(round(e, 3) for e in sorted(_UPPER + _LOWER))
# Returns by received power (sensors.lidar.Lidar.detection_probability): HDL-64E S2, "50 m for
# pavement (about 10 % reflectivity), 120 m for cars and foliage (about 80 %)" (Velodyne HDL-64E S2
# data sheet): the two agree with the inverse-square law. HDL-32E: "80 m to 100 m" with no
# reflectivity given (HDL-32E data sheet); taken as 100 m for 80 %, so 35 m for 10 %.
HDL64E_RANGE_10PCT_M = 50.0
HDL32E_RANGE_10PCT_M = 35.0
# The HDL-32E's spot: "approximately 4 inches wide by 2 inches tall at 100 feet" (HDL-32E user's
# manual, appendix D, laser spot size): 3.3 x 1.7 mrad. The sensor has strongest, last and dual
# return modes (same manual); nuScenes's sweeps hold one return a shot. A scenario may set
# LIDAR_TOP's beam_divergence_mrad to this (mixed returns at depth edges, sensors.beam) and
# returns: dual; the preset does not, since an edge's echo reaches out beyond its surface by half
# a spot (0.8 cm at 10 m, 5.8 cm at 70 m) and labels' boxes would no longer hold every object
# point within 2 cm. The HDL-64E S2 of the kitti preset reports one return a shot.
HDL32E_SPOT_MRAD = (3.3, 1.7)
KITTI_FOCAL_PX = 721.5377
KITTI_IMAGE = (1242, 375)
KITTI_HFOV_DEG = round(math.degrees(2.0 * math.atan(KITTI_IMAGE[0] / 2.0 / KITTI_FOCAL_PX)), 3)

HDL32E_ELEVATIONS_DEG = tuple(round((k * 4.0 - 92.0) / 3.0, 2) for k in range(32))  # -30.67 .. +10.67
NUSCENES_IMAGE = (1600, 900)
NUSCENES_REAR_AXLE_X_M = -1.412  # where nuScenes's ego origin lies in ours
# channel: translation (m, from the rear axle), rotation (w, x, y, z) of the sensor frame (cameras:
# optical) in nuScenes's ego frame, and for cameras the focal length in pixels (n015).
NUSCENES_CAMERAS = {
    "CAM_FRONT": (
        (1.70079118954, 0.0159456324149, 1.51095763913),
        (0.4998015430569128, -0.5030316162024876, 0.4997798114386805, -0.49737083824542755),
        1266.417203046554,
    ),
    "CAM_FRONT_RIGHT": (
        (1.5508477543, -0.493404796419, 1.49574800619),
        (0.2060347966337182, -0.2026940577919598, 0.6824507824531167, -0.6713610884174485),
        1260.8474446004698,
    ),
    "CAM_BACK_RIGHT": (
        (1.0148780988, -0.480568219723, 1.56239545128),
        (0.12280980120078765, -0.132400842670559, -0.7004305821388234, 0.690496031265798),
        1259.5137405846733,
    ),
    "CAM_BACK": (
        (0.0283260309358, 0.00345136761476, 1.57910346144),
        (0.5037872666382278, -0.49740249788611096, -0.4941850223835201, 0.5045496097725578),
        809.2209905677063,
    ),
    "CAM_BACK_LEFT": (
        (1.03569100218, 0.484795032713, 1.59097014818),
        (0.6924185592174665, -0.7031619420114925, -0.11648342771943819, 0.11203317912370753),
        1256.7414812095406,
    ),
    "CAM_FRONT_LEFT": (
        (1.52387798135, 0.494631336551, 1.50932822144),
        (0.6757265034669446, -0.6736266522251881, 0.21214015046209478, -0.21122827103904068),
        1272.5979470598488,
    ),
}
NUSCENES_LIDAR = (
    (0.943713, 0.0, 1.84023),
    (0.7077955119163518, -0.006492242056004365, 0.010646214713995808, -0.7063073142877817),
)
NUSCENES_RADARS = {  # pitch and roll are 0: (translation, yaw in degrees)
    "RADAR_FRONT": ((3.412, 0.0, 0.5), 0.200),
    "RADAR_FRONT_LEFT": ((2.422, 0.8, 0.78), 88.360),
    "RADAR_FRONT_RIGHT": ((2.422, -0.8, 0.77), -90.980),
    "RADAR_BACK_LEFT": ((-0.562, 0.628, 0.53), 174.410),
    "RADAR_BACK_RIGHT": ((-0.562, -0.618, 0.53), -176.110),
}


def nuscenes_hfov_deg(focal_px: float) -> float:
    """The horizontal field of view of a 1600 px wide nuScenes camera of this focal length."""
    return round(math.degrees(2.0 * math.atan(NUSCENES_IMAGE[0] / 2.0 / focal_px)), 4)


def _mount(
    translation: tuple[float, float, float], wxyz: tuple[float, float, float, float], optical: bool = False
) -> dict[str, list[float]]:
    """A nuScenes mount as ours: position from our origin, body roll/pitch/yaw in degrees."""
    w, x, y, z = wxyz
    rotation = rotation_from_quaternion_xyzw(x, y, z, w)
    if optical:  # the camera body (x forward) from its optical frame
        rotation = rotation @ EGO_AXES_R_OPTICAL.T
    xyz = [translation[0] + NUSCENES_REAR_AXLE_X_M, translation[1], translation[2]]
    return {
        "mount_xyz_m": [round(v, 6) for v in xyz],
        "mount_rpy_deg": [round(float(np.degrees(a)), 6) for a in rpy_from_rotation(rotation)],
    }


def _nuscenes() -> dict[str, Any]:
    width, height = NUSCENES_IMAGE
    cameras = [{"name": name, "width_px": width, "height_px": height, "rate_hz": 12.0,
                "hfov_deg": nuscenes_hfov_deg(focal), **_mount(t, q, optical=True)}
               for name, (t, q, focal) in NUSCENES_CAMERAS.items()]  # fmt: skip
    lidar = {"name": "LIDAR_TOP", "beams": 32, "elevations_deg": list(HDL32E_ELEVATIONS_DEG),
             "vertical_min_deg": HDL32E_ELEVATIONS_DEG[0], "vertical_max_deg": HDL32E_ELEVATIONS_DEG[-1],
             "azimuth_steps": 1084, "range_m": 70.0, "rate_hz": 20.0, "sweep": "timed", "firing": "hdl32e",
             "reference": "end", "deskew": True, "range_10pct_m": HDL32E_RANGE_10PCT_M,
             **_mount(*NUSCENES_LIDAR)}  # fmt: skip
    radars = []
    for name, (t, yaw_deg) in NUSCENES_RADARS.items():
        half = math.radians(yaw_deg) / 2.0
        radars.append(
            {
                "name": name,
                "hfov_deg": 120.0,
                "vfov_deg": 20.0,
                "range_m": 250.0,
                "rate_hz": 13.0,
                "points_per_frame": 125,
                **_mount(t, (math.cos(half), 0.0, 0.0, math.sin(half))),
            }
        )
    return {"lidars": [lidar], "cameras": cameras, "radars": radars}


PRESETS: dict[str, dict[str, Any]] = {
    "default": {},
    "kitti": {
        "lidars": [{"name": "lidar", "beams": 64, "elevations_deg": list(HDL64E_ELEVATIONS_DEG),
                    "vertical_min_deg": HDL64E_ELEVATIONS_DEG[0], "vertical_max_deg": HDL64E_ELEVATIONS_DEG[-1],
                    "azimuth_steps": 2048, "range_m": 120.0, "rate_hz": 10.0, "mount_xyz_m": [0.0, 0.0, 1.73],
                    "sweep": "timed", "firing": "hdl64e", "reference": "middle",
                    "range_10pct_m": HDL64E_RANGE_10PCT_M, "intensity": "kitti"}],
        "cameras": [
            {"name": "cam2", "width_px": KITTI_IMAGE[0], "height_px": KITTI_IMAGE[1], "hfov_deg": KITTI_HFOV_DEG,
             "mount_xyz_m": [0.27, 0.06, 1.65], "rate_hz": 10.0},
            {"name": "cam3", "width_px": KITTI_IMAGE[0], "height_px": KITTI_IMAGE[1], "hfov_deg": KITTI_HFOV_DEG,
             "mount_xyz_m": [0.27, -0.47, 1.65], "rate_hz": 10.0},
        ],
        "radars": [],
    },
    "nuscenes": _nuscenes(),
}  # fmt: skip
# Scenario keys a preset sets unless the scenario sets them itself.
PRESET_DEFAULTS: dict[str, dict[str, Any]] = {
    "kitti": {"step_s": 0.1},
    "nuscenes": {"outputs": {"nuscenes": True, "kitti": False}},
}


def _merged(preset: list[dict[str, Any]], own: list[Any]) -> list[Any]:
    """The preset's sensors with the scenario's laid over them: an entry naming a preset sensor
    edits it key by key, any other entry is added."""
    out: list[Any] = [dict(entry) for entry in preset]
    names = [entry.get("name") for entry in preset]
    for entry in own:
        if isinstance(entry, dict) and entry.get("name") in names:
            at = names.index(entry["name"])
            out[at] = {**out[at], **entry}
        else:
            out.append(entry)
    return out


def with_rig(data: dict[str, Any]) -> dict[str, Any]:
    """The scenario data with its ``rig`` preset's sensors under its own ``sensors`` keys (an
    unknown preset is left to the scenario's check, which names the known ones)."""
    name = data.get("rig", "default")
    if not isinstance(name, str) or name not in PRESETS:
        return data
    own = data.get("sensors") or {}
    if not isinstance(own, dict):
        return data  # the scenario's own check names the wrong type
    sensors = dict(PRESETS[name])
    for kind, entries in own.items():
        preset = sensors.get(kind)
        if isinstance(preset, list) and isinstance(entries, list) and entries:
            sensors[kind] = _merged(preset, entries)
        else:
            sensors[kind] = entries
    out = {**data, "sensors": sensors}
    for key, value in PRESET_DEFAULTS.get(name, {}).items():
        mine = out.get(key)
        if isinstance(value, dict) and (mine is None or isinstance(mine, dict)):
            out[key] = {**value, **(mine or {})}
        elif key not in out:
            out[key] = value
    return out
