"""Errors raised while labelling or writing a dataset."""

from __future__ import annotations

import errno

DISK_FULL = (errno.ENOSPC, errno.EDQUOT)


class GtgenError(Exception):
    """Labels could not be computed or a dataset could not be written."""


class SinkError(GtgenError):
    """An output writer failed (disk full, unwritable folder, ...)."""


class OutputKeptError(SinkError):
    """The writers stopped and left every frame written so far where it is, under the files'
    partial names (``disk_full``, or the writer process was killed): a run that continues
    (``--resume``) takes them back."""

    def __init__(self, message: str, disk_full: bool = False) -> None:
        super().__init__(message)
        self.disk_full = disk_full


def out_of_space(err: BaseException) -> bool:
    """Whether ``err``, or an error it was raised from, is a file system out of space."""
    seen: set[int] = set()
    cause: BaseException | None = err
    while cause is not None and id(cause) not in seen:
        if isinstance(cause, OSError) and cause.errno in DISK_FULL:
            return True
        seen.add(id(cause))
        cause = cause.__cause__ or cause.__context__
    return False


def disk_full_error(err: BaseException) -> OutputKeptError:
    """The one line for an output that ran out of space (the sink's own line when it has one)."""
    if isinstance(err, GtgenError):
        return OutputKeptError(str(err), disk_full=True)
    where = getattr(err, "filename", None) or "an output file"
    return OutputKeptError(f"{where}: cannot write: {getattr(err, 'strerror', None) or err}", disk_full=True)
