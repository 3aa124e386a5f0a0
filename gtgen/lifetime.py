"""One lifetime for the things a run opens (the sinks, the traffic feed): used in a ``with``
block, they are closed when it ends and aborted when it raises."""

from __future__ import annotations

from typing import Self


class ClosedOnExit:
    """A context manager over ``close()`` (finish: files move into place) and ``abort()``
    (stop: nothing is left that looks complete)."""

    def close(self) -> None:
        raise NotImplementedError

    def abort(self) -> None:
        raise NotImplementedError

    def __enter__(self) -> Self:
        return self

    def __exit__(self, kind: type[BaseException] | None, *_: object) -> None:
        if kind is None:
            self.close()
        else:
            self.abort()
