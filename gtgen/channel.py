"""The messages between the frame loop and its helper processes, and how they travel.

Two helpers run beside the loop, each a new interpreter (:mod:`gtgen.child`): the traffic
process (:mod:`cosim.traffic_feed`: SUMO, one frame ahead) and the writer process
(:mod:`gtgen.sinks.background`: the sinks). Both talk in the typed messages below, pickled
through two pipes. The parent holds a :class:`Link`; the child runs :func:`serve`, which turns
any error into one :class:`Failed` line. The parent raises that line as its own error type.

Parent to child: :class:`Start` (the job), then :class:`Go` (traffic: step one frame) or
:class:`Slots`, :class:`Frame`, :class:`Inband` (writer: shared memory and frames), and
:class:`Close` (finish, report stage times) or :class:`Abort` (stop, keep nothing).
Child to parent: :class:`Ready`, :class:`Result`, :class:`Free`,
:class:`Closed`, :class:`Failed`.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable
from dataclasses import dataclass, field
from multiprocessing.connection import Connection
from typing import Generic, TypeVar

from gtgen.child import ChildGoneError, ChildProcess
from gtgen.crash import internal_error_line
from gtgen.errors import OutputKeptError
from gtgen.timing import StageTimes
from networks.errors import clipped

T = TypeVar("T")
M = TypeVar("M")


# --- parent to child ----------------------------------------------------------------------------
@dataclass(frozen=True, slots=True)
class Start(Generic[T]):
    """The child's job, and whether to time its stages."""

    job: T
    timed: bool = False


@dataclass(frozen=True, slots=True)
class Go:
    """Step one frame and send its :class:`Result`."""


@dataclass(frozen=True, slots=True)
class Slots:
    """Names of the shared-memory segments frames arrive in, one per slot."""

    names: tuple[str, ...]


@dataclass(frozen=True, slots=True)
class Frame:
    """A frame pickled with its arrays out of band: ``meta`` here, the arrays in slot
    ``slot`` at ``layout`` (offset, size) each."""

    slot: int
    meta: bytes
    layout: tuple[tuple[int, int], ...]


@dataclass(frozen=True, slots=True)
class Inband:
    """A frame too large for its slot, pickled whole (the slot is handed back all the same)."""

    slot: int
    data: bytes


@dataclass(frozen=True, slots=True)
class Close:
    """Finish the job (files move into place) and send :class:`Closed`."""


@dataclass(frozen=True, slots=True)
class Abort:
    """Stop now and keep nothing."""


# --- child to parent ----------------------------------------------------------------------------
@dataclass(frozen=True, slots=True)
class Ready:
    """The job has started; lines for the user."""

    notices: tuple[str, ...] = ()


@dataclass(frozen=True, slots=True)
class Result(Generic[T]):
    """What one :class:`Go` made."""

    value: T


@dataclass(frozen=True, slots=True)
class Free:
    """Slot ``slot`` may take the next frame."""

    slot: int


@dataclass(frozen=True, slots=True)
class Closed:
    """The job finished; the child's stage times."""

    times: StageTimes = field(default_factory=StageTimes)


@dataclass(frozen=True, slots=True)
class Failed:
    """The job failed: one line saying why; ``kept``: the child left its outputs as they were
    (:class:`~gtgen.errors.OutputKeptError`), ``disk_full`` because the disk was."""

    line: str
    kept: bool = False
    disk_full: bool = False


class ParentGoneError(EOFError):
    """The child's parent has gone (its pipe closed while the child read or answered)."""


def error_line(err: BaseException, own: tuple[type[BaseException], ...], process: str) -> str:
    """One line naming a failure: the message of the project's own errors (``own``: written
    for users); a file the system refused, with the system's reason; else an internal error
    of the process, with its details in a crash report."""
    text = clipped(" ".join(str(err).split()))
    if isinstance(err, own) and text:
        return text
    if isinstance(err, OSError) and err.filename is not None and err.strerror:
        return f"{process}: {err.filename}: {err.strerror}"
    return internal_error_line(err, f"the {process}")


def serve(outbox: Connection, work: Callable[[], None], own: tuple[type[BaseException], ...], process: str) -> None:
    """Run a child's ``work``; any error it raises goes to the parent as one :class:`Failed`
    line (unless the parent has gone: nobody is left to tell)."""
    try:
        work()
    except (EOFError, BrokenPipeError):
        return
    except BaseException as err:
        kept = isinstance(err, OutputKeptError)
        with contextlib.suppress(OSError):
            outbox.send(Failed(error_line(err, own, process), kept, kept and getattr(err, "disk_full", False)))


def receive_from_parent(inbox: Connection) -> object:
    """The parent's next message (raises :class:`ParentGoneError` if it has gone)."""
    try:
        message: object = inbox.recv()
    except (EOFError, OSError) as err:
        raise ParentGoneError(str(err)) from err
    return message


def tell_parent(outbox: Connection, message: object) -> None:
    """Send ``message`` to the parent (raises :class:`ParentGoneError` if it has gone)."""
    try:
        outbox.send(message)
    except OSError as err:
        raise ParentGoneError(str(err)) from err


class Link:
    """The parent's end of a helper process running ``target`` (``module:function``): typed
    messages both ways. A :class:`Failed` line from the child is raised as ``error(line)``; a
    child that ended unexpectedly as ``lost("<process> stopped unexpectedly (...)", False)``,
    and the line of a child that kept its outputs as ``lost(line, disk_full)`` (``lost``
    defaults to ``error``). A child that ``dies_with_parent`` is killed when this process
    ends, however it ends."""

    def __init__(
        self, target: str, process: str, error: Callable[[str], Exception],
        lost: Callable[[str, bool], Exception] | None = None, dies_with_parent: bool = False,
    ) -> None:  # fmt: skip
        self._child = ChildProcess(target, dies_with_parent)
        self._process, self._error = process, error
        self._lost = lost or (lambda line, _disk_full: error(line))

    @property
    def pid(self) -> int:
        return self._child.pid

    def send(self, message: object) -> None:
        try:
            self._child.send(message)
        except ChildGoneError as gone:
            while self._child.poll():  # the child's own error, if it said one
                self.receive()
            raise self._stopped(gone) from None

    def poll(self, timeout_s: float = 0.0) -> bool:
        return self._child.poll(timeout_s)

    def receive(self) -> object:
        """The child's next message; raises its :class:`Failed` line, or that it is gone."""
        try:
            message: object = self._child.receive()
        except ChildGoneError as gone:
            raise self._stopped(gone) from None
        if isinstance(message, Failed):
            raise self._lost(message.line, message.disk_full) if message.kept else self._error(message.line)
        return message

    def expect(self, kind: type[M]) -> M:
        """The child's next message, which must be a ``kind``."""
        message = self.receive()
        if not isinstance(message, kind):
            raise self._error(f"{self._process}: expected {kind.__name__}, got {type(message).__name__}")
        return message

    def alive(self) -> bool:
        return self._child.alive()

    def gone(self) -> Exception:
        """The error of a child that ended without saying why (waits for it to end)."""
        return self._stopped(ChildGoneError(self._child.last_words()))

    def stop(self, message: object, timeout_s: float) -> None:
        """Send ``message`` (:class:`Abort` or :class:`Close`) if the child still listens, wait
        for it to end (kill it after ``timeout_s``) and close the pipes."""
        with contextlib.suppress(ChildGoneError):
            self._child.send(message)
        self.join(timeout_s)
        self.close()

    def join(self, timeout_s: float) -> None:
        self._child.join(timeout_s)

    def kill(self) -> None:
        """End the child now (one that holds nothing worth finishing) and close the pipes."""
        self._child.kill()
        self.close()

    def close(self) -> None:
        self._child.close()

    def _stopped(self, gone: ChildGoneError) -> Exception:
        return self._lost(f"{self._process} stopped unexpectedly ({gone})", False)
