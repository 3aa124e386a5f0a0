"""``nuscenes/``: the run in the nuScenes v1.0 layout (see :mod:`gtgen.nuscenes`).

Each frame writes the files of the sensors that fired in it, under ``samples/<CHANNEL>/``
when the file is its channel's keyframe (the firing nearest a LiDAR keyframe, every 0.5 s)
and ``sweeps/<CHANNEL>/`` otherwise, and one record ``rows/<frame>.json`` with what the
tables need (ego pose, files, and at keyframes the annotations), and for a ``LIDAR_TOP``
keyframe sweep ``rows/<frame>.lidar.npz`` (``semantic_class`` and ``instance_id`` per point,
for the point labels). The tables, ``lidarseg/`` and ``panoptic/`` are built from these records
when the run closes, so a run that stops keeps its frames and one that continues takes up
where they end; ``rows/`` and ``calibration.json`` (each sensor's ``calibrated_sensor``
values) stay beside them for that.
"""

from __future__ import annotations

import json
import shutil
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from gtgen.counting import count_hits
from gtgen.frame import FrameRecord
from gtgen.npz import npz_bytes
from gtgen.nuscenes import (
    KEYFRAME_S,
    TEST_VERSION,
    TRAFFIC_CONTROL,
    VERSION,
    attribute_of,
    calibration_record,
    category_of,
    channel_of,
    quaternion_wxyz,
    radar_pcd,
    visibility_level,
    write_tables,
)
from gtgen.objects import EXPORT_MARGIN_M
from gtgen.sinks.folder import PartialFolder
from gtgen.sinks.images import JPEG_QUALITY, FrameImages
from gtgen.table import subtypes as body_subtypes
from networks.classes import SemanticClass
from networks.geometry import SE3
from networks.vocabulary import SensorKind
from sensors.camera import CameraOutput
from sensors.lidar import LidarOutput, LidarScan
from sensors.radar import RadarOutput
from sensors.sensor import SensorOutput, fires


@dataclass(frozen=True, slots=True)
class NuscenesSetup:
    """What the export needs to know of the run: its name (the log and scene names), the
    frame step, each sensor's (kind, name, rate) in rig order, the map file (``map/map.json``
    of the network, or None) and the network's name (the log's location)."""

    name: str
    step_s: float
    sensors: tuple[tuple[SensorKind, str, float], ...]
    location: str
    map_json: Path | None = None


def keyframe_of(rate_hz: float, step_s: float, frame_index: int) -> int | None:
    """The keyframe (frame index) whose sample this firing belongs to as its channel's
    keyframe, or None: a sensor's keyframe is its firing nearest the LiDAR keyframe (the
    earlier on a tie)."""
    every = round(KEYFRAME_S / step_s)
    key = round(frame_index / every) * every
    near = [g for g in range(max(key - every + 1, 0), key + every) if fires(rate_hz, step_s, g)]
    best = min(near, key=lambda g: (abs(g - key), g))
    return key if best == frame_index else None


class NuscenesSink:
    def __init__(self, folder: Path, setup: NuscenesSetup, keep_frames: int = 0) -> None:
        self._setup = setup
        partial = folder.with_name(folder.name + ".partial")
        if keep_frames > 0:
            if not partial.exists() and folder.exists():
                folder.replace(partial)
            _drop_after(partial, keep_frames)
        self._folder = PartialFolder(folder, ("rows",), keep_frames)
        self._rates = {name: rate for _, name, rate in setup.sensors}
        lidars = [name for kind, name, _ in setup.sensors if kind == SensorKind.LIDAR]
        self._channels = {name: channel_of(kind, name, first=lidars[:1] == [name]) for kind, name, _ in setup.sensors}
        self._lidar_channel = "LIDAR_TOP"
        calibration = self._folder.partial / "calibration.json"
        self._calibration: dict[str, Any] = json.loads(calibration.read_text()) if calibration.exists() else {}
        for where in ("samples", "sweeps"):
            for channel in self._channels.values():
                (self._folder.partial / where / channel).mkdir(parents=True, exist_ok=True)
        self._scene = _last_scene(self._folder.partial / "rows", keep_frames)

    def encode(self, record: FrameRecord, images: FrameImages) -> dict[str, bytes]:
        """The frame's files and its record, by path relative to the ``nuscenes`` folder."""
        setup = self._setup
        if record.scene_cut and record.frame_index > 0:
            self._scene += 1
        stamp_us = record.timestamp_ns // 1000
        files: dict[str, bytes] = {}
        data: list[dict[str, Any]] = []
        radar_counts: dict[str, dict[str, int]] = {}
        cameras = list(record.cameras)
        camera_index = {c.spec.name: i for i, c in enumerate(cameras)}
        map_R_ego = record.map_SE3_ego.rotation
        ego_velocity_ego = map_R_ego.T @ np.asarray(record.ego_velocity_map_mps, np.float64)
        for output in record.sensors:
            name = output.spec.name
            channel = self._channels[name]
            if channel not in self._calibration:
                self._calibration[channel] = _calibration(channel, output)
                files["calibration.json"] = json.dumps(self._calibration, indent=1, sort_keys=True).encode()
            key = keyframe_of(self._rates[name], setup.step_s, record.frame_index)
            where = "samples" if key is not None else "sweeps"
            stem = f"{where}/{channel}/{setup.name}__{channel}__{stamp_us}"
            entry: dict[str, Any] = {"channel": channel, "key": key, "width": 0, "height": 0}
            if isinstance(output, CameraOutput):
                entry.update(
                    filename=f"{stem}.jpg", fileformat="jpg", width=output.spec.width_px, height=output.spec.height_px
                )
                files[entry["filename"]] = images.jpeg(camera_index[name], JPEG_QUALITY)
            elif isinstance(output, LidarOutput):
                scan = output.scan
                # nuScenes's sweeps are ego-motion compensated to the sweep's timestamp: the deskewed
                # copy where the LiDAR makes one (the nuscenes preset does)
                xyz = scan.xyz_deskewed_lidar_m if len(scan.xyz_deskewed_lidar_m) else scan.xyz_lidar_m
                points = np.column_stack([xyz, scan.intensity * 255.0, scan.ring]).astype("<f4")
                entry.update(filename=f"{stem}.pcd.bin", fileformat="pcd")
                files[entry["filename"]] = points.tobytes()
                if key is not None and channel == self._lidar_channel:
                    files[f"rows/{record.frame_index:06d}.lidar.npz"] = _point_classes(scan)
            elif isinstance(output, RadarOutput):
                entry.update(filename=f"{stem}.pcd", fileformat="pcd")
                radar_R_ego = output.spec.ego_SE3_sensor.rotation.T
                files[entry["filename"]] = radar_pcd(output.scan, radar_R_ego @ ego_velocity_ego)
                ids, counts = np.unique(output.scan.instance_id[output.scan.instance_id > 0], return_counts=True)
                radar_counts[channel] = {str(int(i)): int(c) for i, c in zip(ids, counts, strict=True)}
            data.append(entry)
        row: dict[str, Any] = {
            "frame": record.frame_index,
            "timestamp": stamp_us,
            "scene": self._scene,
            "ego_pose": {
                "translation": record.map_SE3_ego.translation.tolist(),
                "rotation": quaternion_wxyz(record.map_SE3_ego.rotation),
            },
            "data": data,
            "radar_counts": radar_counts,
        }
        every = round(KEYFRAME_S / setup.step_s)
        if record.frame_index % every == 0:
            row["annotations"], row["traffic_control"] = self._annotations(record, ego_velocity_ego)
        files[f"rows/{record.frame_index:06d}.json"] = json.dumps(row, separators=(",", ":")).encode()
        return files

    def _annotations(
        self, record: FrameRecord, ego_velocity_ego: npt.NDArray[np.float64]
    ) -> tuple[list[dict[str, Any]], list[dict[str, Any]]]:
        """One annotation per labelled object of a class nuScenes names: the box in the map
        frame (grown and lifted by ``EXPORT_MARGIN_M``), LiDAR points of the keyframe LiDAR,
        visibility from the cameras of the frame;
        and the traffic lights and signs (the extension table)."""
        labels, o = record.labels, record.labels.objects
        lidar = next((x for x in record.lidars if self._channels[x.spec.name] == self._lidar_channel), None)
        lidar_pts = count_hits(lidar.scan.instance_id, o.track_id) if lidar is not None else np.zeros(len(o), np.int32)
        fraction = np.zeros(len(o))
        for cam in labels.cameras:
            fraction = np.maximum(fraction, np.nan_to_num(cam.visibility.fraction))
        map_SE3_ego: SE3 = record.map_SE3_ego
        rotations = map_SE3_ego.rotation @ o.rotations()
        centre = map_SE3_ego.transform_from(o.center_ego_m) + rotations[:, :, 2] * EXPORT_MARGIN_M
        lwh = o.lwh_m + np.array([2, 2, 0]) * EXPORT_MARGIN_M
        speed = np.linalg.norm((o.velocity_ego_mps + ego_velocity_ego)[:, :2], axis=1)
        out, control = [], []
        states = record.signals.state_of()
        subtypes = dict(zip(record.signals.track_id.tolist(), record.signals.subtype, strict=True))
        bodies = body_subtypes(o.semantic_class, o.lwh_m, o.track_id)
        for i in range(len(o)):
            length, width, height = (float(v) for v in lwh[i])
            box = {
                "translation": [round(float(v), 6) for v in centre[i]],
                "size": [round(width, 6), round(length, 6), round(height, 6)],
                "rotation": quaternion_wxyz(rotations[i]),
            }
            kind = TRAFFIC_CONTROL.get(SemanticClass(int(o.semantic_class[i])))
            if kind is not None:
                track = int(o.track_id[i])
                control.append({"id": track, "kind": kind, "subtype": subtypes.get(track, ""),
                                "state": states.get(track, ""), **box, "num_lidar_pts": int(lidar_pts[i])})  # fmt: skip
                continue
            category = category_of(int(o.semantic_class[i]), str(bodies[i]))
            if category is None:
                continue
            out.append(
                {
                    "id": int(o.track_id[i]),
                    "category": category,
                    "attribute": attribute_of(category, bool(o.parked[i]), float(speed[i])),
                    **box,
                    "num_lidar_pts": int(lidar_pts[i]),
                    "visibility": visibility_level(float(fraction[i])),
                }
            )
        return out, control

    def write(self, encoded: dict[str, bytes]) -> None:
        self._folder.write_files(encoded)

    def close(self) -> None:
        write_tables(
            self._folder.partial, self._setup.name, self._setup.location, self._setup.map_json, self._lidar_channel
        )
        self._folder.commit()

    def abort(self) -> None:
        self._folder.discard()

    def keep(self) -> None:
        pass  # each frame's files are written whole


def _calibration(channel: str, output: SensorOutput) -> dict[str, Any]:
    """The sensor's ``calibrated_sensor`` values: its frame in the ego frame, a camera's K."""
    spec = output.spec
    pose = spec.ego_SE3_sensor
    modality = (SensorKind.CAMERA if isinstance(output, CameraOutput)
                else SensorKind.LIDAR if isinstance(output, LidarOutput) else SensorKind.RADAR)  # fmt: skip
    intrinsic = output.spec.pinhole.K.tolist() if isinstance(output, CameraOutput) else []
    return calibration_record(
        channel, modality, [round(float(v), 9) for v in pose.translation], quaternion_wxyz(pose.rotation), intrinsic
    )


def _point_classes(scan: LidarScan) -> bytes:
    """``rows/<frame>.lidar.npz``: each point's class and instance (see :mod:`gtgen.nuscenes_lidarseg`)."""
    return npz_bytes(semantic_class=scan.semantic_class, instance_id=scan.instance_id)


def _drop_after(partial: Path, keep_frames: int) -> None:
    """Remove the records of the frames a continued run makes again, and their files."""
    rows = partial / "rows"
    if not rows.is_dir():
        return
    for path in sorted(rows.glob("*.json")):
        if path.stem.isdigit() and int(path.stem) >= keep_frames:
            for entry in json.loads(path.read_text())["data"]:
                (partial / entry["filename"]).unlink(missing_ok=True)
            (rows / f"{path.stem}.lidar.npz").unlink(missing_ok=True)
            path.unlink()
    for folder in (VERSION, TEST_VERSION, "lidarseg", "panoptic"):
        shutil.rmtree(partial / folder, ignore_errors=True)


def _last_scene(rows: Path, keep_frames: int) -> int:
    """The scene index of the last kept frame (0 for a new run)."""
    if keep_frames == 0:
        return 0
    last = rows / f"{keep_frames - 1:06d}.json"
    return int(json.loads(last.read_text())["scene"]) if last.exists() else 0
