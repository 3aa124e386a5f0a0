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
aborts it.

Three faults keep every frame written so far, under the files' partial names, for a run that
continues (``--resume``): the disk running out of space (the child keeps its sinks' files and
says so: :class:`~gtgen.errors.OutputKeptError`), the child killed (the parent raises the same
and removes nothing), and the parent killed (the child sees its pipe close, while it waits for a
frame or while it answers, and keeps its sinks' files, MCAP index written). While the child
runs it holds ``.resume/writer.lock`` in the output folder: a run that continues waits for the
writer of a killed run to finish keeping its files.
The messages are those of :mod:`gtgen.channel`.
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

from gtgen.channel import (
    Abort,
    Close,
    Closed,
    Frame,
    Free,
    Inband,
    Link,
    ParentGoneError,
    Ready,
    Slots,
    Start,
    receive_from_parent,
    tell_parent,
)
from gtgen.channel import serve as serve_child
from gtgen.child import ABORT_WAIT_S, keep_freed_memory
from gtgen.errors import OutputKeptError, SinkError
from gtgen.frame import FrameRecord
from gtgen.lifetime import ClosedOnExit
from gtgen.sinks.group import SinkChoice, SinkGroup
from gtgen.sinks.images import shaded
from gtgen.sinks.resume_sink import hold_folder
from gtgen.timing import NO_CLOCK, StageClock, StageTimes, is_timing

ALIGN = 64
SLOT_HEADROOM = 1.5  # slots are sized from the first frame; a larger frame goes through the pipe
POLL_S = 0.5
PROCESS = "writer process"


class BackgroundSinks(ClosedOnExit):
    """The sinks of ``choice`` in a writer process fed through a bounded queue of ``depth`` frames.
    With a ``clock``, the child's stage times are added to it on ``close`` ("writer ...").
    As a context manager: closed when the ``with`` block ends, aborted when it raises."""

    def __init__(self, choice: SinkChoice, depth: int = 2, clock: StageClock = NO_CLOCK) -> None:
        if depth < 1:
            raise ValueError(f"BackgroundSinks: depth must be >= 1, got {depth}")
        self._link = Link("gtgen.sinks.background:serve", PROCESS, SinkError, lost=OutputKeptError)
        self._choice = choice
        self._depth = depth
        self._clock = clock
        self._slots: list[SharedMemory] = []
        self._free: list[int] = []
        self._child_times: StageTimes | None = None
        self._ready = False
        self._send(Start(choice, is_timing(clock)))

    def ready(self) -> None:
        """Wait until every sink has opened in the writer process (raises if one could not)."""
        self._wait(lambda: self._ready)

    @property
    def pid(self) -> int:
        return self._link.pid

    def write(self, record: FrameRecord) -> None:
        """Hand ``record`` to the writer process. While every slot is taken (the writer is behind)
        its camera images are shaded here instead of waiting idle: the writer gets them made."""
        self._drain()
        if self._slots and not self._free:
            with self._clock.stage("shading ahead"):
                record = shaded(record)
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
                self._send(Inband(slot, pickle.dumps(record, protocol=5)))
            else:
                self._send(Frame(slot, meta, layout))

    def close(self) -> None:
        """Write out what is queued, close the sinks (files move into place) and stop the child."""
        with self._clock.stage("close"):
            self._send(Close())
            self._wait(lambda: self._child_times is not None)
            self._link.join(ABORT_WAIT_S)
            self._release()
        if self._child_times is not None:
            for name, seconds in self._child_times.seconds.items():
                self._clock.add(f"writer {name}", seconds, self._child_times.calls[name])

    def abort(self) -> None:
        """Stop the child, which discards its partial files (one still starting a new run is
        killed: it has written nothing yet); kill it if it does not stop, and remove what a
        killed child left."""
        if self._link.alive() and not self._ready and self._choice.keep_frames == 0:
            self._link.kill()
        elif self._link.alive():
            self._link.stop(Abort(), ABORT_WAIT_S)
        self._release()
        for path in self._choice.partial_paths():
            if path.is_dir():
                shutil.rmtree(path, ignore_errors=True)
            else:
                path.unlink(missing_ok=True)

    def keep(self) -> None:
        """The child kept its files (or was killed): wait for it to end, remove nothing."""
        self._link.join(ABORT_WAIT_S)
        self._release()

    # --- parent side ------------------------------------------------------------------------
    def _allocate(self, frame_bytes: int) -> None:
        size = max(int(frame_bytes * SLOT_HEADROOM) + ALIGN * 64, 1 << 20)
        self._slots = [SharedMemory(create=True, size=size) for _ in range(self._depth)]
        self._free = list(range(self._depth))
        self._send(Slots(tuple(s.name for s in self._slots)))

    def _send(self, message: object) -> None:
        self._link.send(message)

    def _wait(self, done: Callable[[], bool]) -> None:
        """Handle the child's messages until ``done()``; raise if it reports an error or dies."""
        while not done():
            if self._link.poll(POLL_S):
                self._handle(self._link.receive())
            elif not self._link.alive() and not self._link.poll():
                raise self._link.gone()

    def _drain(self) -> None:
        """Handle what the child has said so far (an error is raised now, not frames later)."""
        while self._link.poll():
            self._handle(self._link.receive())

    def _handle(self, message: object) -> None:
        if isinstance(message, Free):
            self._free.append(message.slot)
        elif isinstance(message, Ready):
            self._ready = True
            for line in message.notices:
                print(line, file=sys.stderr)
        elif isinstance(message, Closed):
            self._child_times = message.times

    def _release(self) -> None:
        self._link.close()
        for shm in self._slots:
            shm.close()
            shm.unlink()
        self._slots = []


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
    """Open the sinks, write frames until :class:`Close` or :class:`Abort`. The parent gone
    (its pipe closed) or the disk full: the sinks keep their files; any other error aborts
    them. Errors are reported as one line."""
    keep_freed_memory()  # a frame's images and their encodings are made and dropped every frame
    slots: list[SharedMemory] = []

    def work(group: SinkGroup, times: StageTimes) -> None:
        nonlocal slots
        tell_parent(acks_tx, Ready(tuple(group.notices)))
        while True:
            message = receive_from_parent(frames_rx)
            if isinstance(message, Slots):
                slots = [_attach(name) for name in message.names]
            elif isinstance(message, Close):
                group.close()
                tell_parent(acks_tx, Closed(times))
                return
            elif isinstance(message, Abort):
                group.abort()
                return
            elif isinstance(message, Frame | Inband):
                group.write(_unpack(message, slots))
                tell_parent(acks_tx, Free(message.slot))

    def open_and_work() -> None:
        start = receive_from_parent(frames_rx)
        if not isinstance(start, Start) or not isinstance(start.job, SinkChoice):
            raise SinkError(f"{PROCESS}: expected the sinks to open, got {type(start).__name__}")
        choice: SinkChoice = start.job
        if choice.resume:
            hold_folder(choice.out_dir)  # until this process ends
        times = StageTimes()
        group = SinkGroup.open(choice, times if start.timed else NO_CLOCK, announce=False)
        try:
            work(group, times)
        except (ParentGoneError, OutputKeptError):  # killed parent, full disk: every frame written stays
            group.keep()
            raise
        except BaseException:
            group.abort()
            raise

    try:
        serve_child(acks_tx, open_and_work, (SinkError,), PROCESS)
    finally:
        _detach(slots)


def _attach(name: str) -> SharedMemory:
    """Map the parent's segment. The parent owns and unlinks it: this process must not
    register it with a resource tracker of its own, which would unlink it at exit."""
    register = resource_tracker.register
    resource_tracker.register = lambda *args, **kwargs: None
    try:
        return SharedMemory(name=name)
    finally:
        resource_tracker.register = register


def _unpack(message: Frame | Inband, slots: list[SharedMemory]) -> FrameRecord:
    if isinstance(message, Inband):
        record: FrameRecord = pickle.loads(message.data)
        return record
    buf = slots[message.slot].buf
    if buf is None:
        raise SinkError("writer process: a shared-memory slot was closed")
    record = pickle.loads(message.meta, buffers=[buf[o : o + n] for o, n in message.layout])
    return record


def _detach(slots: list[SharedMemory]) -> None:
    for shm in slots:
        # a frame's arrays may still be referenced (an error while writing); the OS unmaps at exit
        with contextlib.suppress(BufferError):
            shm.close()
