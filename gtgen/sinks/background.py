"""The sinks in a writer process, so that encoding and writing overlap the next frames.

The parent hands each :class:`~gtgen.frame.FrameRecord` over through shared memory: the
record is pickled (protocol 5) with its arrays out of band, the arrays are copied into one
of ``depth`` shared-memory slots and the small rest goes through a pipe. At most ``depth``
frames are in flight: the parent waits for a free slot (the bounded queue), and the child
hands a slot back once its frame is written. The child runs a
:class:`~gtgen.sinks.group.SinkGroup`. Any error there aborts the child's sinks (their
``*.partial`` files go, no complete-looking file is left) and reaches the parent as one
line, raised as :class:`~gtgen.errors.SinkError` from the parent's next ``write`` or
``close``. The child is a new interpreter (:mod:`gtgen.child`: never a fork of a process
running Open3D's threads) in its own session, so Ctrl-C reaches only the parent, which then
aborts it. If the parent dies, the child sees its pipe close and discards its partial files.
"""

from __future__ import annotations

import contextlib
import pickle
import shutil
import sys
from collections.abc import Callable
from multiprocessing import resource_tracker
from multiprocessing.connection import Connection
from multiprocessing.shared_memory import SharedMemory
from typing import Any

from gtgen.child import ChildGoneError, ChildProcess
from gtgen.errors import SinkError
from gtgen.frame import FrameRecord
from gtgen.sinks.group import SinkChoice, SinkGroup
from gtgen.timing import NO_CLOCK, StageClock, StageTimes, is_timing

ALIGN = 64
SLOT_HEADROOM = 1.5  # slots are sized from the first frame; a larger frame goes through the pipe
POLL_S = 0.5


def error_line(err: BaseException) -> str:
    """One line naming the failure: the message of the project's errors, else type and message."""
    text = " ".join(str(err).split())
    if isinstance(err, SinkError) and text:
        return text
    return f"{type(err).__name__}: {text}" if text else type(err).__name__


class BackgroundSinks:
    """The sinks of ``choice`` in a writer process fed through a bounded queue of ``depth`` frames.
    With a ``clock``, the child's stage times are added to it on ``close`` ("writer ...")."""

    def __init__(self, choice: SinkChoice, depth: int = 2, clock: StageClock = NO_CLOCK) -> None:
        if depth < 1:
            raise ValueError(f"BackgroundSinks: depth must be >= 1, got {depth}")
        self._child = ChildProcess("gtgen.sinks.background:serve")
        self._choice = choice
        self._depth = depth
        self._clock = clock
        self._slots: list[SharedMemory] = []
        self._free: list[int] = []
        self._child_times: StageTimes | None = None
        self._send(("open", choice, is_timing(clock)))

    @property
    def pid(self) -> int:
        return self._child.pid

    def write(self, record: FrameRecord) -> None:
        with self._clock.stage("handoff"):
            buffers: list[pickle.PickleBuffer] = []
            meta = pickle.dumps(record, protocol=5, buffer_callback=buffers.append)
            views = [b.raw() for b in buffers]
            if not self._slots:
                self._allocate(sum(v.nbytes for v in views))
            self._drain()
            self._wait(lambda: bool(self._free))
            slot = self._free.pop()
            layout = _copy_into(self._slots[slot], views)
            if layout is None:
                self._send(("inband", slot, pickle.dumps(record, protocol=5)))
            else:
                self._send(("frame", slot, meta, layout))

    def close(self) -> None:
        """Write out what is queued, close the sinks (files move into place) and stop the child."""
        with self._clock.stage("close"):
            self._send(("close",))
            self._wait(lambda: self._child_times is not None)
            self._child.join()
            self._release()
        if self._child_times is not None:
            for name, seconds in self._child_times.seconds.items():
                self._clock.add(f"writer {name}", seconds, self._child_times.calls[name])

    def abort(self) -> None:
        """Stop the child, which discards its partial files; kill it if it does not stop, and
        remove what a killed child left."""
        if self._child.alive():
            with contextlib.suppress(ChildGoneError):
                self._child.send(("abort",))
            self._child.join()
        self._release()
        for path in self._choice.partial_paths():
            if path.is_dir():
                shutil.rmtree(path, ignore_errors=True)
            else:
                path.unlink(missing_ok=True)

    # --- parent side ------------------------------------------------------------------------
    def _allocate(self, frame_bytes: int) -> None:
        size = max(int(frame_bytes * SLOT_HEADROOM) + ALIGN * 64, 1 << 20)
        self._slots = [SharedMemory(create=True, size=size) for _ in range(self._depth)]
        self._free = list(range(self._depth))
        self._send(("slots", [s.name for s in self._slots]))

    def _send(self, message: tuple[Any, ...]) -> None:
        try:
            self._child.send(message)
        except ChildGoneError as gone:
            self._drain()  # the child's own error, if it said one
            raise _stopped(gone) from None

    def _wait(self, done: Callable[[], bool]) -> None:
        """Handle the child's messages until ``done()``; raise if it reports an error or dies."""
        while not done():
            if self._child.poll(POLL_S):
                self._handle(self._receive())
            elif not self._child.alive() and not self._child.poll():
                raise _stopped(ChildGoneError(self._child.last_words()))

    def _drain(self) -> None:
        """Handle what the child has said so far (an error is raised now, not frames later)."""
        while self._child.poll():
            self._handle(self._receive())

    def _receive(self) -> tuple[Any, ...]:
        try:
            message: tuple[Any, ...] = self._child.receive()
        except ChildGoneError as gone:
            raise _stopped(gone) from None
        return message

    def _handle(self, message: tuple[Any, ...]) -> None:
        kind = message[0]
        if kind == "free":
            self._free.append(message[1])
        elif kind == "notice":
            print(message[1], file=sys.stderr)
        elif kind == "closed":
            self._child_times = message[1]
        elif kind == "error":
            raise SinkError(f"writer process: {message[1]}")

    def _release(self) -> None:
        self._child.close()
        for shm in self._slots:
            shm.close()
            shm.unlink()
        self._slots = []


def _stopped(gone: ChildGoneError) -> SinkError:
    return SinkError(f"writer process stopped unexpectedly ({gone}); no dataset was completed")


def _copy_into(shm: SharedMemory, views: list[memoryview]) -> tuple[tuple[int, int], ...] | None:
    """Copy the buffers into ``shm`` at aligned offsets; None when they do not fit."""
    layout, offset = [], 0
    buf = shm.buf
    if buf is None:
        return None
    for view in views:
        n = view.nbytes
        if offset + n > shm.size:
            return None
        buf[offset : offset + n] = view
        layout.append((offset, n))
        offset = -(-(offset + n) // ALIGN) * ALIGN
    return tuple(layout)


# --- child side ---------------------------------------------------------------------------
def serve(frames_rx: Connection, acks_tx: Connection) -> None:  # runs in the writer process
    """Open the sinks, write frames until told to close or abort; any error (the parent's
    pipe closing too) aborts the sinks and is reported as one line."""
    times = StageTimes()
    slots: list[SharedMemory] = []
    group: SinkGroup | None = None
    try:
        _, choice, timed = frames_rx.recv()
        group = SinkGroup.open(choice, times if timed else NO_CLOCK, announce=False)
        for line in group.notices:
            acks_tx.send(("notice", line))
        while True:
            message = frames_rx.recv()
            kind = message[0]
            if kind == "slots":
                slots = [_attach(name) for name in message[1]]
            elif kind == "close":
                group.close()
                acks_tx.send(("closed", times))
                return
            elif kind == "abort":
                group.abort()
                return
            else:
                group.write(_unpack(message, slots))
                acks_tx.send(("free", message[1]))
    except BaseException as err:
        if group is not None:
            group.abort()
        with contextlib.suppress(OSError):
            acks_tx.send(("error", error_line(err)))
    finally:
        _detach(slots)


def _attach(name: str) -> SharedMemory:
    """Map the parent's segment. The parent owns and unlinks it: this process must not
    register it with a resource tracker of its own, which would unlink it at exit."""
    register = resource_tracker.register
    resource_tracker.register = lambda *args, **kwargs: None  # type: ignore[assignment]
    try:
        return SharedMemory(name=name)
    finally:
        resource_tracker.register = register  # type: ignore[assignment]


def _unpack(message: tuple[Any, ...], slots: list[SharedMemory]) -> FrameRecord:
    if message[0] == "inband":
        record: FrameRecord = pickle.loads(message[2])
        return record
    _, slot, meta, layout = message
    buf = slots[slot].buf
    if buf is None:
        raise SinkError("writer process: a shared-memory slot was closed")
    record = pickle.loads(meta, buffers=[buf[o : o + n] for o, n in layout])
    return record


def _detach(slots: list[SharedMemory]) -> None:
    for shm in slots:
        # a frame's arrays may still be referenced (an error while writing); the OS unmaps at exit
        with contextlib.suppress(BufferError):
            shm.close()
