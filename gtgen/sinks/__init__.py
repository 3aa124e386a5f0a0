"""Dataset writers. Each takes :class:`gtgen.frame.FrameRecord` objects in frame order.

A sink writes into a ``*.partial`` path and moves it into place on ``close()``, so an
interrupted run never leaves a file that looks complete.
"""

from __future__ import annotations

from typing import Protocol

from gtgen.frame import FrameRecord


class Sink(Protocol):
    def write(self, record: FrameRecord) -> None: ...

    def close(self) -> None: ...

    def abort(self) -> None: ...
