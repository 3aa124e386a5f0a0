"""A nuScenes dataroot's versions: the scenes of a run (or of several runs merged) split into
``v1.0-trainval`` (train and val scenes) and ``v1.0-test`` (test scenes), named from nuScenes's
official split lists, so that the devkit's ``splits.train/val/test`` (and the converters of
mmdetection3d and OpenPCDet that take scenes by them) find every scene in its split.

Both versions share the dataroot's ``samples/``, ``sweeps/`` and ``maps/``, as nuScenes's own
releases do; the tables of each version hold the records of its scenes (and the shared ones:
categories, attributes, visibility, sensors, calibrations, logs, maps). Unlike nuScenes's test
release, ``v1.0-test`` keeps its annotations. ``lidarseg/<version>/`` and
``panoptic/<version>/`` hold each version's point labels. Each version's ``splits.json`` has
the devkit's custom splits ``sim_train``, ``sim_val`` (trainval) or ``sim_test`` (test), and
``sim_all`` (the version's scenes).

``merge`` puts the ``nuscenes/`` folders of several runs into one dataroot: by default every
scene keeps the split its run gave it (scenes renamed so that names stay unique); ``--val`` and
``--test`` (or ``--val-fraction``) put whole runs into val and test instead, the other runs
into train.
"""

from __future__ import annotations

import datetime
import json
import os
import shutil
from collections import defaultdict
from collections.abc import Callable
from pathlib import Path
from typing import Any

from gtgen import nuscenes_names
from gtgen.splits import SPLITS, Split

VERSION = "v1.0-trainval"
TEST_VERSION = "v1.0-test"
TABLES = ("category", "attribute", "visibility", "sensor", "calibrated_sensor", "ego_pose", "log", "scene",
          "sample", "sample_data", "sample_annotation", "instance", "map")  # fmt: skip
Tables = dict[str, list[dict[str, Any]]]
LABEL_TASKS = ("lidarseg", "panoptic")
OPTIONAL_TABLES = ("traffic_control", *LABEL_TASKS)
NAMES: dict[str, tuple[int, ...]] = {"train": nuscenes_names.TRAIN, "val": nuscenes_names.VAL,
                                     "test": nuscenes_names.TEST}  # fmt: skip
DAY_US = 86_400_000_000


class NuscenesError(Exception):
    """A run or merge that cannot be made into the nuScenes layout (one line for the user)."""


def version_of(split: str) -> str:
    return TEST_VERSION if split == "test" else VERSION


def label_filename(task: str, version: str, sample_data_token: str) -> str:
    """Where the devkit looks for a keyframe sweep's point labels (``lidarseg`` or ``panoptic``)."""
    ext = "bin" if task == "lidarseg" else "npz"
    return f"{task}/{version}/{sample_data_token}_{task}.{ext}"


def official_names(splits: list[Split], first: dict[str, int] | None = None) -> list[str]:
    """Scene names for scenes of these splits (in order): the k-th scene of a split gets the
    k-th name of nuScenes's list for it (after the ``first`` names of each split already given)."""
    taken = dict.fromkeys(SPLITS, 0) | (first or {})
    names = []
    for split in splits:
        numbers = NAMES[split]
        if taken[split] >= len(numbers):
            raise NuscenesError(
                f"more than {len(numbers)} {split} scenes: nuScenes's {split} list has "
                f"{len(numbers)} names; merge fewer runs into one dataroot"
            )
        names.append(f"scene-{numbers[taken[split]]:04d}")
        taken[split] += 1
    return names


def _scene_finder(tables: Tables) -> dict[str, Callable[[dict[str, Any]], str | None]]:
    """For each table whose records belong to a scene: record -> scene token (None: no scene)."""
    scene_of_sample = {s["token"]: s["scene_token"] for s in tables["sample"]}
    scene_of_data = {d["token"]: scene_of_sample[d["sample_token"]] for d in tables["sample_data"]}
    scene_of_pose = {d["ego_pose_token"]: scene_of_data[d["token"]] for d in tables["sample_data"]}
    scene_of_annotation = {a["token"]: scene_of_sample[a["sample_token"]] for a in tables["sample_annotation"]}
    return {
        "scene": lambda r: r["token"],
        "sample": lambda r: r["scene_token"],
        "sample_data": lambda r: scene_of_data[r["token"]],
        "ego_pose": lambda r: scene_of_pose.get(r["token"]),
        "sample_annotation": lambda r: scene_of_sample[r["sample_token"]],
        "instance": lambda r: scene_of_annotation[r["first_annotation_token"]],
        "traffic_control": lambda r: scene_of_sample[r["sample_token"]],
        "lidarseg": lambda r: scene_of_data[r["sample_data_token"]],
        "panoptic": lambda r: scene_of_data[r["sample_data_token"]],
    }


def partition(tables: Tables, split_of_scene: dict[str, Split]) -> dict[str, Tables]:
    """The tables of each version: the records of its scenes, and every shared record."""
    versions = sorted({version_of(s) for s in split_of_scene.values()})
    out: dict[str, Tables] = {v: {t: [] for t in tables} for v in versions}
    finder = _scene_finder(tables)
    for table, records in tables.items():
        scene_of = finder.get(table)
        for record in records:
            if scene_of is None:
                for version in versions:
                    out[version][table].append(record)
                continue
            scene = scene_of(record)
            if scene is not None:
                out[version_of(split_of_scene[scene])][table].append(record)
    for version, part in out.items():
        for task in LABEL_TASKS:
            part[task] = [
                {**r, "filename": label_filename(task, version, r["sample_data_token"])} for r in part.get(task, [])
            ]
    return out


def write_versions(root: Path, tables: Tables, split_of_scene: dict[str, Split]) -> dict[str, Tables]:
    """Write each version's tables and ``splits.json`` under ``root`` (the versions, ``lidarseg/``
    and ``panoptic/`` made anew); the label files are the caller's to place, at the filenames
    of the returned tables' ``lidarseg`` and ``panoptic`` records."""
    for name in (VERSION, TEST_VERSION, *LABEL_TASKS):
        shutil.rmtree(root / name, ignore_errors=True)
    parts = partition(tables, split_of_scene)
    for version, part in parts.items():
        folder = root / version
        folder.mkdir(parents=True)
        for name in (*TABLES, *OPTIONAL_TABLES):
            if name in TABLES or part.get(name):
                (folder / f"{name}.json").write_text(json.dumps(part.get(name, []), indent=0, separators=(",", ":")))
        for task in LABEL_TASKS:
            if part.get(task):
                (root / task / version).mkdir(parents=True)
        names = {s["token"]: s["name"] for s in part["scene"]}
        by_split: dict[str, list[str]] = defaultdict(list)
        for scene, split in split_of_scene.items():
            if scene in names:
                by_split[f"sim_{split}"].append(names[scene])
        custom = {k: by_split[k] for k in (("sim_test",) if version == TEST_VERSION else ("sim_train", "sim_val"))}
        custom["sim_all"] = [s["name"] for s in part["scene"]]
        (folder / "splits.json").write_text(json.dumps(custom, indent=2) + "\n")
    return parts


def read_versions(root: Path) -> tuple[Tables, dict[str, Split]]:
    """All tables of a dataroot's versions (shared records once) and each scene's split (from
    its version's ``splits.json``)."""
    folders = [root / v for v in (VERSION, TEST_VERSION) if (root / v).is_dir()]
    if not folders:
        raise NuscenesError(f"{root}: no nuScenes export (expected {root}/{VERSION}; run with outputs.nuscenes=true)")
    tables: Tables = {t: [] for t in (*TABLES, *OPTIONAL_TABLES)}
    seen: dict[str, set[str]] = defaultdict(set)
    split_of_scene: dict[str, Split] = {}
    for folder in folders:
        missing = [t for t in TABLES if not (folder / f"{t}.json").is_file()]
        if missing:
            raise NuscenesError(f"{folder}: not a nuScenes version folder (no {missing[0]}.json)")
        custom = json.loads((folder / "splits.json").read_text()) if (folder / "splits.json").is_file() else {}
        for table in tables:
            path = folder / f"{table}.json"
            for record in json.loads(path.read_text()) if path.is_file() else []:
                key = record.get("token", json.dumps(record, sort_keys=True))
                if key not in seen[table]:
                    seen[table].add(key)
                    tables[table].append(record)
        split_of_name = {n: s for s in SPLITS for n in custom.get(f"sim_{s}", [])}
        default: Split = "test" if folder.name == TEST_VERSION else "train"
        for scene in json.loads((folder / "scene.json").read_text()):
            split_of_scene[scene["token"]] = split_of_name.get(scene["name"], default)
    return tables, split_of_scene


def merge(out: Path, runs: list[Path], val: list[Path] | None = None, test: list[Path] | None = None,
          val_fraction: float | None = None) -> dict[str, int]:  # fmt: skip
    """Merge the ``nuscenes/`` folders of ``runs`` into the dataroot ``out``: files linked (or
    copied across file systems), tables concatenated, scenes renamed from nuScenes's lists.
    Splits: each scene's own, or with ``val``/``test``/``val_fraction`` whole runs."""
    roots = [run / "nuscenes" if (run / "nuscenes").is_dir() else run for run in runs]
    for run, root in zip(runs, roots, strict=True):
        if not (root / VERSION).is_dir() and not (root / TEST_VERSION).is_dir():
            raise NuscenesError(
                f"{run}: no nuScenes export (expected {run}/nuscenes/{VERSION}; run it with outputs.nuscenes=true)"
            )
    if out.exists() and any(out.iterdir()):
        raise NuscenesError(f"{out}: the output folder exists and is not empty")
    whole = _whole_run_splits(runs, val, test, val_fraction)
    partial = out.with_name(out.name + ".partial")
    shutil.rmtree(partial, ignore_errors=True)
    merged: Tables = {t: [] for t in (*TABLES, *OPTIONAL_TABLES)}
    seen: dict[str, set[str]] = defaultdict(set)
    maps: dict[str, dict[str, Any]] = {}
    split_of_scene: dict[str, Split] = {}
    sources: dict[str, Path] = {}  # the label files by (task, sample_data token)
    for k, (run, root) in enumerate(zip(runs, roots, strict=True)):
        tables, own_splits = read_versions(root)
        tables = _retimed(tables, k)
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
                elif record["token"] not in seen[table]:
                    seen[table].add(record["token"])
                    merged[table].append(record)
        for scene in tables["scene"]:
            split_of_scene[scene["token"]] = whole[k] if whole is not None else own_splits[scene["token"]]
        for record in tables["sample_data"] + tables["map"]:
            _link(root / record["filename"], partial / record["filename"])
        for task in LABEL_TASKS:
            sources |= {f"{task}:{r['sample_data_token']}": root / r["filename"] for r in tables[task]}
    merged["map"] = list(maps.values())
    for split in SPLITS:
        scenes = [s for s in merged["scene"] if split_of_scene[s["token"]] == split]
        for scene, name in zip(scenes, official_names([split] * len(scenes)), strict=True):
            scene["name"] = name
    parts = write_versions(partial, merged, split_of_scene)
    for part in parts.values():
        for task in LABEL_TASKS:
            for record in part[task]:
                _link(sources[f"{task}:{record['sample_data_token']}"], partial / record["filename"])
    if out.exists():
        out.rmdir()  # empty, checked above
    partial.replace(out)
    counts = {f"{s}_scenes": sum(1 for v in split_of_scene.values() if v == s) for s in SPLITS}
    return {"runs": len(runs), "scenes": len(merged["scene"]), "samples": len(merged["sample"]),
            "annotations": len(merged["sample_annotation"]), **counts}  # fmt: skip


def _whole_run_splits(
    runs: list[Path], val: list[Path] | None, test: list[Path] | None, val_fraction: float | None
) -> list[Split] | None:
    """Each run's split when whole runs are split (None: each scene keeps its run's split)."""
    if not val and not test and val_fraction is None:
        return None
    resolved = [str(r.resolve()) for r in runs]
    named = {"val": val or [], "test": test or []}
    for option, paths in named.items():
        for path in paths:
            if str(path.resolve()) not in resolved:
                raise NuscenesError(f"--{option} {path}: not one of the runs merged")
    splits: list[Split] = ["train"] * len(runs)
    if val_fraction is not None and not val:
        count = max(1, round(val_fraction * len(runs))) if len(runs) > 1 else 0
        for i in range(len(runs) - count, len(runs)):
            splits[i] = "val"
    for option, paths in named.items():
        chosen = {str(p.resolve()) for p in paths}
        for i, run in enumerate(resolved):
            if run in chosen:
                splits[i] = "val" if option == "val" else "test"
    return splits


def _retimed(tables: Tables, days: int) -> Tables:
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
