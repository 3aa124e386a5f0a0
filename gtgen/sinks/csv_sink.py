"""``labels.csv``: one row per labelled object and frame (columns in :mod:`gtgen.table`).

Each frame's rows reach the file when the frame is written (the file is flushed), so an
interrupted run's rows are on disk. A run that continues an earlier one keeps the header
and the rows of the frames it keeps.
"""

from __future__ import annotations

import contextlib
from pathlib import Path

from gtgen.errors import SinkError
from gtgen.frame import FrameRecord
from gtgen.signals import SIGNAL_COLUMNS, signal_table
from gtgen.sinks.folder import cut_to
from gtgen.sinks.images import FrameImages
from gtgen.table import COLUMNS, format_rows, label_table, table_columns


def rows_of_frames(text: str, keep_frames: int) -> tuple[str, bool]:
    """The header and the rows of frames ``0 .. keep_frames - 1`` of a CSV text whose first
    column is the frame (rows in frame order, so they begin the text; a last line without its
    newline is dropped); whether it had a header."""
    lines = text.splitlines(keepends=True)
    if not lines or not lines[0].endswith("\n"):
        return "", False
    kept = [lines[0]]
    for line in lines[1:]:
        if not line.endswith("\n") or int(line.split(",", 1)[0]) >= keep_frames:
            break
        kept.append(line)
    return "".join(kept), True


class CsvSink:
    """``labels.csv``; with ``signals``, ``lights_and_signs.csv`` (columns in :mod:`gtgen.signals`)."""

    def __init__(self, path: Path, keep_frames: int = 0, signals: bool = False) -> None:
        self._signals = signals
        self._path = path
        self._partial = path.with_name(path.name + ".partial")
        self._header_written = False
        try:
            if keep_frames > 0 and not self._partial.exists() and path.exists():
                path.replace(self._partial)
            if keep_frames > 0 and self._partial.exists():  # cut in place: a full disk keeps the rows
                kept, self._header_written = rows_of_frames(self._partial.read_text(encoding="utf-8"), keep_frames)
                cut_to(self._partial, kept)
                self._file = self._partial.open("a", encoding="utf-8", newline="\n")
            else:
                self._file = self._partial.open("w", encoding="utf-8", newline="\n")
        except OSError as err:
            raise SinkError(f"{self._partial}: cannot write: {err.strerror}") from err

    def encode(self, record: FrameRecord, images: FrameImages) -> str:
        if self._signals:
            rows = format_rows(signal_table(record.labels, record.signals))
            header = SIGNAL_COLUMNS
        else:
            rows = format_rows(label_table(record.labels))
            header = table_columns(record.labels)  # the columns depend on the rig's cameras
        text = "".join(row + "\n" for row in rows)
        if not self._header_written:
            self._header_written = True
            text = ",".join(header) + "\n" + text
        return text

    def write(self, encoded: str) -> None:
        try:
            self._file.write(encoded)
            self._file.flush()
        except OSError as err:
            raise SinkError(f"{self._partial}: cannot write: {err.strerror}") from err

    def close(self) -> None:
        if not self._header_written:
            self._file.write(",".join(SIGNAL_COLUMNS if self._signals else COLUMNS) + "\n")
        self._file.close()
        self._partial.replace(self._path)

    def abort(self) -> None:
        self._file.close()
        self._partial.unlink(missing_ok=True)

    def keep(self) -> None:
        with contextlib.suppress(OSError):  # what the disk would not take is not a whole frame
            self._file.close()
