"""``summary/``: statistics and pictures of a written dataset, read back from its files.

``stats.csv`` (per class), ``objects_per_frame.png``, ``distance.png``, ``visibility.png``,
``lidar_points.png``, ``content.csv`` (seen objects within 50 m per frame by class, the ego's
stopped share: :mod:`gtgen.content`), and for a few frames ``bev_<frame>.png`` (LiDAR points by class with
the label boxes) and ``camera_<frame>.png`` (the image with tight and projected boxes). A run
with hazards adds ``events.csv`` (events per kind, per minute, median and smallest time to
collision) and ``events.png`` (each event's minimum time to collision, by kind). A run with
occupancy adds ``occupancy_<frame>.png`` and ``occupancy_3d_<frame>.png`` of its middle frame
(:mod:`gtgen.occupancy_pictures`).
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path
from typing import Any

import cv2
import matplotlib
import numpy as np
import numpy.typing as npt
import pandas as pd

from gtgen.bev import bev_image, map_bev_image
from gtgen.content import write_content
from gtgen.load import iter_messages, lidar_points, load_labels, load_map_frame, objects_from_table, topics
from gtgen.topics import MAP, TF
from networks.geometry import SE3, rotation_from_quaternion_xyzw

matplotlib.use("Agg")
import matplotlib.pyplot as plt

CLASS_ORDER = ["car", "truck", "bus", "motorcycle", "bicycle", "pedestrian"]


def class_stats(labels: pd.DataFrame) -> pd.DataFrame:
    """Per class: labelled and seen objects per frame, tracks, parked share, LiDAR points."""
    frames = max(labels["frame"].nunique(), 1)
    seen = labels[labels["seen"] == 1]
    rows = []
    for cls in [c for c in CLASS_ORDER if c in set(labels["type"])]:
        all_c, seen_c = labels[labels["type"] == cls], seen[seen["type"] == cls]
        rows.append({
            "class": cls, "labelled_per_frame": len(all_c) / frames, "seen_per_frame": len(seen_c) / frames,
            "tracks": all_c["id"].nunique(), "parked_share": float(all_c["parked"].mean()),
            "median_lidar_points_seen": float(seen_c["lidar_points"].median()) if len(seen_c) else 0.0,
            "camera_visible_per_frame": float((seen_c["camera_visible_px"].fillna(0) > 0).sum() / frames),
        })  # fmt: skip
    total = {"class": "all", "labelled_per_frame": len(labels) / frames, "seen_per_frame": len(seen) / frames,
             "tracks": labels["id"].nunique(), "parked_share": float(labels["parked"].mean()) if len(labels) else 0.0,
             "median_lidar_points_seen": float(seen["lidar_points"].median()) if len(seen) else 0.0,
             "camera_visible_per_frame": float((seen["camera_visible_px"].fillna(0) > 0).sum() / frames)}  # fmt: skip
    return pd.DataFrame([*rows, total])


def _save(fig: Any, path: Path) -> None:
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def plot_summary(labels: pd.DataFrame, folder: Path) -> None:
    seen = labels[labels["seen"] == 1]
    classes = [c for c in CLASS_ORDER if c in set(seen["type"])]
    fig, ax = plt.subplots(figsize=(8, 4))
    counts = seen.groupby(["frame", "type"]).size().unstack(fill_value=0).reindex(columns=classes, fill_value=0)
    if len(counts):
        ax.stackplot(counts.index, counts.T.to_numpy(), labels=classes)
        ax.legend(loc="upper left", fontsize=8)
    ax.set(xlabel="frame", ylabel="objects seen", title="Objects seen per frame")
    _save(fig, folder / "objects_per_frame.png")
    fig, ax = plt.subplots(figsize=(8, 4))
    for cls in classes:
        ax.hist(seen.loc[seen["type"] == cls, "distance"], bins=list(range(0, 125, 5)), histtype="step", label=cls)
    ax.set(xlabel="distance from the ego (m)", ylabel="objects", title="Seen objects by distance")
    ax.legend(fontsize=8)
    _save(fig, folder / "distance.png")
    fig, ax = plt.subplots(figsize=(8, 4))
    in_image = labels[labels["camera_visible_px"].fillna(0) > 0]
    bins = in_image.groupby(["type", "visibility_bin"]).size().unstack(fill_value=0)
    bins = bins.reindex([c for c in classes if c in bins.index])
    if bins.size:
        bins.plot.bar(ax=ax, rot=0)
    else:
        ax.text(0.5, 0.5, "no object visible in a camera", ha="center", va="center", transform=ax.transAxes)
    ax.set(ylabel="objects", title="Camera visibility bins (1: 0-40 %, 2: 40-60 %, 3: 60-80 %, 4: 80-100 %)")
    _save(fig, folder / "visibility.png")
    fig, ax = plt.subplots(figsize=(8, 4))
    for cls in classes:
        c = seen[(seen["type"] == cls) & (seen["lidar_points"] > 0)]
        ax.scatter(c["distance"], c["lidar_points"], s=3, label=cls)
    ax.set(xlabel="distance (m)", ylabel="LiDAR points", yscale="log", title="LiDAR points per object")
    ax.legend(fontsize=8)
    _save(fig, folder / "lidar_points.png")


def _ego_SE3(transforms: Any, child: str) -> SE3:
    for t in transforms.transforms:
        if t.parent_frame_id == "ego" and t.child_frame_id == child:
            q = t.rotation
            translation = np.array([t.translation.x, t.translation.y, t.translation.z])
            return SE3(rotation_from_quaternion_xyzw(q.x, q.y, q.z, q.w), translation)
    return SE3.identity()


def frame_pictures(mcap_path: Path, labels: pd.DataFrame, frames: list[int], folder: Path) -> None:
    """BEV and camera pictures of ``frames`` (indices in the run)."""
    wanted = set(frames)
    index_of_time: dict[int, int] = {}
    tf: dict[int, Any] = {}
    names = topics(mcap_path)
    camera = next((t for t in names if t.endswith("/image")), "/camera/image")  # the rig's first camera
    clouds = [t for t in names if t.count("/") == 1 and t not in (TF, MAP)]  # LiDARs and radars
    lidar = ""  # the first topic whose clouds have rings
    for topic, log_time, msg in iter_messages(mcap_path, topics=[TF, camera, *clouds]):
        if topic in clouds and not lidar and any(f.name == "ring" for f in msg.fields):
            lidar = topic
        frame = index_of_time.setdefault(log_time, len(index_of_time))
        if frame not in wanted:
            continue
        rows = labels[labels["frame"] == frame]
        if topic == TF:
            tf[frame] = msg
        elif topic == lidar:
            pts = lidar_points(msg)
            xyz = np.column_stack([pts["x"], pts["y"], pts["z"]]).astype(np.float64)
            xyz_ego = _ego_SE3(tf[frame], msg.frame_id).transform_from(xyz) if frame in tf else xyz
            objects, seen = objects_from_table(rows)
            cv2.imwrite(str(folder / f"bev_{frame:06d}.png"), bev_image(xyz_ego, pts["class"], objects, seen))
            run_dir = mcap_path.parent
            if (run_dir / "map" / "vectors" / f"{frame:06d}.json").exists():
                vectors, layers = load_map_frame(run_dir, frame)
                picture = map_bev_image(vectors, layers, xyz_ego, pts["class"], objects, seen)
                cv2.imwrite(str(folder / f"map_{frame:06d}.png"), picture)
        elif topic == camera:
            image = np.asarray(cv2.imdecode(np.frombuffer(msg.data, np.uint8), cv2.IMREAD_COLOR), dtype=np.uint8)
            cv2.imwrite(str(folder / f"camera_{frame:06d}.png"), draw_camera_boxes(image, rows))


def draw_camera_boxes(image: npt.NDArray[np.uint8], rows: pd.DataFrame) -> npt.NDArray[np.uint8]:
    out = image.copy()
    for r in rows.itertuples():
        if np.isfinite(r.left):
            cv2.rectangle(out, (int(r.left), int(r.top)), (int(r.right), int(r.bottom)), (0, 220, 255), 1)
        if r.camera_visible_px > 0 and np.isfinite(r.modal_left):
            p0, p1 = (int(r.modal_left), int(r.modal_top)), (int(r.modal_right), int(r.modal_bottom))
            cv2.rectangle(out, p0, p1, (0, 0, 255), 2)
            text = f"{r.type} {r.id} occ{int(r.occluded)} {r.visible_fraction:.2f}"
            cv2.putText(out, text, (p0[0], max(p0[1] - 4, 10)), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (255, 255, 255), 1)
    return out


def hazard_lines(out_dir: Path) -> list[str]:
    """What the run's summary says of its hazard events, a line per kind ([] without hazards)."""
    table = out_dir / "summary" / "events.csv"
    if not table.exists():
        return []
    lines = []
    for row in pd.read_csv(table).itertuples():
        ttc = "" if pd.isna(row.smallest_min_ttc) else f", smallest time to collision {row.smallest_min_ttc:.2f} s"
        lines.append(
            f"hazard events, {row.kind}: {row.events} ({row.per_minute:.1f} a minute, "
            f"{row.asked_per_minute:g} asked{ttc})"
        )
        if row.per_minute < row.asked_per_minute / 2:
            lines.append(
                f"  fewer than asked: a {row.kind} starts only where the ego's way allows it "
                "(see Hazard scenes in the README)"
            )
    return lines


def write_summary(out_dir: Path, picture_frames: int = 3, asked: dict[str, float] | None = None) -> pd.DataFrame:
    """Write ``out_dir/summary`` from ``labels.csv`` and ``run.mcap``; return the class table.
    It is written as ``summary.partial`` and moved into place when whole. ``asked``: the hazard
    events a minute of each kind the scenario asked for (default: from ``manifest.json``)."""
    labels = load_labels(out_dir / "labels.csv")
    folder = out_dir / "summary.partial"
    shutil.rmtree(folder, ignore_errors=True)
    folder.mkdir()
    stats = _write_summary(out_dir, labels, folder, picture_frames, asked)
    shutil.rmtree(out_dir / "summary", ignore_errors=True)  # an earlier summary (of an interrupted run) goes
    folder.replace(out_dir / "summary")
    return stats


def _write_summary(
    out_dir: Path, labels: pd.DataFrame, folder: Path, picture_frames: int, asked: dict[str, float] | None
) -> pd.DataFrame:
    stats = class_stats(labels)
    stats.to_csv(folder / "stats.csv", index=False, float_format="%.3f")
    write_content(out_dir, folder)
    plot_summary(labels, folder)
    n = int(labels["frame"].max()) + 1 if len(labels) else 0
    if n and (out_dir / "run.mcap").exists():
        picks = sorted({0, n // 2, n - 1}) if picture_frames >= 3 else [0]
        frame_pictures(out_dir / "run.mcap", labels, picks, folder)
    if n and (out_dir / "occupancy").is_dir():
        from gtgen.occupancy_pictures import occupancy_pictures

        occupancy_pictures(out_dir, n // 2, folder)
    if (out_dir / "events.csv").exists():
        minutes = labels["timestamp"].nunique() and (labels["timestamp"].max() - labels["timestamp"].min()) / 60.0
        if asked is None:
            manifest = out_dir / "manifest.json"
            scenario = json.loads(manifest.read_text()).get("scenario", {}) if manifest.exists() else {}
            asked = asked_rates(scenario.get("hazards", []))
        event_summary(pd.read_csv(out_dir / "events.csv"), float(minutes or 0.0), folder, asked)
    return stats


def asked_rates(hazards: list[dict[str, Any]]) -> dict[str, float]:
    """The events a minute of each kind that a scenario's ``hazards`` (plain data) ask for."""
    asked: dict[str, float] = {}
    for hazard in hazards:
        asked[hazard["kind"]] = asked.get(hazard["kind"], 0.0) + float(hazard["per_minute"])
    return asked


def event_summary(events: pd.DataFrame, minutes: float, folder: Path, asked: dict[str, float] | None = None) -> None:
    """``summary/events.csv`` (per kind: events, per minute and as asked in the scenario, median
    and smallest minimum time to collision) and ``summary/events.png`` (each event's minimum
    time to collision). ``asked``: the scenario's events per minute of each kind (kinds without
    an event are listed too)."""
    asked = asked or {}
    rows = []
    for kind in sorted(set(events["kind"]) | set(asked)):
        group = events[events["kind"] == kind]
        ttc = group["min_ttc"].dropna()
        rows.append({"kind": kind, "events": len(group), "per_minute": len(group) / minutes if minutes else np.nan,
                     "asked_per_minute": asked.get(kind, np.nan),
                     "median_min_ttc": float(ttc.median()) if len(ttc) else np.nan,
                     "smallest_min_ttc": float(ttc.min()) if len(ttc) else np.nan,
                     "ego_collided": int(group["ego_collided"].sum())})  # fmt: skip
    columns = ["kind", "events", "per_minute", "asked_per_minute", "median_min_ttc", "smallest_min_ttc", "ego_collided"]
    pd.DataFrame(rows, columns=columns).to_csv(folder / "events.csv", index=False, float_format="%.3f")
    fig, ax = plt.subplots(figsize=(8, 4))
    for kind, group in events.groupby("kind"):
        shown = group.dropna(subset=["min_ttc"])
        ax.scatter(shown["first_frame"], shown["min_ttc"].clip(upper=10.0), label=f"{kind} ({len(group)})", s=30)
    ax.axhline(4.0, color="grey", lw=0.8, ls="--")
    ax.set(
        xlabel="frame the event starts",
        ylabel="minimum time to collision [s] (10 = 10 or more)",
        title=f"{len(events)} hazard events",
        ylim=(0, 10.5),
    )
    if len(events):
        ax.legend(loc="upper right")
    _save(fig, folder / "events.png")
