"""Optional wall-clock timing of named stages (the benchmark's hook; free when off).

Code that can be timed takes a :class:`StageClock` and wraps each stage in
``with clock.stage("name"):``. The default :data:`NO_CLOCK` hands back one shared
``nullcontext``, so an untimed run pays a method call per stage and nothing else.
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from contextlib import AbstractContextManager, contextmanager, nullcontext
from dataclasses import dataclass, field
from typing import Protocol


class StageClock(Protocol):
    def stage(self, name: str) -> AbstractContextManager[object]:
        """Time the ``with`` block as (one more call of) stage ``name``."""
        ...

    def add(self, name: str, seconds: float, calls: int = 1) -> None:
        """Count time measured elsewhere (another process) as stage ``name``."""
        ...


class NoClock:
    """Times nothing."""

    _NULL = nullcontext()

    def stage(self, name: str) -> AbstractContextManager[object]:
        return self._NULL

    def add(self, name: str, seconds: float, calls: int = 1) -> None:
        pass


NO_CLOCK: StageClock = NoClock()


def is_timing(clock: StageClock) -> bool:
    return not isinstance(clock, NoClock)


@dataclass(slots=True)
class StageTimes:
    """Seconds spent and times entered per stage, in the order the stages first ran."""

    seconds: dict[str, float] = field(default_factory=dict)
    calls: dict[str, int] = field(default_factory=dict)

    @contextmanager
    def stage(self, name: str) -> Iterator[None]:
        start = time.perf_counter()
        try:
            yield
        finally:
            self.add(name, time.perf_counter() - start)

    def add(self, name: str, seconds: float, calls: int = 1) -> None:
        self.seconds[name] = self.seconds.get(name, 0.0) + seconds
        self.calls[name] = self.calls.get(name, 0) + calls

    def merge(self, other: StageTimes, prefix: str = "") -> None:
        for name, seconds in other.seconds.items():
            self.add(prefix + name, seconds, other.calls[name])
