"""One lifetime for the things a run opens (the sinks, the traffic feed): used in a ``with``
block, they are closed when it ends, aborted when it raises, and left as they are when it
raises :class:`~gtgen.errors.OutputKeptError` (the outputs keep their frames)."""

from __future__ import annotations

from typing import Self

from gtgen.errors import OutputKeptError


class ClosedOnExit:
    """A context manager over ``close()`` (finish: files move into place), ``abort()`` (stop:
    nothing is left that looks complete) and ``keep()`` (stop: what was written stays where it
    is, for a run that continues; by default the same as ``abort()``)."""

    def close(self) -> None:
        raise NotImplementedError

    def abort(self) -> None:
        raise NotImplementedError

    def keep(self) -> None:
        self.abort()

    def __enter__(self) -> Self:
        return self

    def __exit__(self, kind: type[BaseException] | None, error: BaseException | None, *_: object) -> None:
        if kind is None:
            self.close()
        elif isinstance(error, OutputKeptError):
            self.keep()
        else:
            self.abort()
