"""A dataset sub-folder written under ``<name>.partial`` and moved into place when complete."""

from __future__ import annotations

import shutil
from pathlib import Path


class PartialFolder:
    def __init__(self, final: Path, subfolders: tuple[str, ...]) -> None:
        self.final = final
        self.partial = final.with_name(final.name + ".partial")
        if self.partial.exists():
            shutil.rmtree(self.partial)
        for sub in subfolders:
            (self.partial / sub).mkdir(parents=True, exist_ok=True)

    def commit(self) -> None:
        if self.final.exists():
            shutil.rmtree(self.final)
        self.partial.replace(self.final)

    def discard(self) -> None:
        shutil.rmtree(self.partial, ignore_errors=True)
