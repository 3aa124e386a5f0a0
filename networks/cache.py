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
    processes may fill the same cache entry at once); removed afterwards, or by the next
    writer if its process was killed. Finished files are moved into ``folder`` with
    ``Path.replace``, which is atomic."""
    remove_stale_scratch(folder)
    scratch = Path(tempfile.mkdtemp(prefix=f".scratch-{os.getpid()}-", dir=folder))
    try:
        yield scratch
    finally:
        shutil.rmtree(scratch, ignore_errors=True)


# --- entries that are checked before use ------------------------------------------------------
# A cached file gets a seal beside it (``<name>.sha256``: its size and SHA-256) once complete.
# A file whose seal is missing or does not match (a truncated write, a damaged disk) is made
# again, with a notice the run shows.
_notices: list[str] = []


def _seal_path(path: Path) -> Path:
    return path.with_name(path.name + ".sha256")


def file_sha256(path: Path) -> str:
    h = hashlib.sha256()
    with path.open("rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def seal(path: Path) -> None:
    """Mark a complete cached file as good (after it is in place)."""
    _write_seal(path, path)


def place(partial: Path, path: Path) -> None:
    """Move a finished file into the cache, its seal first: a process that looks at the entry
    meanwhile finds either the old file or none with the new seal (and makes it again), never the
    new file without a seal (which it would take for a damaged one)."""
    _write_seal(partial, path)
    partial.replace(path)


def _write_seal(content: Path, path: Path) -> None:
    """``path``'s seal, from the size and SHA-256 of ``content``."""
    tmp = _seal_path(path).with_suffix(f".{os.getpid()}.partial")
    tmp.write_text(f"{content.stat().st_size} {file_sha256(content)}\n")
    tmp.replace(_seal_path(path))


def intact(path: Path) -> bool:
    """Whether a cached file is there and matches its seal; a damaged one is removed, with a notice."""
    if not path.exists():
        return False
    try:
        size, sha = _seal_path(path).read_text().split()
        good = path.stat().st_size == int(size) and file_sha256(path) == sha
    except (OSError, ValueError):
        good = False
    if not good:  # made again and put in place atomically; not removed, another process may read it
        _notices.append(f"note: {path}: the cached file was damaged or incomplete; it is made again")
    return good


def take_notices() -> list[str]:
    """The notices of cache entries made again since the last call."""
    out = list(_notices)
    _notices.clear()
    return out


def remove_stale_scratch(folder: Path) -> None:
    """Remove scratch folders whose writer process is gone (killed while it wrote)."""
    for scratch in folder.glob(".scratch-*"):
        pid = scratch.name.split("-")[1]
        if pid.isdigit() and not _alive(int(pid)):
            shutil.rmtree(scratch, ignore_errors=True)


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True
