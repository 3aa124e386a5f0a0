"""A dataset sub-folder written under ``<name>.partial`` and moved into place when complete."""

from __future__ import annotations

import shutil
from pathlib import Path

from gtgen.errors import SinkError


class PartialFolder:
    def __init__(self, final: Path, subfolders: tuple[str, ...]) -> None:
        self.final = final
        self.partial = final.with_name(final.name + ".partial")
        if self.partial.exists():
            shutil.rmtree(self.partial)
        for sub in subfolders:
            (self.partial / sub).mkdir(parents=True, exist_ok=True)

    def write_files(self, files: dict[str, bytes]) -> None:
        """Write ``files`` (contents by path relative to the folder) under the partial folder."""
        for relative, data in files.items():
            path = self.partial / relative
            try:
                path.write_bytes(data)
            except OSError as err:
                raise SinkError(f"{path}: cannot write: {err.strerror}") from err

    def commit(self) -> None:
        if self.final.exists():
            shutil.rmtree(self.final)
        self.partial.replace(self.final)

    def discard(self) -> None:
        shutil.rmtree(self.partial, ignore_errors=True)
