"""``events.csv``: one row per hazard event of the run, and ``event_frames.csv``: one row per
event and frame it was under way.

A frame row holds the event's smallest time to collision and distance to the ego over its
actors that frame, and whether some actor was seen by the LiDARs, the radars and each camera
(empty: the camera did not fire). ``events.csv`` sums the frames up when the run closes:
``kind``, first and last frame, actors, ego, minimum time to collision and distance, what saw
the actors at the first frame they are labelled in, and whether the ego collided while it
was under way.
"""

from __future__ import annotations

import csv
import io
import math
from pathlib import Path
from typing import Any

import numpy as np

from gtgen.errors import SinkError
from gtgen.frame import FrameRecord
from gtgen.sinks.csv_sink import rows_of_frames
from gtgen.sinks.folder import cut_to
from gtgen.sinks.images import FrameImages

FRAME_COLUMNS = ["frame", "timestamp", "event", "kind", "ego_id", "actors", "actors_labelled", "min_ttc",
                 "min_distance", "ego_collided", "seen_lidar", "seen_radar"]  # fmt: skip
EVENT_COLUMNS = ["event", "kind", "first_frame", "last_frame", "frames", "actors", "ego_id", "min_ttc",
                 "min_distance", "ego_collided", "seen_lidar", "seen_radar"]  # fmt: skip


def _number(value: float) -> str:
    return "" if not math.isfinite(value) else f"{value:.4f}"


class EventsSink:
    def __init__(self, out_dir: Path, keep_frames: int = 0) -> None:
        self._frames_path = out_dir / "event_frames.csv"
        self._events_path = out_dir / "events.csv"
        self._partial = self._frames_path.with_name(self._frames_path.name + ".partial")
        self._header_written = False
        try:
            if keep_frames > 0 and not self._partial.exists() and self._frames_path.exists():
                self._frames_path.replace(self._partial)
            if keep_frames > 0 and self._partial.exists():  # cut in place: a full disk keeps the rows
                kept, self._header_written = rows_of_frames(self._partial.read_text(), keep_frames)
                cut_to(self._partial, kept)
            else:
                self._partial.write_text("")
        except OSError as err:
            raise SinkError(f"{self._partial}: cannot write: {err.strerror}") from err

    def encode(self, record: FrameRecord, images: FrameImages) -> str:
        labels = record.labels
        cameras = list(labels.rig_cameras)
        out = io.StringIO()
        writer = csv.writer(out, lineterminator="\n")
        if not self._header_written:
            self._header_written = True
            writer.writerow(FRAME_COLUMNS + [f"seen_{c}" for c in cameras])
        if not record.hazards:
            return out.getvalue()
        ids = labels.objects.track_id
        for hazard in record.hazards:
            rows = np.flatnonzero(np.isin(ids, np.asarray(hazard.actor_ids, np.uint32)))
            ttc = labels.ttc_s[rows] if labels.ttc_s is not None else np.zeros(0)
            min_ttc = float(np.nanmin(ttc)) if np.isfinite(ttc).any() else math.nan
            min_distance = float(labels.distance_m[rows].min()) if rows.size else math.nan
            seen_cameras = []
            for name in cameras:
                cam = labels.camera(name)
                seen_cameras.append("" if cam is None else int((cam.visibility.visible_px[rows] > 0).any()))
            writer.writerow([
                record.frame_index, f"{record.timestamp_ns / 1e9:.3f}", hazard.name, hazard.kind, hazard.ego_id,
                " ".join(str(a) for a in hazard.actor_ids), rows.size, _number(min_ttc), _number(min_distance),
                int(record.ego_collided), int((labels.lidar_points[rows] > 0).any()),
                int((labels.radar_points[rows] > 0).any()), *seen_cameras,
            ])  # fmt: skip
        return out.getvalue()

    def write(self, encoded: str) -> None:
        try:
            with self._partial.open("a") as f:
                f.write(encoded)
        except OSError as err:
            raise SinkError(f"{self._partial}: cannot write: {err.strerror}") from err

    def close(self) -> None:
        if not self._partial.read_text():
            self._partial.write_text(",".join(FRAME_COLUMNS) + "\n")
        events_partial = self._events_path.with_name(self._events_path.name + ".partial")
        events_partial.write_text(summarize(self._partial.read_text()))
        self._partial.replace(self._frames_path)
        events_partial.replace(self._events_path)

    def abort(self) -> None:
        self._partial.unlink(missing_ok=True)

    def keep(self) -> None:
        pass  # each frame's rows are appended and closed


def summarize(frames_csv: str) -> str:
    """``events.csv`` from ``event_frames.csv``."""
    rows = list(csv.DictReader(io.StringIO(frames_csv)))
    header = frames_csv.splitlines()[0].split(",") if frames_csv else FRAME_COLUMNS
    cameras = header[len(FRAME_COLUMNS) :]
    events: dict[str, list[dict[str, Any]]] = {}
    for row in rows:
        events.setdefault(row["event"], []).append(row)
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow(EVENT_COLUMNS + cameras)
    for name, frames in sorted(events.items(), key=lambda e: int(e[1][0]["frame"])):
        # what saw the actors: at the first frame they are labelled (a pedestrian added in the
        # event's first step is in the world state from the next one)
        first = next((r for r in frames if r["actors_labelled"] not in ("", "0")), frames[0])
        ttc = [float(r["min_ttc"]) for r in frames if r["min_ttc"]]
        distance = [float(r["min_distance"]) for r in frames if r["min_distance"]]
        actors = sorted({int(a) for r in frames for a in r["actors"].split()})
        writer.writerow([
            name, first["kind"], frames[0]["frame"], frames[-1]["frame"], len(frames), " ".join(map(str, actors)),
            first["ego_id"], _number(min(ttc)) if ttc else "", _number(min(distance)) if distance else "",
            int(any(r["ego_collided"] == "1" for r in frames)), first["seen_lidar"], first["seen_radar"],
            *(first[c] for c in cameras),
        ])  # fmt: skip
    return out.getvalue()
