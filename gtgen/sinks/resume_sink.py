"""``.resume/states.jsonl`` in the output folder: what a run needs to continue after each frame.

One line per written frame (``frame``, the ego's pose ``map_SE3_ego`` as a 4x4 matrix, and the
frame loop's ``checkpoint``: its generator's state and counters), appended after every other
sink has written and flushed the frame, so a line stands for a frame that is on disk in every
output. The folder goes when the run completes. The writer of a run holds ``writer.lock`` there
(an advisory lock, released by the system when the process ends, however it ends).
"""

from __future__ import annotations

import contextlib
import fcntl
import json
import os
import time
from pathlib import Path
from typing import Any

from gtgen.errors import SinkError
from gtgen.frame import FrameRecord
from gtgen.sinks.folder import cut_to, kept_lines
from gtgen.sinks.images import FrameImages

RESUME_DIR = ".resume"
STATES_FILE = "states.jsonl"
LOCK_FILE = "writer.lock"


def hold_folder(out_dir: Path) -> None:
    """Hold the writer's lock of ``out_dir`` until this process ends (waiting for an earlier
    holder). The descriptor is left open on purpose: the system releases the lock at exit."""
    path = out_dir / RESUME_DIR / LOCK_FILE
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd = os.open(path, os.O_CREAT | os.O_RDWR, 0o644)
        fcntl.flock(fd, fcntl.LOCK_EX)
    except OSError as err:
        raise SinkError(f"{path}: cannot write: {err.strerror}") from err


def wait_for_writer(out_dir: Path, timeout_s: float) -> bool:
    """Wait until no process holds the writer's lock of ``out_dir`` (a killed run's writer still
    keeping its files); False if one still does after ``timeout_s``."""
    try:
        fd = os.open(out_dir / RESUME_DIR / LOCK_FILE, os.O_RDONLY)
    except OSError:
        return True  # no writer has run here
    try:
        deadline = time.monotonic() + timeout_s
        while True:
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                return True
            except BlockingIOError:
                if time.monotonic() > deadline:
                    return False
                time.sleep(0.05)
    finally:
        os.close(fd)


def read_states(out_dir: Path) -> list[dict[str, Any]]:
    """The lines of a run's states file that were written whole."""
    text = kept_lines(out_dir / RESUME_DIR / STATES_FILE, 1 << 62)
    return [json.loads(line) for line in text.splitlines()]


class ResumeSink:
    def __init__(self, out_dir: Path, keep_frames: int = 0) -> None:
        self._path = out_dir / RESUME_DIR / STATES_FILE
        try:
            self._path.parent.mkdir(parents=True, exist_ok=True)
            if keep_frames > 0 and self._path.exists():  # cut in place: a full disk keeps the lines
                cut_to(self._path, kept_lines(self._path, keep_frames))
                self._file = self._path.open("a", encoding="utf-8")
            else:
                self._file = self._path.open("w", encoding="utf-8")
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

    def keep(self) -> None:
        with contextlib.suppress(OSError):
            self._file.close()
