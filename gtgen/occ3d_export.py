"""Occ3D-nuScenes's ``annotations.json`` beside a run's nuScenes export, so that Occ3D-style loaders
find each keyframe's occupancy by its sample token.

Written when a run has both ``nuscenes/`` and ``occupancy/``: ``nuscenes/annotations.json``
(``train_split``, ``val_split``, ``test_split``: scene names; ``scene_infos``: per scene, per
sample token in time order, ``timestamp``, ``camera_sensor`` (per camera channel: ``img_path``,
``intrinsic`` 3x3, ``extrinsic`` and ``ego_pose`` as translation and wxyz rotation), ``ego_pose``,
``gt_path``, ``prev``, ``next``) and ``nuscenes/gts/<scene>/<sample token>/labels.npz``, links
to (or copies of) the frame's ``occupancy/NNNNNN/labels.npz``.
"""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path
from typing import Any

from gtgen.nuscenes import token
from gtgen.nuscenes_versions import TEST_VERSION, VERSION, read_versions
from networks.vocabulary import SensorKind


def _link(source: Path, target: Path) -> None:
    """``target`` as a hard link to ``source`` (a copy across file systems)."""
    target.parent.mkdir(parents=True, exist_ok=True)
    target.unlink(missing_ok=True)
    try:
        os.link(source, target)
    except OSError:
        shutil.copy2(source, target)


def _pose(record: dict[str, Any]) -> dict[str, Any]:
    return {"translation": record["translation"], "rotation": record["rotation"]}


def write_occ3d_annotations(out_dir: Path, name: str) -> Path | None:
    """Write ``out_dir/nuscenes/annotations.json`` and ``gts/`` (None: the run has no nuScenes
    export or no occupancy). ``name``: the run's name in its tokens (the output folder's name)."""
    root, occupancy = out_dir / "nuscenes", out_dir / "occupancy"
    if not (occupancy.is_dir() and ((root / VERSION).is_dir() or (root / TEST_VERSION).is_dir())):
        return None
    tables, split_of_scene = read_versions(root)
    frame_of = {token(name, "sample", int(p.name)): int(p.name) for p in occupancy.iterdir() if p.name.isdigit()}
    sample = {r["token"]: r for r in tables["sample"]}
    ego_pose = {r["token"]: r for r in tables["ego_pose"]}
    calibrated = {r["token"]: r for r in tables["calibrated_sensor"]}
    modality = {r["token"]: r for r in tables["sensor"]}
    key_data: dict[str, list[dict[str, Any]]] = {}
    for record in tables["sample_data"]:
        if record["is_key_frame"]:
            key_data.setdefault(record["sample_token"], []).append(record)
    infos: dict[str, dict[str, Any]] = {}
    splits: dict[str, list[str]] = {"train_split": [], "val_split": [], "test_split": []}
    for scene in tables["scene"]:
        frames: dict[str, Any] = {}
        at = scene["first_sample_token"]
        while at:
            s = sample[at]
            if at in frame_of:
                frames[at] = _frame(root, occupancy, scene["name"], s, frame_of[at], key_data.get(at, []), ego_pose,
                                    calibrated, modality)  # fmt: skip
            at = s["next"]
        if frames:
            infos[scene["name"]] = frames
            splits[f"{split_of_scene.get(scene['token'], 'train')}_split"].append(scene["name"])
    path = root / "annotations.json"
    path.write_text(json.dumps({**splits, "scene_infos": infos}, separators=(",", ":")))
    return path


def _frame(
    root: Path, occupancy: Path, scene: str, s: dict[str, Any], frame: int, data: list[dict[str, Any]],
    ego_pose: dict[str, Any], calibrated: dict[str, Any], sensor: dict[str, Any],
) -> dict[str, Any]:  # fmt: skip
    cameras, pose = {}, None
    for d in data:
        cal = calibrated[d["calibrated_sensor_token"]]
        channel = sensor[cal["sensor_token"]]
        if channel["modality"] == SensorKind.CAMERA:
            view = {"img_path": d["filename"], "intrinsic": cal["camera_intrinsic"], "extrinsic": _pose(cal)}
            cameras[channel["channel"]] = {**view, "ego_pose": _pose(ego_pose[d["ego_pose_token"]])}
        elif channel["modality"] == SensorKind.LIDAR and pose is None:
            pose = _pose(ego_pose[d["ego_pose_token"]])
    gt_path = f"gts/{scene}/{s['token']}/labels.npz"
    _link(occupancy / f"{frame:06d}" / "labels.npz", root / gt_path)
    return {"timestamp": s["timestamp"], "camera_sensor": cameras, "ego_pose": pose, "gt_path": gt_path,
            "prev": s["prev"], "next": s["next"]}  # fmt: skip
