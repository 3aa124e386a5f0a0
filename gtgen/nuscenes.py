"""The nuScenes v1.0 layout: the 13 tables built from a run's per-frame records, and several
runs merged into one version with train/val splits the nuScenes devkit evaluates.

A run's ``nuscenes/`` folder is a ``dataroot``: ``samples/<CHANNEL>/`` (keyframe files),
``sweeps/<CHANNEL>/`` (the others), ``maps/<token>.png`` (the drivable area, 0.1 m per
pixel, as the devkit's map mask reads it) and ``v1.0-trainval/`` with the 13 tables, a
``splits.json`` (the devkit's custom splits; ``sim_all`` holds the run's scenes) and
``traffic_control.json``, an extension table the devkit does not read: the traffic lights
(with the state they show) and signs at each keyframe, boxes as in ``sample_annotation``. Load it
with ``NuScenes(version="v1.0-trainval", dataroot="<run>/nuscenes")``.

Conventions: the ego frame is this project's (origin at the footprint centre on the ground,
x forward, z up) and ``ego_pose`` places it in the map frame; sensor frames as in
``calibrated_sensor`` (cameras: x right, y down, z forward). Timestamps are the simulation
clock in microseconds. Keyframes come every 0.5 s from the first LiDAR, which is the
``LIDAR_TOP`` channel; a sensor's keyframe is its firing nearest the LiDAR keyframe. Boxes
are those of the labels (yaw about the ego's up axis), put into the map frame.
``num_radar_pts`` counts the returns in the radars' keyframe sweeps. A radar sweep with no
return holds one invalid cluster (``invalid_state`` 1), which the devkit's default filters
drop: its reader cannot read an empty file.

``python -m gtgen.nuscenes merge OUT RUN [RUN ...] [--val-fraction F | --val RUN ...]``
merges the ``nuscenes/`` folders of several runs (a sweep's) into ``OUT``: one scene per run
(more where a run has scene cuts), splits ``sim_train`` and ``sim_val`` by whole runs. The
k-th run's timestamps move k days later (every run's clock starts at the same simulated time).
Evaluate with the devkit's ``DetectionEval(..., eval_set="sim_val")``.
"""

from __future__ import annotations

import argparse
import datetime
import hashlib
import json
import math
import os
import shutil
import sys
from collections import defaultdict
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import numpy.typing as npt

from networks.classes import SemanticClass
from networks.geometry import quaternion_xyzw_from_rotation
from sensors.radar import RadarScan

VERSION = "v1.0-trainval"
KEYFRAME_S = 0.5
MAP_RESOLUTION_M = 0.1
CATEGORIES = {
    SemanticClass.CAR: ("vehicle.car", "Passenger car."),
    SemanticClass.TRUCK: ("vehicle.truck", "Truck."),
    SemanticClass.BUS: ("vehicle.bus.rigid", "Rigid bus."),
    SemanticClass.MOTORCYCLE: ("vehicle.motorcycle", "Motorcycle with its rider."),
    SemanticClass.BICYCLE: ("vehicle.bicycle", "Bicycle with its rider."),
    SemanticClass.PEDESTRIAN: ("human.pedestrian.adult", "Adult pedestrian."),
}
# Traffic lights and signs are no nuScenes category (the devkit's renderer has no colour for a
# new one): they go to an extension table the devkit does not read, traffic_control.json.
TRAFFIC_CONTROL = {SemanticClass.TRAFFIC_LIGHT: "traffic_light", SemanticClass.TRAFFIC_SIGN: "traffic_sign"}
ATTRIBUTES = {
    "vehicle.moving": "Vehicle is moving.",
    "vehicle.stopped": "Vehicle, not parked, is standing still.",
    "vehicle.parked": "Vehicle is parked.",
    "cycle.with_rider": "There is a rider on the bicycle or motorcycle.",
    "cycle.without_rider": "There is no rider on the bicycle or motorcycle.",
    "pedestrian.sitting_lying_down": "The pedestrian is sitting or lying down.",
    "pedestrian.standing": "The pedestrian is standing.",
    "pedestrian.moving": "The pedestrian is moving.",
}
VISIBILITY = (("1", "v0-40", "visibility of whole object is between 0 and 40%"),
              ("2", "v40-60", "visibility of whole object is between 40 and 60%"),
              ("3", "v60-80", "visibility of whole object is between 60 and 80%"),
              ("4", "v80-100", "visibility of whole object is between 80 and 100%"))  # fmt: skip
MOVING_MPS = 0.3  # slower than this counts as standing still
TABLES = ("category", "attribute", "visibility", "sensor", "calibrated_sensor", "ego_pose", "log", "scene",
          "sample", "sample_data", "sample_annotation", "instance", "map")  # fmt: skip


class NuscenesError(Exception):
    """A run or merge that cannot be made into the nuScenes layout (one line for the user)."""


def token(*parts: object) -> str:
    """A 32-hex token, the same for the same parts (tokens are stable across re-runs)."""
    return hashlib.md5(":".join(str(p) for p in parts).encode()).hexdigest()


def channel_of(kind: str, name: str, first: bool = False) -> str:
    """The nuScenes channel of a sensor: the rig's first LiDAR is LIDAR_TOP, others by name."""
    return "LIDAR_TOP" if kind == "lidar" and first else name.upper()


def category_of(semantic_class: int) -> str | None:
    entry = (
        CATEGORIES.get(SemanticClass(semantic_class)) if semantic_class in SemanticClass._value2member_map_ else None
    )
    return None if entry is None else entry[0]


def attribute_of(category: str, parked: bool, speed_mps: float) -> str:
    """The one attribute nuScenes gives an object of this category ('' for none)."""
    if category.startswith("vehicle.") and category not in ("vehicle.bicycle", "vehicle.motorcycle"):
        return "vehicle.parked" if parked else "vehicle.moving" if speed_mps >= MOVING_MPS else "vehicle.stopped"
    if category in ("vehicle.bicycle", "vehicle.motorcycle"):
        return "cycle.with_rider"  # the simulation's cycles are ridden
    if category.startswith("human.pedestrian"):
        return "pedestrian.moving" if speed_mps >= MOVING_MPS else "pedestrian.standing"
    return ""


def visibility_level(fraction: float) -> str:
    """The visibility token of the largest visible fraction over the cameras."""
    return "1" if fraction < 0.4 else "2" if fraction < 0.6 else "3" if fraction < 0.8 else "4"


def quaternion_wxyz(rotation: npt.NDArray[np.float64]) -> list[float]:
    x, y, z, w = quaternion_xyzw_from_rotation(rotation)
    return [round(float(v), 9) for v in (w, x, y, z)]


RADAR_FIELDS = [("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("dyn_prop", "i1"), ("id", "<i2"), ("rcs", "<f4"),
                ("vx", "<f4"), ("vy", "<f4"), ("vx_comp", "<f4"), ("vy_comp", "<f4"), ("is_quality_valid", "i1"),
                ("ambig_state", "i1"), ("x_rms", "i1"), ("y_rms", "i1"), ("invalid_state", "i1"), ("pdh0", "i1"),
                ("vx_rms", "i1"), ("vy_rms", "i1")]  # fmt: skip


def radar_pcd(scan: RadarScan, radar_velocity_mps: npt.NDArray[np.float64]) -> bytes:
    """A radar sweep as nuScenes's binary PCD v0.7: positions in the radar frame, velocities
    along the ray (``vx, vy``: relative; ``*_comp``: with the radar's own motion taken out),
    dynamic property moving (0) or stationary (1) from the compensated speed."""
    n = len(scan.range_m)
    rows = np.zeros(max(n, 1), dtype=np.dtype(RADAR_FIELDS))
    if n == 0:
        rows["invalid_state"] = 1  # invalid due to low RCS: the devkit drops it
        rows["ambig_state"] = 3
    else:
        xyz = scan.xyz_radar_m.astype(np.float64)
        direction = xyz / np.maximum(np.linalg.norm(xyz, axis=1, keepdims=True), 1e-9)
        radial = scan.radial_velocity_mps.astype(np.float64)
        compensated = radial + direction @ radar_velocity_mps
        rows["x"], rows["y"], rows["z"] = xyz[:, 0], xyz[:, 1], xyz[:, 2]
        rows["dyn_prop"] = np.where(np.abs(compensated) >= MOVING_MPS, 0, 1)
        rows["id"] = np.arange(n)
        rows["rcs"] = scan.strength_db
        rows["vx"], rows["vy"] = radial * direction[:, 0], radial * direction[:, 1]
        rows["vx_comp"], rows["vy_comp"] = compensated * direction[:, 0], compensated * direction[:, 1]
        rows["is_quality_valid"], rows["ambig_state"], rows["pdh0"] = 1, 3, 1
    names = " ".join(f for f, _ in RADAR_FIELDS)
    sizes = " ".join(str(np.dtype(t).itemsize) for _, t in RADAR_FIELDS)
    types = " ".join("F" if t.endswith("f4") else "I" for _, t in RADAR_FIELDS)
    counts = " ".join("1" for _ in RADAR_FIELDS)
    header = (f"# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\nFIELDS {names}\nSIZE {sizes}\n"
              f"TYPE {types}\nCOUNT {counts}\nWIDTH {len(rows)}\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\n"
              f"POINTS {len(rows)}\nDATA binary\n")  # fmt: skip
    return header.encode() + rows.tobytes()


def calibration_record(channel: str, modality: str, translation: list[float], rotation_wxyz: list[float],
                       intrinsic: list[list[float]]) -> dict[str, Any]:  # fmt: skip
    return {"channel": channel, "modality": modality, "translation": translation, "rotation": rotation_wxyz,
            "camera_intrinsic": intrinsic}  # fmt: skip


def _scene_name(name: str, index: int, scenes: int) -> str:
    return name if scenes == 1 else f"{name}-{index}"


def write_tables(root: Path, name: str, location: str, map_json: Path | None, lidar_channel: str) -> None:
    """Build ``v1.0-trainval/`` and ``maps/`` under ``root`` from its ``rows/`` and
    ``calibration.json`` (see :mod:`gtgen.sinks.nuscenes_sink`)."""
    rows = [json.loads(p.read_text()) for p in sorted((root / "rows").glob("*.json"))]
    calibration = json.loads((root / "calibration.json").read_text()) if (root / "calibration.json").exists() else {}
    if not rows:
        return
    tables: dict[str, list[dict[str, Any]]] = {t: [] for t in TABLES}
    tables["category"] = [{"token": token("category", c), "name": c, "description": d}
                          for c, d in CATEGORIES.values()]  # fmt: skip
    tables["attribute"] = [{"token": token("attribute", a), "name": a, "description": d} for a, d in ATTRIBUTES.items()]
    tables["visibility"] = [{"token": t, "level": level, "description": d} for t, level, d in VISIBILITY]
    for channel, cal in sorted(calibration.items()):
        tables["sensor"].append({"token": token("sensor", channel), "channel": channel, "modality": cal["modality"]})
        tables["calibrated_sensor"].append({
            "token": token(name, "calibrated_sensor", channel), "sensor_token": token("sensor", channel),
            "translation": cal["translation"], "rotation": cal["rotation"], "camera_intrinsic": cal["camera_intrinsic"],
        })  # fmt: skip
    log_token = token(name, "log")
    tables["log"] = [{"token": log_token, "logfile": name, "vehicle": "simulated-ego", "date_captured": "1970-01-01",
                      "location": location}]  # fmt: skip
    map_token = token("map", location)
    tables["map"] = [{"token": map_token, "log_tokens": [log_token], "category": "semantic_prior",
                      "filename": f"maps/{map_token}.png"}]  # fmt: skip
    (root / "maps").mkdir(exist_ok=True)
    cv2.imwrite(str(root / "maps" / f"{map_token}.png"), drivable_mask(map_json, rows))

    by_frame = {r["frame"]: r for r in rows}
    scene_of = {r["frame"]: int(r["scene"]) for r in rows}
    scenes = sorted(set(scene_of.values()))
    sample_frames = [r["frame"] for r in rows if "annotations" in r]
    sample_token = {f: token(name, "sample", f) for f in sample_frames}
    by_scene: dict[int, list[int]] = defaultdict(list)
    for f in sample_frames:
        by_scene[scene_of[f]].append(f)
    for index in scenes:
        frames = by_scene.get(index, [])
        if not frames:
            continue
        scene_token = token(name, "scene", index)
        for k, f in enumerate(frames):
            tables["sample"].append({
                "token": sample_token[f], "timestamp": by_frame[f]["timestamp"], "scene_token": scene_token,
                "prev": sample_token[frames[k - 1]] if k > 0 else "",
                "next": sample_token[frames[k + 1]] if k + 1 < len(frames) else "",
            })  # fmt: skip
        tables["scene"].append({
            "token": scene_token, "log_token": log_token, "nbr_samples": len(frames),
            "first_sample_token": sample_token[frames[0]], "last_sample_token": sample_token[frames[-1]],
            "name": _scene_name(name, index, len(scenes)), "description": f"{name}, {location}",
        })  # fmt: skip

    # sample_data: one chain per channel and scene; keyframes only where their sample exists.
    key_frame_of: dict[tuple[str, int], int] = {}  # (channel, sample frame) -> the frame of its keyframe file
    chains: dict[tuple[str, int], list[dict[str, Any]]] = defaultdict(list)
    for r in rows:
        frame = r["frame"]
        tables["ego_pose"].append({"token": token(name, "ego_pose", frame), "timestamp": r["timestamp"],
                                   "translation": r["ego_pose"]["translation"],
                                   "rotation": r["ego_pose"]["rotation"]})  # fmt: skip
        own = by_scene.get(scene_of[frame], [])
        for entry in r["data"]:
            key = entry["key"]
            is_key = key is not None and key in sample_token and scene_of[key] == scene_of[frame]
            if is_key:
                key_frame_of[(entry["channel"], key)] = frame
            later = [f for f in own if f >= frame]
            belongs = key if is_key else (later[0] if later else own[-1] if own else None)
            if belongs is None:
                continue  # a scene without a keyframe (it ended within 0.5 s)
            chains[(entry["channel"], scene_of[frame])].append({
                "token": token(name, "sample_data", entry["channel"], frame), "sample_token": sample_token[belongs],
                "ego_pose_token": token(name, "ego_pose", frame),
                "calibrated_sensor_token": token(name, "calibrated_sensor", entry["channel"]),
                "timestamp": r["timestamp"], "fileformat": entry["fileformat"], "is_key_frame": is_key,
                "height": entry["height"], "width": entry["width"], "filename": entry["filename"],
            })  # fmt: skip
    for chain in chains.values():
        for k, record in enumerate(chain):
            record["prev"] = chain[k - 1]["token"] if k > 0 else ""
            record["next"] = chain[k + 1]["token"] if k + 1 < len(chain) else ""
            tables["sample_data"].append(record)

    radar_counts = {r["frame"]: r["radar_counts"] for r in rows}
    radar_channels = sorted(c for c, cal in calibration.items() if cal["modality"] == "radar")
    instances: dict[tuple[int, int], list[dict[str, Any]]] = defaultdict(list)
    category_of_instance: dict[tuple[int, int], str] = {}
    for f in sample_frames:
        for a in by_frame[f]["annotations"]:
            radar_pts = 0
            for channel in radar_channels:
                at = key_frame_of.get((channel, f))
                if at is not None:
                    radar_pts += int(radar_counts[at].get(channel, {}).get(str(a["id"]), 0))
            key = (scene_of[f], a["id"])
            category_of_instance.setdefault(key, a["category"])
            instances[key].append({
                "token": token(name, "sample_annotation", key[0], a["id"], f), "sample_token": sample_token[f],
                "instance_token": token(name, "instance", key[0], a["id"]),
                "visibility_token": a["visibility"],
                "attribute_tokens": [token("attribute", a["attribute"])] if a["attribute"] else [],
                "translation": a["translation"], "size": a["size"], "rotation": a["rotation"],
                "num_lidar_pts": a["num_lidar_pts"], "num_radar_pts": radar_pts,
            })  # fmt: skip
    for key, chain in sorted(instances.items()):
        for k, record in enumerate(chain):
            record["prev"] = chain[k - 1]["token"] if k > 0 else ""
            record["next"] = chain[k + 1]["token"] if k + 1 < len(chain) else ""
            tables["sample_annotation"].append(record)
        tables["instance"].append({
            "token": token(name, "instance", *key), "category_token": token("category", category_of_instance[key]),
            "nbr_annotations": len(chain), "first_annotation_token": chain[0]["token"],
            "last_annotation_token": chain[-1]["token"],
        })  # fmt: skip
    extension = [{"token": token(name, "traffic_control", scene_of[f], c["id"], f), "sample_token": sample_token[f],
                  **{k: v for k, v in c.items() if k != "id"}, "id": c["id"]}
                 for f in sample_frames for c in by_frame[f].get("traffic_control", [])]  # fmt: skip
    _write_version(root, tables, {"sim_all": [s["name"] for s in tables["scene"]]}, extension)


def _write_version(root: Path, tables: dict[str, list[dict[str, Any]]], splits: dict[str, list[str]],
                   traffic_control: list[dict[str, Any]]) -> None:  # fmt: skip
    folder = root / VERSION
    folder.mkdir(parents=True, exist_ok=True)
    for name, records in {**tables, "traffic_control": traffic_control}.items():
        (folder / f"{name}.json").write_text(json.dumps(records, indent=0, separators=(",", ":")))
    (folder / "splits.json").write_text(json.dumps(splits, indent=2) + "\n")


def drivable_mask(map_json: Path | None, rows: list[dict[str, Any]]) -> npt.NDArray[np.uint8]:
    """The map mask the devkit reads: 255 on the drivable area, 0 elsewhere, 0.1 m per pixel,
    pixel (row, col) at map x = col * 0.1, y = (height - row) * 0.1. Without a map, an empty
    mask covering the ego's path."""
    rings: list[npt.NDArray[np.float64]] = []
    if map_json is not None and map_json.exists():
        elements = json.loads(map_json.read_text())["elements"]
        rings = [np.asarray(e["points"], np.float64) for e in elements if e["type"] == "road_boundary"]
    path = np.asarray([r["ego_pose"]["translation"][:2] for r in rows], np.float64)
    extent = np.vstack([*(ring[:, :2] for ring in rings), path]).max(axis=0) + 50.0
    width, height = (math.ceil(float(v) / MAP_RESOLUTION_M) for v in np.maximum(extent, 1.0))
    mask = np.zeros((height, width), np.uint8)
    if rings:
        pixels = [np.round(np.column_stack([ring[:, 0], height * MAP_RESOLUTION_M - ring[:, 1]]) / MAP_RESOLUTION_M)
                  .astype(np.int32) for ring in rings]  # fmt: skip
        cv2.fillPoly(mask, pixels, 255)
    return mask


def _read_tables(folder: Path) -> dict[str, list[dict[str, Any]]]:
    missing = [t for t in TABLES if not (folder / f"{t}.json").is_file()]
    if missing:
        raise NuscenesError(f"{folder}: not a nuScenes version folder (no {missing[0]}.json)")
    return {t: json.loads((folder / f"{t}.json").read_text()) for t in TABLES}


def merge(out: Path, runs: list[Path], val: list[Path] | None = None, val_fraction: float = 0.25) -> dict[str, int]:
    """Merge the ``nuscenes/`` folders of ``runs`` into the dataroot ``out``: files linked (or
    copied across file systems), tables concatenated, ``splits.json`` with ``sim_train`` and
    ``sim_val`` (the ``val`` runs, or the last ``val_fraction`` of them) and ``sim_all``."""
    roots = []
    for run in runs:
        root = run / "nuscenes" if (run / "nuscenes" / VERSION).is_dir() else run
        if not (root / VERSION).is_dir():
            raise NuscenesError(f"{run}: no nuScenes export (expected {run}/nuscenes/{VERSION}; run it with "
                                "outputs.nuscenes=true)")  # fmt: skip
        roots.append(root)
    if out.exists() and any(out.iterdir()):
        raise NuscenesError(f"{out}: the output folder exists and is not empty")
    partial = out.with_name(out.name + ".partial")
    shutil.rmtree(partial, ignore_errors=True)
    merged: dict[str, list[dict[str, Any]]] = {t: [] for t in TABLES}
    seen: dict[str, set[str]] = defaultdict(set)
    maps: dict[str, dict[str, Any]] = {}
    scenes_of_run: list[list[str]] = []
    traffic_control: list[dict[str, Any]] = []
    for k, (run, root) in enumerate(zip(runs, roots, strict=True)):
        tables = _retimed(_read_tables(root / VERSION), k)
        extension = root / VERSION / "traffic_control.json"
        traffic_control += json.loads(extension.read_text()) if extension.is_file() else []
        logs = {log["logfile"] for log in tables["log"]}
        clash = logs & seen["logfile"]
        if clash:
            raise NuscenesError(f"{run}: its log {sorted(clash)[0]} is already in the merge (the same run twice?)")
        seen["logfile"] |= logs
        for table, records in tables.items():
            for record in records:
                if table == "map":
                    known = maps.setdefault(record["token"], {**record, "log_tokens": []})
                    known["log_tokens"] = sorted(set(known["log_tokens"]) | set(record["log_tokens"]))
                    continue
                if record["token"] in seen[table]:
                    continue  # categories, attributes, visibility, sensors: shared
                seen[table].add(record["token"])
                merged[table].append(record)
        scenes_of_run.append([s["name"] for s in tables["scene"]])
        for record in tables["sample_data"] + tables["map"]:
            _link(root / record["filename"], partial / record["filename"])
    merged["map"] = list(maps.values())
    val_runs = {str(v.resolve()) for v in val} if val else None
    if val_runs is None:
        count = max(1, round(val_fraction * len(runs))) if len(runs) > 1 else 0
        val_runs = {str(r.resolve()) for r in runs[len(runs) - count :]}
    unknown = val_runs - {str(r.resolve()) for r in runs}
    if unknown:
        raise NuscenesError(f"--val {sorted(unknown)[0]}: not one of the runs merged")
    splits: dict[str, list[str]] = {"sim_train": [], "sim_val": [], "sim_all": []}
    for run, names in zip(runs, scenes_of_run, strict=True):
        splits["sim_val" if str(run.resolve()) in val_runs else "sim_train"] += names
        splits["sim_all"] += names
    _write_version(partial, merged, splits, traffic_control)
    if out.exists():
        out.rmdir()  # empty, checked above
    partial.replace(out)
    return {"runs": len(runs), "scenes": len(merged["scene"]), "samples": len(merged["sample"]),
            "annotations": len(merged["sample_annotation"])}  # fmt: skip


DAY_US = 86_400_000_000


def _retimed(tables: dict[str, list[dict[str, Any]]], days: int) -> dict[str, list[dict[str, Any]]]:
    """The tables of the ``days``-th run of a merge moved that many days later: every run's
    clock starts at the same simulated time, and the devkit orders scenes by their start."""
    for table in ("sample", "sample_data", "ego_pose"):
        for record in tables[table]:
            record["timestamp"] += days * DAY_US
    for log in tables["log"]:
        log["date_captured"] = (datetime.date(1970, 1, 1) + datetime.timedelta(days=days)).isoformat()
    return tables


def _link(source: Path, target: Path) -> None:
    target.parent.mkdir(parents=True, exist_ok=True)
    if target.exists():
        return
    try:
        os.link(source, target)
    except OSError:
        shutil.copy2(source, target)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m gtgen.nuscenes", description=__doc__.split("\n\n")[0])
    sub = parser.add_subparsers(dest="command", required=True)
    m = sub.add_parser("merge", help="merge the nuScenes exports of several runs into one version")
    m.add_argument("out", type=Path)
    m.add_argument("runs", type=Path, nargs="+")
    m.add_argument("--val", type=Path, nargs="*", help="the runs of the validation split")
    m.add_argument("--val-fraction", type=float, default=0.25, help="share of runs for validation (the last ones)")
    args = parser.parse_args(argv)
    if not 0.0 <= args.val_fraction < 1.0:
        print(f"error: --val-fraction: expected a share in [0, 1), got {args.val_fraction}", file=sys.stderr)
        return 2
    try:
        counts = merge(args.out, args.runs, args.val, args.val_fraction)
    except NuscenesError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    print(
        f"{args.out}: {counts['runs']} runs, {counts['scenes']} scenes, {counts['samples']} samples, "
        f"{counts['annotations']} annotations; splits sim_train, sim_val, sim_all in {args.out}/{VERSION}/splits.json"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
