"""Failures the software did not foresee: the user gets one line that says where the details
are, the details (the traceback) go to a crash report in the cache folder."""

from __future__ import annotations

import os
import time
import traceback
from pathlib import Path

from networks.cache import cache_root


def crash_report(err: BaseException) -> Path | None:
    """Write ``err``'s traceback to ``<cache>/crash-reports/``; the file, or None if it cannot be written."""
    folder = cache_root() / "crash-reports"
    path = folder / f"{time.strftime('%Y%m%d-%H%M%S')}-{os.getpid()}.txt"
    try:
        folder.mkdir(parents=True, exist_ok=True)
        path.write_text("".join(traceback.format_exception(err)))
    except OSError:
        return None
    return path


def internal_error_line(err: BaseException, where: str) -> str:
    """One line for an unforeseen failure in ``where``: no exception class, no library wording."""
    path = crash_report(err)
    details = f"the details are in {path}" if path is not None else "no crash report could be written"
    return f"internal error in {where}: {details}; please report it with the scenario file"
