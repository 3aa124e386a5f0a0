"""Dataset writers. Each takes :class:`gtgen.frame.FrameRecord` objects in frame order.

A sink works in two steps per frame: ``encode`` (pure computation: images, messages,
text; the frame's :class:`~gtgen.sinks.images.FrameImages` is shared by all sinks) and
``write`` (file access only). It writes into a ``*.partial`` path and moves it into place
on ``close()``, so an interrupted run never leaves a file that looks complete. ``abort()``
removes what it wrote; ``keep()`` leaves every file where and as it is, under its partial name,
for a run that continues (the disk is full, the run was killed).
:class:`~gtgen.sinks.group.SinkGroup` drives a list of sinks in this process,
:class:`~gtgen.sinks.background.BackgroundSinks` the same in a writer process.
"""

from __future__ import annotations

from typing import Any, Protocol

from gtgen.frame import FrameRecord
from gtgen.sinks.images import FrameImages


class Sink(Protocol):
    def encode(self, record: FrameRecord, images: FrameImages) -> Any: ...

    def write(self, encoded: Any) -> None: ...

    def close(self) -> None: ...

    def abort(self) -> None: ...

    def keep(self) -> None: ...
