"""A dataset sub-folder written under ``<name>.partial`` and moved into place when complete.

A run that continues an earlier one (``keep_frames`` > 0) takes the folder back, from its
partial or its final name, and removes every per-frame file (named by frame index,
``000123.png``, at any depth; links are not followed) of the frames it does not keep.
"""

from __future__ import annotations

import shutil
from pathlib import Path

from gtgen.errors import SinkError


def frame_of(path: Path) -> int | None:
    """The frame index a per-frame file is named by (``000123.txt`` -> 123), else None."""
    return int(path.stem) if path.stem.isdigit() else None


class PartialFolder:
    def __init__(self, final: Path, subfolders: tuple[str, ...], keep_frames: int = 0) -> None:
        self.final = final
        self.partial = final.with_name(final.name + ".partial")
        if keep_frames > 0:
            self._take_back(keep_frames)
        elif self.partial.exists():
            shutil.rmtree(self.partial)
        for sub in subfolders:
            (self.partial / sub).mkdir(parents=True, exist_ok=True)

    def _take_back(self, keep_frames: int) -> None:
        if not self.partial.exists() and self.final.exists():
            self.final.replace(self.partial)
        for path in list(self.partial.rglob("*")):
            frame = frame_of(path)
            if frame is not None and frame >= keep_frames and not path.is_dir():
                path.unlink()

    def write_files(self, files: dict[str, bytes]) -> None:
        """Write ``files`` (contents by path relative to the folder) under the partial folder."""
        for relative, data in files.items():
            path = self.partial / relative
            try:
                path.write_bytes(data)
            except OSError as err:
                raise SinkError(f"{path}: cannot write: {err.strerror}") from err

    def append_file(self, relative: str, data: bytes) -> None:
        path = self.partial / relative
        try:
            with path.open("ab") as f:
                f.write(data)
        except OSError as err:
            raise SinkError(f"{path}: cannot write: {err.strerror}") from err

    def commit(self) -> None:
        if self.final.exists():
            shutil.rmtree(self.final)
        self.partial.replace(self.final)

    def discard(self) -> None:
        shutil.rmtree(self.partial, ignore_errors=True)


def cut_to(path: Path, kept: str) -> None:
    """Cut the text file ``path`` to ``kept``, its first lines, in place: no new space is needed,
    so a disk that is full keeps them."""
    with path.open("r+b") as f:
        f.truncate(len(kept.encode("utf-8")))


def kept_lines(path: Path, count: int) -> str:
    """The first ``count`` whole lines of a text file (none if it does not exist)."""
    if not path.exists():
        return ""
    lines = path.read_text().splitlines(keepends=True)
    return "".join(line for line in lines[:count] if line.endswith("\n"))
