"""Content-addressed cache for converted networks and world meshes."""

from __future__ import annotations

import hashlib
import os
import shutil
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path


def cache_root() -> Path:
    """``$SUMO_DATASET_CACHE``, else ``$XDG_CACHE_HOME/sumo-dataset-factory``, else ``~/.cache/...``."""
    explicit = os.environ.get("SUMO_DATASET_CACHE")
    if explicit:
        return Path(explicit)
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "sumo-dataset-factory"


def digest(*parts: bytes | str) -> str:
    h = hashlib.sha256()
    for part in parts:
        data = part.encode() if isinstance(part, str) else part
        h.update(len(data).to_bytes(8, "little"))
        h.update(data)
    return h.hexdigest()[:20]


def cache_dir(kind: str, key: str) -> Path:
    path = cache_root() / kind / key
    path.mkdir(parents=True, exist_ok=True)
    return path


@contextmanager
def scratch_dir(folder: Path) -> Iterator[Path]:
    """A private folder inside a cache folder for one writer's partial files (several
    processes may fill the same cache entry at once); removed afterwards. Finished files
    are moved into ``folder`` with ``Path.replace``, which is atomic."""
    scratch = Path(tempfile.mkdtemp(prefix=".scratch-", dir=folder))
    try:
        yield scratch
    finally:
        shutil.rmtree(scratch, ignore_errors=True)
