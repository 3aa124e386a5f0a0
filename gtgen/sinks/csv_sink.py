"""``labels.csv``: one row per labelled object and frame (columns in :mod:`gtgen.table`).

Each frame's rows reach the file when the frame is written (the file is flushed), so an
interrupted run's rows are on disk. A run that continues an earlier one keeps the header
and the rows of the frames it keeps.
"""

from __future__ import annotations

from pathlib import Path

from gtgen.errors import SinkError
from gtgen.frame import FrameRecord
from gtgen.signals import SIGNAL_COLUMNS, signal_table
from gtgen.sinks.images import FrameImages
from gtgen.table import COLUMNS, format_rows, label_table, table_columns


def rows_of_frames(text: str, keep_frames: int) -> tuple[str, bool]:
    """The header and the rows of frames ``0 .. keep_frames - 1`` of a labels.csv text (the
    frame is the first column; a last line without its newline is dropped); whether it had a header."""
    lines = [line for line in text.splitlines(keepends=True) if line.endswith("\n")]
    if not lines:
        return "", False
    rows = [line for line in lines[1:] if int(line.split(",", 1)[0]) < keep_frames]
    return lines[0] + "".join(rows), True


class CsvSink:
    """``labels.csv``; with ``signals``, ``lights_and_signs.csv`` (columns in :mod:`gtgen.signals`)."""

    def __init__(self, path: Path, keep_frames: int = 0, signals: bool = False) -> None:
        self._signals = signals
        self._path = path
        self._partial = path.with_name(path.name + ".partial")
        kept, self._header_written = "", False
        if keep_frames > 0:
            source = self._partial if self._partial.exists() else path
            if source.exists():
                kept, self._header_written = rows_of_frames(source.read_text(encoding="utf-8"), keep_frames)
        try:
            self._file = self._partial.open("w", encoding="utf-8", newline="\n")
            self._file.write(kept)
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
