"""What a run shows, set against real driving data: seen objects near the ego by class, and
how much of the time the ego stands.

Per frame, the objects within ``RADIUS_M`` of the ego (horizontal distance of the box centre,
``labels.csv``'s ``distance``) that some sensor saw (``seen``), by class; cyclists are the
bicycles with their riders (not parked ones), parked vehicles are counted apart as well. The
ego's speed comes from the ``map -> ego`` transforms of ``run.mcap`` (``/tf``), the distance
between consecutive frames over their time (the first frame of a scene takes the next
frame's); the ego stands in a frame when its speed is below ``STOPPED_MPS``.

``python -m gtgen.content RUN [RUN ...]`` prints one row per run folder (a Markdown table);
``summary/content.csv`` holds the same numbers for one run.
"""

from __future__ import annotations

import argparse
import json
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import numpy.typing as npt
import pandas as pd

from gtgen.load import iter_messages, load_labels
from gtgen.topics import TF

RADIUS_M = 50.0
STOPPED_MPS = 0.1
CLASSES = ("pedestrian", "cyclist", "car", "truck", "bus", "motorcycle", "parked")
"""Columns of the table: ``cyclist`` is an unparked bicycle, ``parked`` any parked vehicle."""
REFERENCE = {
    "nuScenes": {"pedestrian": "6.5", "cyclist": "0.35"},
    "KITTI": {"cyclist": "0.22"},
}
"""Per keyframe (nuScenes v1.0-trainval annotations) and per front image (KITTI object training set)."""


@dataclass(frozen=True, slots=True)
class Content:
    frames: int
    per_frame: dict[str, float]  # seen within RADIUS_M per frame, by class (CLASSES and any other type)
    stopped_share: float  # of the frames with a speed: the ego slower than STOPPED_MPS
    speed_frames: int  # frames with an ego speed (0: no /tf in the run)

    def rows(self) -> list[tuple[str, float]]:
        return [("frames", float(self.frames)), *self.per_frame.items(), ("ego_stopped_share", self.stopped_share),
                ("ego_speed_frames", float(self.speed_frames))]  # fmt: skip


def seen_near(labels: pd.DataFrame, frames: int, radius_m: float = RADIUS_M) -> dict[str, float]:
    """Seen objects within ``radius_m`` of the ego per frame, by class (see :data:`CLASSES`)."""
    near = labels[(labels["seen"] == 1) & (labels["distance"] <= radius_m)]
    parked = near["parked"].fillna(0).astype(int) == 1
    n = max(frames, 1)
    out = {c: 0.0 for c in CLASSES}
    for cls, count in near[~parked]["type"].value_counts().items():
        out["cyclist" if cls == "bicycle" else str(cls)] = count / n
    out["parked"] = float(parked.sum()) / n
    return out


def ego_speeds(mcap_path: Path, scene_cuts: list[int] | tuple[int, ...] = ()) -> npt.NDArray[np.float64]:
    """The ego's speed over the ground in each frame of a run (m/s), from its ``/tf``."""
    times, xyz = [], []
    for _topic, log_time, msg in iter_messages(mcap_path, topics=[TF]):
        for t in msg.transforms:
            if t.parent_frame_id == "map" and t.child_frame_id == "ego":
                times.append(log_time * 1e-9)
                xyz.append((t.translation.x, t.translation.y, t.translation.z))
                break
    return speeds_of(np.asarray(times, np.float64), np.asarray(xyz, np.float64).reshape(-1, 3), scene_cuts)


def speeds_of(
    times_s: npt.NDArray[np.float64], xyz: npt.NDArray[np.float64], scene_cuts: list[int] | tuple[int, ...] = ()
) -> npt.NDArray[np.float64]:
    """Speed in each frame from positions: the step from the frame before over its time; a
    scene's first frame (the run's, or a cut's) takes the next frame's."""
    n = len(times_s)
    if n < 2:
        return np.zeros(n)
    step = np.linalg.norm(np.diff(xyz, axis=0), axis=1) / np.maximum(np.diff(times_s), 1e-9)
    speed = np.concatenate([[step[0]], step])
    for cut in sorted(scene_cuts):
        if 0 < cut < n:
            speed[cut] = speed[cut + 1] if cut + 1 < n else 0.0
    return speed


def measure(run_dir: Path) -> Content:
    """The content of one run folder (``labels.csv``, and ``run.mcap`` for the ego's speed)."""
    labels = load_labels(run_dir / "labels.csv")
    manifest = run_dir / "manifest.json"
    meta = json.loads(manifest.read_text()) if manifest.exists() else {}
    cuts = [int(f) for f in meta.get("scene_cuts", [])]
    speeds = ego_speeds(run_dir / "run.mcap", cuts) if (run_dir / "run.mcap").exists() else np.zeros(0)
    frames = int(meta.get("frames") or max(int(labels["frame"].max()) + 1 if len(labels) else 0, len(speeds)))
    stopped = float((speeds < STOPPED_MPS).mean()) if len(speeds) else 0.0
    return Content(frames, seen_near(labels, frames), stopped, len(speeds))


def write_content(run_dir: Path, folder: Path) -> Content:
    """``folder/content.csv``: ``quantity, value`` rows of :func:`measure`."""
    content = measure(run_dir)
    pd.DataFrame(content.rows(), columns=["quantity", "value"]).to_csv(
        folder / "content.csv", index=False, float_format="%.3f"
    )
    return content


def table(runs: list[tuple[str, Content]]) -> list[str]:
    """A Markdown table: one row per run, the references below."""
    head = ["run", "frames", *CLASSES, "ego stopped %"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for name, c in runs:
        cells = [name, str(c.frames), *(f"{c.per_frame.get(k, 0.0):.2f}" for k in CLASSES)]
        cells.append(f"{100 * c.stopped_share:.0f}" if c.speed_frames else "")
        lines.append("| " + " | ".join(cells) + " |")
    for name, ref in REFERENCE.items():
        lines.append("| " + " | ".join([name, "", *(ref.get(k, "") for k in CLASSES), ""]) + " |")
    return lines


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m gtgen.content", description=__doc__.split("\n\n")[0])
    parser.add_argument("runs", type=Path, nargs="+", help="run folders (each with labels.csv and run.mcap)")
    args = parser.parse_args(argv)
    runs = []
    for run in args.runs:
        if not (run / "labels.csv").is_file():
            print(f"{run}: no labels.csv (expected a run folder written by `python -m cosim run`)", file=sys.stderr)
            return 2
        runs.append((run.name, measure(run)))
    print(f"seen objects within {RADIUS_M:g} m per frame by class; the ego stopped below {STOPPED_MPS:g} m/s")
    print("\n".join(table(runs)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
