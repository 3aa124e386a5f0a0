"""The nuScenes v1.0 layout: the tables built from a run's per-frame records (the versions,
splits and merges are in :mod:`gtgen.nuscenes_versions`).

A run's ``nuscenes/`` folder is a ``dataroot``: ``samples/<CHANNEL>/`` (keyframe files),
``sweeps/<CHANNEL>/`` (the others), ``maps/<token>.png`` (the drivable area, 0.1 m per
pixel, as the devkit's map mask reads it), ``v1.0-trainval/`` (train and val scenes) and
``v1.0-test/`` (test scenes) with the 13 tables, ``lidarseg.json`` and ``panoptic.json`` (the
point labels under ``lidarseg/`` and ``panoptic/``, see :mod:`gtgen.nuscenes_lidarseg`), a
``splits.json`` (the devkit's custom splits) and ``traffic_control.json``, an extension table
the devkit does not read: the traffic lights (with the state they show) and signs at each
keyframe, boxes as in ``sample_annotation``. Load it with
``NuScenes(version="v1.0-trainval", dataroot="<run>/nuscenes")``.

Scenes last at most 20 s (40 keyframes) as nuScenes's, shorter where a run is under a minute
(so that it has three), and a scene cut starts a new one; they are split in time blocks by
:mod:`gtgen.splits` and named from nuScenes's official lists (``scene-0001`` for the first
train scene, ``scene-0003`` the first val, ``scene-0077`` the first test); ``description``
gives the run, the network and the scene's time span.

Conventions: the ego frame is this project's (origin at the footprint centre on the ground,
x forward, z up) and ``ego_pose`` places it in the map frame; sensor frames as in
``calibrated_sensor`` (cameras: x right, y down, z forward). Timestamps are the simulation
clock in microseconds. Keyframes come every 0.5 s from the first LiDAR, which is the
``LIDAR_TOP`` channel; a sensor's keyframe is its firing nearest the LiDAR keyframe. Boxes
are those of the labels (with their pitch and roll), put into the map frame.
``num_radar_pts`` counts the returns in the radars' keyframe sweeps. A radar sweep with no
return holds one invalid cluster (``invalid_state`` 1), which the devkit's default filters
drop: its reader cannot read an empty file.

``python -m gtgen.nuscenes merge OUT RUN [RUN ...] [--val RUN ...] [--test RUN ...]
[--val-fraction F]`` merges the ``nuscenes/`` folders of several runs (a sweep's) into ``OUT``.
The k-th run's timestamps move k days later (every run's clock starts at the same simulated time).
"""

from __future__ import annotations

import argparse
import hashlib
import json
import math
import sys
from collections import defaultdict
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import numpy.typing as npt

from gtgen.npz import npz_bytes
from gtgen.nuscenes_lidarseg import LIDARSEG_CATEGORIES, lidarseg_of_objects, number_instances, panoptic_labels
from gtgen.nuscenes_versions import (
    DAY_US,
    TABLES,
    TEST_VERSION,
    VERSION,
    NuscenesError,
    Tables,
    merge,
    official_names,
    write_versions,
)
from gtgen.splits import split_units
from networks.classes import SemanticClass
from networks.geometry import quaternion_xyzw_from_rotation
from networks.vocabulary import SensorKind
from sensors.radar import RadarScan

__all__ = ["DAY_US", "TEST_VERSION", "VERSION", "NuscenesError"]

KEYFRAME_S = 0.5
SCENE_KEYFRAMES = 40  # nuScenes's scenes: 20 s, 40 keyframes
MAP_RESOLUTION_M = 0.1
CATEGORIES = {
    SemanticClass.CAR: ("vehicle.car", "Passenger car."),
    SemanticClass.TRUCK: ("vehicle.truck", "Truck."),
    SemanticClass.BUS: ("vehicle.bus.rigid", "Rigid bus."),
    SemanticClass.MOTORCYCLE: ("vehicle.motorcycle", "Motorcycle with its rider."),
    SemanticClass.BICYCLE: ("vehicle.bicycle", "Bicycle with its rider."),
    SemanticClass.PEDESTRIAN: ("human.pedestrian.adult", "Adult pedestrian."),
    SemanticClass.TRAILER: ("vehicle.trailer", "Trailer pulled by a truck (its own object behind the tractor)."),
    SemanticClass.CONSTRUCTION_VEHICLE: ("vehicle.construction", "Vehicle designed for construction work."),
    SemanticClass.TRAFFIC_CONE: ("movable_object.trafficcone", "Traffic cone of a construction zone."),
    SemanticClass.BARRIER: ("movable_object.barrier", "Temporary barrier closing a lane."),
}
# Body types (the labels' subtype column) with a nuScenes category of their own: emergency
# vehicles (their points get it too, in lidarseg and panoptic). nuScenes's detection and
# tracking challenges leave these categories out, as the devkit does.
SUBTYPE_CATEGORIES = {
    "vehicle.emergency.police": "Police vehicle (a car in police livery).",
    "vehicle.emergency.ambulance": "Ambulance.",
}
CATEGORY_OF_SUBTYPE = {"police": "vehicle.emergency.police", "ambulance": "vehicle.emergency.ambulance"}
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
VISIBILITY = (
    ("1", "v0-40", "visibility of whole object is between 0 and 40%"),
    ("2", "v40-60", "visibility of whole object is between 40 and 60%"),
    ("3", "v60-80", "visibility of whole object is between 60 and 80%"),
    ("4", "v80-100", "visibility of whole object is between 80 and 100%"),
)
MOVING_MPS = 0.3  # slower than this counts as standing still


def token(*parts: object) -> str:
    """A 32-hex token, the same for the same parts (tokens are stable across re-runs)."""
    return hashlib.md5(":".join(str(p) for p in parts).encode()).hexdigest()


def channel_of(kind: SensorKind, name: str, first: bool = False) -> str:
    """The nuScenes channel of a sensor: the rig's first LiDAR is LIDAR_TOP, others by name."""
    return "LIDAR_TOP" if kind == SensorKind.LIDAR and first else name.upper()


def category_of(semantic_class: int, subtype: str = "") -> str | None:
    """The nuScenes category of an object of this class and body type (``subtype``: police cars
    and ambulances have their own); None for classes nuScenes annotates none of."""
    if subtype in CATEGORY_OF_SUBTYPE:
        return CATEGORY_OF_SUBTYPE[subtype]
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
    dynamic property moving (0) or stationary (1) from the compensated speed. A newline follows
    the binary data: the devkit's reader (``RadarPointCloud.from_file``) needs a byte there."""
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
    header = (
        f"# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\nFIELDS {names}\nSIZE {sizes}\n"
        f"TYPE {types}\nCOUNT {counts}\nWIDTH {len(rows)}\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\n"
        f"POINTS {len(rows)}\nDATA binary\n"
    )
    return header.encode() + rows.tobytes() + b"\n"


def calibration_record(
    channel: str, modality: str, translation: list[float], rotation_wxyz: list[float], intrinsic: list[list[float]]
) -> dict[str, Any]:
    return {"channel": channel, "modality": modality, "translation": translation, "rotation": rotation_wxyz,
            "camera_intrinsic": intrinsic}  # fmt: skip


def scene_chunks(frames: list[int], segment_of: dict[int, int], keyframes: list[int]) -> dict[int, int]:
    """Each frame's scene index (-1: none). A segment (frames between scene cuts) is cut into
    scenes of at most ``SCENE_KEYFRAMES`` keyframes, a third of the run's where it has fewer than
    three scenes' worth, so that it gives train, val and test scenes (3 keyframes or more). A frame
    between keyframes belongs to the scene of the next keyframe of its segment (nuScenes's
    sweeps come before their keyframe), after the last one to the last scene."""
    scenes = max(math.ceil(len(keyframes) / SCENE_KEYFRAMES), min(3, len(keyframes)))
    size = math.ceil(len(keyframes) / max(scenes, 1))
    by_segment: dict[int, list[int]] = defaultdict(list)
    for f in keyframes:
        by_segment[segment_of[f]].append(f)
    scene_of_key: dict[int, int] = {}
    for segment in sorted(by_segment):
        own = by_segment[segment]
        first = len(set(scene_of_key.values()))
        scene_of_key |= {f: first + k // size for k, f in enumerate(own)}
    scene_of = {}
    for f in frames:
        own = by_segment.get(segment_of[f], [])
        later = [g for g in own if g >= f]
        scene_of[f] = scene_of_key[later[0] if later else own[-1]] if own else -1
    return scene_of


def write_tables(root: Path, name: str, location: str, map_json: Path | None, lidar_channel: str) -> None:
    """Build the versions (``v1.0-trainval/``, ``v1.0-test/``), ``lidarseg/``, ``panoptic/`` and
    ``maps/`` under ``root`` from its ``rows/`` and ``calibration.json`` (see
    :mod:`gtgen.sinks.nuscenes_sink`): scenes of at most 20 s (:func:`scene_chunks`), split by
    :mod:`gtgen.splits` and named from nuScenes's lists (:mod:`gtgen.nuscenes_versions`)."""
    rows = [json.loads(p.read_text()) for p in sorted((root / "rows").glob("*.json"))]
    calibration = json.loads((root / "calibration.json").read_text()) if (root / "calibration.json").exists() else {}
    if not rows:
        return
    tables: Tables = {t: [] for t in TABLES}
    described = dict(CATEGORIES.values()) | SUBTYPE_CATEGORIES
    tables["category"] = [{"token": token("category", c), "name": c, "index": index,
                           "description": described.get(c, f"nuScenes-lidarseg category {c}.")}
                          for index, c in enumerate(LIDARSEG_CATEGORIES)]  # fmt: skip
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
    sample_frames = [r["frame"] for r in rows if "annotations" in r]
    scene_of = scene_chunks([r["frame"] for r in rows], {r["frame"]: int(r["scene"]) for r in rows}, sample_frames)
    sample_token = {f: token(name, "sample", f) for f in sample_frames}
    by_scene: dict[int, list[int]] = defaultdict(list)
    for f in sample_frames:
        by_scene[scene_of[f]].append(f)
    scenes = sorted(by_scene)
    splits = split_units(len(scenes))
    names = official_names(splits)
    for index in scenes:
        frames = by_scene[index]
        scene_token = token(name, "scene", index)
        start_s, end_s = (by_frame[f]["timestamp"] / 1e6 for f in (frames[0], frames[-1]))
        for k, f in enumerate(frames):
            tables["sample"].append({
                "token": sample_token[f], "timestamp": by_frame[f]["timestamp"], "scene_token": scene_token,
                "prev": sample_token[frames[k - 1]] if k > 0 else "",
                "next": sample_token[frames[k + 1]] if k + 1 < len(frames) else "",
            })  # fmt: skip
        tables["scene"].append({
            "token": scene_token, "log_token": log_token, "nbr_samples": len(frames),
            "first_sample_token": sample_token[frames[0]], "last_sample_token": sample_token[frames[-1]],
            "name": names[index], "description": f"{name}, {location}, {start_s:.1f}-{end_s:.1f} s",
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
    radar_channels = sorted(c for c, cal in calibration.items() if cal["modality"] == SensorKind.RADAR)
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
    tables["traffic_control"] = extension
    files = _point_labels(root, name, tables, lidar_channel, key_frame_of, by_scene, by_frame)
    split_of_scene = {token(name, "scene", index): split for index, split in zip(scenes, splits, strict=True)}
    for part in write_versions(root, tables, split_of_scene).values():
        for task in ("lidarseg", "panoptic"):
            for record in part[task]:
                (root / record["filename"]).write_bytes(files[f"{task}:{record['sample_data_token']}"])


def _point_labels(root: Path, name: str, tables: Tables, lidar_channel: str,
                  key_frame_of: dict[tuple[str, int], int], by_scene: dict[int, list[int]],
                  by_frame: dict[int, dict[str, Any]]) -> dict[str, bytes]:  # fmt: skip
    """The ``lidarseg`` and ``panoptic`` records of the keyframe LiDAR sweeps (into ``tables``)
    and their files' bytes by ``task:sample_data token``, from the per-point classes and
    instances staged in ``rows/NNNNNN.lidar.npz``."""
    files: dict[str, bytes] = {}
    tables["lidarseg"], tables["panoptic"] = [], []
    for frames in by_scene.values():
        number_of = number_instances([[a["id"] for a in by_frame[f]["annotations"]] for f in frames])
        for f in frames:
            at = key_frame_of.get((lidar_channel, f))
            staged = root / "rows" / f"{at:06d}.lidar.npz" if at is not None else None
            if at is None or staged is None or not staged.is_file():
                continue
            with np.load(staged) as z:
                semantic_class, instance_id = z["semantic_class"], z["instance_id"]
            sd = token(name, "sample_data", lidar_channel, at)
            annotated = by_frame[f]["annotations"]
            special = {a["id"]: a["category"] for a in annotated if a["category"] in SUBTYPE_CATEGORIES}
            files[f"lidarseg:{sd}"] = lidarseg_of_objects(semantic_class, instance_id, special).tobytes()
            files[f"panoptic:{sd}"] = npz_bytes(data=panoptic_labels(semantic_class, instance_id, number_of, special))
            for task in ("lidarseg", "panoptic"):
                tables[task].append({"token": sd, "sample_data_token": sd, "filename": ""})
    return files


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


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m gtgen.nuscenes", description=__doc__.split("\n\n")[0])
    sub = parser.add_subparsers(dest="command", required=True)
    m = sub.add_parser("merge", help="merge the nuScenes exports of several runs into one dataroot")
    m.add_argument("out", type=Path)
    m.add_argument("runs", type=Path, nargs="+")
    m.add_argument("--val", type=Path, nargs="*", help="whole runs for val (the other runs: train)")
    m.add_argument("--test", type=Path, nargs="*", help="whole runs for test (the other runs: train)")
    m.add_argument("--val-fraction", type=float, default=None, help="share of whole runs for val (the last ones)")
    args = parser.parse_args(argv)
    if args.val_fraction is not None and not 0.0 <= args.val_fraction < 1.0:
        print(f"error: --val-fraction: expected a share in [0, 1), got {args.val_fraction}", file=sys.stderr)
        return 2
    try:
        counts = merge(args.out, args.runs, args.val, args.test, args.val_fraction)
    except NuscenesError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    print(
        f"{args.out}: {counts['runs']} runs, {counts['scenes']} scenes ({counts['train_scenes']} train, "
        f"{counts['val_scenes']} val, {counts['test_scenes']} test), {counts['samples']} samples, "
        f"{counts['annotations']} annotations; versions {VERSION} and {TEST_VERSION}"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
