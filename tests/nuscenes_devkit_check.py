"""Read a nuScenes export with the official nuscenes-devkit (run with the devkit's own Python:
``.venv-nuscenes/bin/python tests/nuscenes_devkit_check.py DATAROOT OUT [--eval SPLIT]``).

Prints one JSON object: the scenes the devkit lists, annotation counts per category, every
token reference that does not resolve, each keyframe camera's boxes as the devkit projects
them (``get_sample_data``, corners through ``view_points``), the radar sweeps its reader reads,
the LiDAR points per nuScenes-lidarseg category and the panoptic instances as its readers load
them, the share of points whose panoptic label equals the devkit's own
``generate_panoptic_labels`` (from our lidarseg and boxes), the scenes of each official split
(``nuscenes.utils.splits``) per version, and with ``--eval`` the devkit's detection (mAP, NDS)
and tracking (AMOTA) scores of the ground truth submitted as predictions. Renders a sample
(``render_sample``, and each channel, the LiDAR also with lidarseg and panoptic colours) into OUT.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from collections import Counter
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import numpy as np
from nuscenes import NuScenes
from nuscenes.eval.common.config import config_factory
from nuscenes.eval.common.loaders import add_center_dist, filter_eval_boxes, load_gt_of_sample_tokens
from nuscenes.eval.detection import data_classes as detection_data_classes
from nuscenes.eval.detection.data_classes import (
    DetectionBox,
    DetectionConfig,
)
from nuscenes.eval.detection.evaluate import DetectionEval
from nuscenes.eval.tracking.data_classes import TrackingBox, TrackingConfig
from nuscenes.eval.tracking.evaluate import TrackingEval
from nuscenes.panoptic.generate_panoptic_labels import generate_panoptic_labels
from nuscenes.utils import splits as official
from nuscenes.utils.data_classes import LidarPointCloud, RadarPointCloud
from nuscenes.utils.data_io import load_bin_file, panoptic_to_lidarseg
from nuscenes.utils.geometry_utils import BoxVisibility, points_in_box, view_points
from nuscenes.utils.splits import get_scenes_of_custom_split

VERSION = "v1.0-trainval"
TEST_VERSION = "v1.0-test"


def unresolved(nusc: NuScenes) -> list[str]:
    """Every reference (``*_token``, ``*_tokens``, ``prev``, ``next``) that names no record."""
    targets = {"sample_token": "sample", "instance_token": "instance", "scene_token": "scene", "log_token": "log",
               "ego_pose_token": "ego_pose", "calibrated_sensor_token": "calibrated_sensor",
               "sensor_token": "sensor", "category_token": "category", "visibility_token": "visibility",
               "first_sample_token": "sample", "last_sample_token": "sample",
               "first_annotation_token": "sample_annotation", "last_annotation_token": "sample_annotation",
               "attribute_tokens": "attribute", "log_tokens": "log"}  # fmt: skip
    tokens = {t: {r["token"] for r in getattr(nusc, t)} for t in nusc.table_names}
    bad = []
    for table in nusc.table_names:
        for record in getattr(nusc, table):
            for field, value in record.items():
                target = table if field in ("prev", "next") else targets.get(field)
                if target is None:
                    continue
                for v in value if isinstance(value, list) else [value]:
                    if field in ("prev", "next") and v == "":
                        continue
                    if v not in tokens[target]:
                        bad.append(f"{table}.{field}={v}")
    return bad


def camera_boxes(nusc: NuScenes, margin_m: float = 0.0) -> list[dict[str, object]]:
    """For each keyframe camera image: the devkit's boxes in it, as 2D boxes of their corners
    (each box less ``margin_m`` at the front, back and sides and lowered by it: the labelled
    object's box, where the export grows its boxes by a margin)."""
    out = []
    for sample in nusc.sample:
        for channel, sd_token in sample["data"].items():
            sd = nusc.get("sample_data", sd_token)
            if sd["sensor_modality"] != "camera":
                continue
            _, boxes, K = nusc.get_sample_data(sd_token, box_vis_level=BoxVisibility.ANY)
            for box in boxes:
                box.wlh = box.wlh - np.array([2 * margin_m, 2 * margin_m, 0.0])
                box.center = box.center - box.rotation_matrix[:, 2] * margin_m
                corners = box.corners()
                if np.any(corners[2] <= 0.1):
                    continue  # a box reaching behind the camera: its 2D box needs clipping in 3D
                uv = view_points(corners, np.asarray(K), normalize=True)[:2]
                ann = nusc.get("sample_annotation", box.token)
                out.append(
                    {
                        "sample_data": sd_token,
                        "channel": channel,
                        "timestamp": sd["timestamp"],
                        "instance": ann["instance_token"],
                        "scene": sample["scene_token"],
                        "box": [float(uv[0].min()), float(uv[1].min()), float(uv[0].max()), float(uv[1].max())],
                    }
                )
    return out


def render(nusc: NuScenes, out: Path) -> list[str]:
    """A sample in the middle of the first scene: ``render_sample`` (every channel at once), each
    channel with its boxes, and the LiDAR with its lidarseg and panoptic colours."""
    scene = nusc.scene[0]
    token = scene["first_sample_token"]
    for _ in range(scene["nbr_samples"] // 2):
        token = nusc.get("sample", token)["next"] or token
    sample = nusc.get("sample", token)
    nusc.render_sample(token, out_path=str(out / "sample.png"), verbose=False)
    written = [str(out / "sample.png")]
    for channel, sd_token in sorted(sample["data"].items()):
        path = out / f"{channel}.png"
        nusc.render_sample_data(sd_token, with_anns=True, out_path=str(path), verbose=False)
        written.append(str(path))
    lidar = sample["data"]["LIDAR_TOP"]
    for kind in ("lidarseg", "panoptic"):
        path = out / f"LIDAR_TOP_{kind}.png"
        nusc.render_sample_data(
            lidar, show_lidarseg=kind == "lidarseg", show_panoptic=kind == "panoptic", out_path=str(path), verbose=False
        )
        written.append(str(path))
    return written


def radar_sweeps(nusc: NuScenes) -> dict[str, int]:
    """Every radar file read by the devkit's reader: files and points."""
    files = points = 0
    for sd in nusc.sample_data:
        if sd["sensor_modality"] == "radar":
            points += RadarPointCloud.from_file(str(Path(nusc.dataroot) / sd["filename"])).nbr_points()
            files += 1
    return {"files": files, "points": points}


def point_labels(nusc: NuScenes, out: Path) -> dict[str, object]:
    """Points per lidarseg category (the devkit's reader), the panoptic labels' semantics against
    lidarseg, instances per scene, and the share of points whose panoptic label the devkit's own
    generator (points in boxes, from our lidarseg) gives the same."""
    per_category: Counter[str] = Counter()
    same_semantics = points = 0
    instances: set[tuple[str, int]] = set()
    for record in nusc.lidarseg:
        sd = nusc.get("sample_data", record["sample_data_token"])
        cloud = LidarPointCloud.from_file(str(Path(nusc.dataroot) / sd["filename"]))
        labels = load_bin_file(str(Path(nusc.dataroot) / record["filename"]), type="lidarseg")
        panoptic = load_bin_file(
            str(Path(nusc.dataroot) / nusc.get("panoptic", sd["token"])["filename"]), type="panoptic"
        )
        assert len(labels) == len(panoptic) == cloud.nbr_points()
        per_category.update(nusc.lidarseg_idx2name_mapping[int(i)] for i in labels)
        same_semantics += int(np.sum(panoptic_to_lidarseg(panoptic) == labels))
        points += len(labels)
        scene = nusc.get("sample", sd["sample_token"])["scene_token"]
        instances |= {(scene, int(v % 1000)) for v in np.unique(panoptic) if v % 1000}
    ours = {
        r["sample_data_token"]: load_bin_file(str(Path(nusc.dataroot) / r["filename"]), type="panoptic")
        for r in nusc.panoptic
    }
    generate_panoptic_labels(nusc, str(out / "devkit_panoptic"))
    agree = total = still_differ = 0
    for sd_token, labels in ours.items():
        theirs = np.load(out / "devkit_panoptic" / "panoptic" / nusc.version / f"{sd_token}_panoptic.npz")["data"]
        agree += int(np.sum(theirs == labels))
        total += len(labels)
        still = standing_instances(nusc, nusc.get("sample_data", sd_token)["sample_token"])
        differ = np.flatnonzero((theirs != labels) & np.isin(labels % 1000, list(still)) & (labels % 1000 > 0))
        still_differ += int(np.sum(boxes_holding(nusc, sd_token, differ, labels // 1000) < 2))
    return {"sweeps": len(nusc.lidarseg), "points": points, "per_category": dict(per_category),
            "panoptic_semantics_equal": same_semantics, "instances": len(instances),
            "devkit_panoptic_agreement": agree / max(total, 1),
            "devkit_panoptic_standing_differ": still_differ}  # fmt: skip


def boxes_holding(nusc: NuScenes, sd_token: str, index: np.ndarray, category: np.ndarray) -> np.ndarray:
    """For the sweep's points ``index``, how many of the sample's boxes of the point's lidarseg
    category hold them (the devkit's generator blanks points in more than one)."""
    sd = nusc.get("sample_data", sd_token)
    points = LidarPointCloud.from_file(str(Path(nusc.dataroot) / sd["filename"])).points[:3, index]
    count = np.zeros(len(index), int)
    for ann_token in nusc.get("sample", sd["sample_token"])["anns"]:
        ann = nusc.get("sample_annotation", ann_token)
        _, boxes, _ = nusc.get_sample_data(sd_token, selected_anntokens=[ann_token])
        same = category[index] == nusc.lidarseg_name2idx_mapping[ann["category_name"]]
        count += points_in_box(boxes[0], points) & same
    return count


def standing_instances(nusc: NuScenes, sample_token: str) -> set[int]:
    """The panoptic instance ids (numbered per scene in the order the devkit's
    ``generate_panoptic_labels`` meets them) of the sample's objects that stand still: their
    points are where their box is, whatever the sweep's timing."""
    sample = nusc.get("sample", sample_token)
    ids: dict[str, int] = {}
    for s in nusc.sample:  # the devkit numbers instances over the scene's samples in table order
        if s["scene_token"] != sample["scene_token"]:
            continue
        for ann_token in s["anns"]:
            ids.setdefault(nusc.get("sample_annotation", ann_token)["instance_token"], len(ids) + 1)
        if s["token"] == sample_token:
            break
    still = set()
    for ann_token in sample["anns"]:
        velocity = np.nan_to_num(nusc.box_velocity(ann_token))
        if np.linalg.norm(velocity[:2]) < 0.05:
            still.add(ids[nusc.get("sample_annotation", ann_token)["instance_token"]])
    return still


def official_splits(nusc: NuScenes) -> dict[str, list[str]]:
    """The version's scenes in each official split list, as the frameworks' converters take them."""
    names = [s["name"] for s in nusc.scene]
    lists = {"train": official.train, "val": official.val, "test": official.test}
    return {split: [n for n in names if n in scenes] for split, scenes in lists.items()}


def submission(path: Path, boxes: object, score: str, samples: list[str]) -> Path:
    """A results file of ``boxes`` (the devkit's EvalBoxes), each with ``score`` 1, every
    sample of the split present."""
    meta = {"use_camera": False, "use_lidar": True, "use_radar": False, "use_map": False, "use_external": False}
    results: dict[str, list[dict[str, object]]] = {t: [] for t in samples}
    for box in boxes.all:  # type: ignore[attr-defined]
        results[box.sample_token].append({**box.serialize(), score: 1.0})
    path.write_text(json.dumps({"meta": meta, "results": results}, default=lambda v: v.tolist()))
    return path


def ground_truth_as_predictions(nusc: NuScenes, split: str, out: Path) -> dict[str, float]:
    """The devkit's detection and tracking evaluations of the ground truth, submitted as
    predictions (the boxes the devkit keeps for evaluation, score 1)."""
    scenes = set(get_scenes_of_custom_split(split, nusc))
    samples = [s["token"] for s in nusc.sample if nusc.get("scene", s["scene_token"])["name"] in scenes]
    default = config_factory("detection_cvpr_2019")
    loaded = load_gt_of_sample_tokens(nusc, samples, DetectionBox)
    loaded_names = sorted({b.detection_name for b in loaded.all})  # before the filter, which works in place
    gt = filter_eval_boxes(nusc, add_center_dist(nusc, loaded), default.class_range)
    # A scene without trailers, construction vehicles, barriers or traffic cones (they come with
    # construction zones and trucks with trailers) has no box of theirs, and a class without a
    # box the devkit keeps scores AP 0: the classes evaluated are those with kept boxes.
    # DetectionConfig insists on all ten names, so it is made with the names of the classes
    # loaded (the devkit's filter needs their ranges), then evaluates the kept ones.
    present = sorted({b.detection_name for b in gt.all})
    detection = default.serialize()
    detection["class_range"] = {c: default.class_range[c] for c in loaded_names}
    names = detection_data_classes.DETECTION_NAMES
    detection_data_classes.DETECTION_NAMES = list(detection["class_range"])
    try:
        config = DetectionConfig.deserialize(detection)
    finally:
        detection_data_classes.DETECTION_NAMES = names
    config.class_names = present
    det_path = submission(out / "detection_results.json", gt, "detection_score", samples)
    det = DetectionEval(
        nusc, config=config, result_path=str(det_path), eval_set=split, output_dir=str(out / "detection"), verbose=False
    )
    metrics, _ = det.evaluate()
    summary = metrics.serialize()

    tracking_default = config_factory("tracking_nips_2019")
    t_loaded = load_gt_of_sample_tokens(nusc, samples, TrackingBox)
    loaded_tracks = sorted({b.tracking_name for b in t_loaded.all})
    tgt = filter_eval_boxes(nusc, add_center_dist(nusc, t_loaded), tracking_default.class_range)
    tracked = sorted({b.tracking_name for b in tgt.all})
    tracking = tracking_default.serialize()
    tracking["tracking_names"] = loaded_tracks
    tracking["class_range"] = {c: tracking_default.class_range[c] for c in loaded_tracks}
    tracking_config = TrackingConfig.deserialize(tracking)
    tracking_config.class_names = tracked
    track_path = submission(out / "tracking_results.json", tgt, "tracking_score", samples)
    trk = TrackingEval(config=tracking_config, result_path=str(track_path), eval_set=split,
                       output_dir=str(out / "tracking"), nusc_version=nusc.version, nusc_dataroot=nusc.dataroot,
                       verbose=False)  # fmt: skip
    tracking_metrics, _ = trk.evaluate()
    t_summary = tracking_metrics.serialize()
    return {"mAP": summary["mean_ap"], "NDS": summary["nd_score"], "AMOTA": t_summary["amota"],
            "detection_classes": present, "tracking_classes": tracked, "class_ap": summary["mean_dist_aps"],
            "gt_per_class": dict(Counter(b.detection_name for b in gt.all)),
            "gt_boxes": len(gt.all), "samples": len(samples)}  # fmt: skip


def main() -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument("dataroot", type=Path)
    parser.add_argument("out", type=Path)
    parser.add_argument("--eval", default="")
    parser.add_argument("--no-render", action="store_true")
    parser.add_argument(
        "--margin", type=float, default=0.0, help="the export's box margin (m), taken off the camera boxes"
    )
    parser.add_argument("--lists", action="store_true", help="also print the devkit's official split lists")
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    report: dict[str, object] = {}
    with open(os.devnull, "w") as quiet:
        stdout, sys.stdout = sys.stdout, quiet
        try:
            nusc = NuScenes(version=VERSION, dataroot=str(args.dataroot), verbose=False)
            report |= {
                "scenes": [s["name"] for s in nusc.scene],
                "samples": len(nusc.sample),
                "per_category": dict(Counter(a["category_name"] for a in nusc.sample_annotation)),
                "unresolved": unresolved(nusc),
                "camera_boxes": camera_boxes(nusc, args.margin),
                "radar": radar_sweeps(nusc),
                "point_labels": point_labels(nusc, args.out),
                "official_splits": {VERSION: official_splits(nusc)},
            }
            nusc.list_scenes()
            if (args.dataroot / TEST_VERSION).is_dir():
                test = NuScenes(version=TEST_VERSION, dataroot=str(args.dataroot), verbose=False)
                report["official_splits"][TEST_VERSION] = official_splits(test)  # type: ignore[index]
                report["test_unresolved"] = unresolved(test)
                report["test_point_labels"] = len(test.lidarseg)
                report["test_per_category"] = dict(Counter(a["category_name"] for a in test.sample_annotation))
            if args.lists:
                report["lists"] = {s: [int(n[-4:]) for n in getattr(official, s)] for s in ("train", "val", "test")}
            if not args.no_render:
                report["rendered"] = render(nusc, args.out)
            if args.eval:
                report["eval"] = ground_truth_as_predictions(nusc, args.eval, args.out)
        finally:
            sys.stdout = stdout
    print(json.dumps(report))
    return 0


if __name__ == "__main__":
    sys.exit(main())
