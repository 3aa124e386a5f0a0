"""An OpenDRIVE file parsed once a process: the markings, the signs, the motorway and sidewalk
rules of the conversion (and through them the world mesh and the HD map) read the same tree.

The tree is kept by the file's path (as given), size and modification time (a file written again is
parsed again) and is to be read, never changed. A file that cannot be read or parsed raises
the same error on every call, as :func:`xml.etree.ElementTree.parse` would.
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path
from xml.etree import ElementTree


def opendrive_root(xodr_path: Path) -> ElementTree.Element:
    """The root (``OpenDRIVE``) element of ``xodr_path``; ``OSError`` or
    ``ElementTree.ParseError`` if it cannot be read."""
    path = Path(xodr_path)
    stat = path.stat()
    parsed = _parsed(path, stat.st_size, stat.st_mtime_ns)
    if isinstance(parsed, BaseException):
        raise parsed
    return parsed


@lru_cache(maxsize=8)
def _parsed(path: Path, size: int, mtime_ns: int) -> ElementTree.Element | ElementTree.ParseError | OSError:
    try:
        return ElementTree.parse(path).getroot()
    except (ElementTree.ParseError, OSError) as err:
        return err
