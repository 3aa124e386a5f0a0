"""Sensor rig presets, chosen with the scenario key ``rig`` (``--set rig=kitti``); the scenario's
own ``sensors`` keys are laid over the preset, so any part of it can still be changed.

- ``default``: the rig of ``sensors/`` (64-beam LiDAR, a 1280x720 camera, a front radar).
- ``kitti``: the KITTI recording car (Geiger et al., "Vision meets Robotics: The KITTI
  Dataset", IJRR 2013, figure 3 and the raw data's calibration files): a Velodyne HDL-64E
  1.73 m above the ground, its 64 beams at the HDL-64E's elevations (upper block +2.0 to
  -8.33 deg in 1/3 deg steps, lower block -8.83 to -24.33 deg in 1/2 deg steps, HDL-64E S2
  manual), 10 Hz; two colour cameras (KITTI's cam2 and cam3) 1.65 m high and 0.27 m ahead of
  the LiDAR, 0.06 m left and 0.47 m right of the grey reference camera above it, 1242x375
  pixels with a focal length of 721.5 px (81.4 deg across); no radar.
"""

from __future__ import annotations

import math
from typing import Any

_UPPER = [2.0 - k / 3.0 for k in range(32)]  # +2.0 .. -8.33
_LOWER = [-8.83 - k / 2.0 for k in range(32)]  # -8.83 .. -24.33
HDL64E_ELEVATIONS_DEG = tuple(round(e, 3) for e in sorted(_UPPER + _LOWER))
KITTI_FOCAL_PX = 721.5377
KITTI_IMAGE = (1242, 375)
KITTI_HFOV_DEG = round(math.degrees(2.0 * math.atan(KITTI_IMAGE[0] / 2.0 / KITTI_FOCAL_PX)), 3)

PRESETS: dict[str, dict[str, Any]] = {
    "default": {},
    "kitti": {
        "lidars": [{"name": "lidar", "beams": 64, "elevations_deg": list(HDL64E_ELEVATIONS_DEG),
                    "vertical_min_deg": HDL64E_ELEVATIONS_DEG[0], "vertical_max_deg": HDL64E_ELEVATIONS_DEG[-1],
                    "azimuth_steps": 2048, "range_m": 120.0, "rate_hz": 10.0, "mount_xyz_m": [0.0, 0.0, 1.73]}],
        "cameras": [
            {"name": "cam2", "width_px": KITTI_IMAGE[0], "height_px": KITTI_IMAGE[1], "hfov_deg": KITTI_HFOV_DEG,
             "mount_xyz_m": [0.27, 0.06, 1.65], "rate_hz": 10.0},
            {"name": "cam3", "width_px": KITTI_IMAGE[0], "height_px": KITTI_IMAGE[1], "hfov_deg": KITTI_HFOV_DEG,
             "mount_xyz_m": [0.27, -0.47, 1.65], "rate_hz": 10.0},
        ],
        "radars": [],
    },
}  # fmt: skip


def with_rig(data: dict[str, Any]) -> dict[str, Any]:
    """The scenario data with its ``rig`` preset's sensors under its own ``sensors`` keys (an
    unknown preset is left to the scenario's check, which names the known ones)."""
    name = data.get("rig", "default")
    if not isinstance(name, str) or name not in PRESETS:
        return data
    own = data.get("sensors") or {}
    if not isinstance(own, dict):
        return data  # the scenario's own check names the wrong type
    return {**data, "sensors": {**PRESETS[name], **own}}
