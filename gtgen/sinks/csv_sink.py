"""``labels.csv``: one row per labelled object and frame (columns in :mod:`gtgen.table`)."""

from __future__ import annotations

from pathlib import Path

from gtgen.frame import FrameRecord
from gtgen.sinks.images import FrameImages
from gtgen.table import COLUMNS, format_rows, label_table, table_columns


class CsvSink:
    def __init__(self, path: Path) -> None:
        self._path = path
        self._partial = path.with_name(path.name + ".partial")
        self._file = self._partial.open("w", encoding="utf-8", newline="\n")
        self._header_written = False

    def encode(self, record: FrameRecord, images: FrameImages) -> str:
        rows = format_rows(label_table(record.labels))
        text = "".join(row + "\n" for row in rows)
        if not self._header_written:  # the columns depend on the rig's cameras
            self._header_written = True
            text = ",".join(table_columns(record.labels)) + "\n" + text
        return text

    def write(self, encoded: str) -> None:
        self._file.write(encoded)

    def close(self) -> None:
        if not self._header_written:
            self._file.write(",".join(COLUMNS) + "\n")
        self._file.close()
        self._partial.replace(self._path)

    def abort(self) -> None:
        self._file.close()
        self._partial.unlink(missing_ok=True)
