"""``labels.csv``: one row per labelled object and frame.

The reference tool's columns come first, in its order; the extra columns follow.
"""

from __future__ import annotations

import math
from pathlib import Path

from gtgen.frame import FrameRecord
from networks.classes import SemanticClass

REFERENCE_COLUMNS = [
    "frame",
    "timestamp",
    "id",
    "type",
    "alpha",
    "left",
    "top",
    "right",
    "bottom",
    "l",
    "w",
    "h",
    "x",
    "y",
    "z",
    "rotation_z",
    "vx",
    "vy",
    "vz",
    "truncated",
    "occluded",
]
EXTRA_COLUMNS = ["class_id", "parked", "distance", "lidar_points", "seen"]
COLUMNS = REFERENCE_COLUMNS + EXTRA_COLUMNS


def _fmt(value: float) -> str:
    return "" if not math.isfinite(value) else f"{value:.4f}"


class CsvSink:
    def __init__(self, path: Path) -> None:
        self._path = path
        self._partial = path.with_name(path.name + ".partial")
        self._file = self._partial.open("w", encoding="utf-8", newline="\n")
        self._file.write(",".join(COLUMNS) + "\n")

    def write(self, record: FrameRecord) -> None:
        labels = record.labels
        o = labels.objects
        timestamp = f"{record.timestamp_ns / 1e9:.3f}"
        rows = []
        for i in range(len(o)):
            cx, cy, cz = o.center_ego_m[i]
            ln, wd, ht = o.lwh_m[i]
            vx, vy, vz = o.velocity_ego_mps[i]
            camera = ["", "", "", "", ""]  # alpha, left, top, right, bottom: filled by the camera labels
            rows.append(
                ",".join(
                    [
                        str(record.frame_index),
                        timestamp,
                        str(int(o.track_id[i])),
                        SemanticClass(o.semantic_class[i]).label,
                    ]
                    + camera
                    + [_fmt(v) for v in (ln, wd, ht, cx, cy, cz, o.yaw_ego_rad[i], vx, vy, vz)]
                    + ["", ""]  # truncated, occluded: camera labels
                    + [str(int(o.semantic_class[i])), str(int(o.parked[i])), _fmt(labels.distance_m[i])]
                    + [str(int(labels.lidar_points[i])), str(int(labels.seen[i]))]
                )
            )
        if rows:
            self._file.write("\n".join(rows) + "\n")

    def close(self) -> None:
        self._file.close()
        self._partial.replace(self._path)

    def abort(self) -> None:
        self._file.close()
