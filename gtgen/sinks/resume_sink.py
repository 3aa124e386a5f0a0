"""``.resume/states.jsonl`` in the output folder: what a run needs to continue after each frame.

One line per written frame (``frame``, the ego's pose ``map_SE3_ego`` as a 4x4 matrix, and the
frame loop's ``checkpoint``: its generator's state and counters), appended after every other
sink has written and flushed the frame, so a line stands for a frame that is on disk in every
output. The folder goes when the run completes.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from gtgen.errors import SinkError
from gtgen.frame import FrameRecord
from gtgen.sinks.folder import kept_lines
from gtgen.sinks.images import FrameImages

RESUME_DIR = ".resume"
STATES_FILE = "states.jsonl"


def read_states(out_dir: Path) -> list[dict[str, Any]]:
    """The lines of a run's states file that were written whole."""
    text = kept_lines(out_dir / RESUME_DIR / STATES_FILE, 1 << 62)
    return [json.loads(line) for line in text.splitlines()]


class ResumeSink:
    def __init__(self, out_dir: Path, keep_frames: int = 0) -> None:
        self._path = out_dir / RESUME_DIR / STATES_FILE
        try:
            self._path.parent.mkdir(parents=True, exist_ok=True)
            kept = kept_lines(self._path, keep_frames)
            self._file = self._path.open("w", encoding="utf-8")
            self._file.write(kept)
        except OSError as err:
            raise SinkError(f"{self._path}: cannot write: {err.strerror}") from err

    def encode(self, record: FrameRecord, images: FrameImages) -> str:
        line = {"frame": record.frame_index, "map_SE3_ego": record.map_SE3_ego.as_matrix().tolist(),
                "checkpoint": dict(record.checkpoint)}  # fmt: skip
        return json.dumps(line, separators=(",", ":")) + "\n"

    def write(self, encoded: str) -> None:
        try:
            self._file.write(encoded)
            self._file.flush()
        except OSError as err:
            raise SinkError(f"{self._path}: cannot write: {err.strerror}") from err

    def close(self) -> None:
        self._file.close()

    def abort(self) -> None:
        self._file.close()
