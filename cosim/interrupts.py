"""Ctrl-C and SIGTERM around a run's files: held while a stopped run closes them, and put off
until a frame has been counted and handed to the writers (a frame is written whole or not at all)."""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Iterator
from typing import Any

from cosim.errors import Terminated

Handlers = dict[int, Any]


def interrupt_behind(err: BaseException) -> BaseException | None:
    """The Ctrl-C (``KeyboardInterrupt``) or SIGTERM (:class:`cosim.errors.Terminated`) that
    ``err`` is or stands for; None for any other error. A signal that arrives while compiled code
    (a Numba kernel, a ray caster) calls back into Python can reach the caller as a ``SystemError``
    ("returned a result with an exception set") caused by the interrupt: that is the interrupt."""
    seen: set[int] = set()
    at: BaseException | None = err
    while at is not None and id(at) not in seen:
        if isinstance(at, (KeyboardInterrupt, Terminated)):
            return at
        if not isinstance(at, SystemError):
            return None
        seen.add(id(at))
        at = at.__cause__ or at.__context__
    return None


def hold_interrupts() -> Handlers:
    """Ignore SIGINT and SIGTERM (in the main thread) while a stopped run closes its files."""
    if threading.current_thread() is not threading.main_thread():
        return {}
    return {sig: signal.signal(sig, signal.SIG_IGN) for sig in (signal.SIGINT, signal.SIGTERM)}


def release_interrupts(held: Handlers) -> None:
    for sig, handler in held.items():
        signal.signal(sig, handler)


@contextlib.contextmanager
def interrupts_after() -> Iterator[None]:
    """Run the block whole: a SIGINT or SIGTERM that arrives inside it takes effect (with the
    handler in place before) as the block ends. A frame is counted and handed to the writers
    together or not at all, so the manifest of a stopped run counts exactly the frames written."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    caught: list[int] = []
    held: Handlers = {
        int(sig): signal.signal(sig, lambda s, _frame: caught.append(s)) for sig in (signal.SIGINT, signal.SIGTERM)
    }
    try:
        yield
    finally:
        release_interrupts(held)
    if caught:
        signal.raise_signal(caught[0])
