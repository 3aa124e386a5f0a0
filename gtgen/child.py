"""A function of this project in a new Python interpreter, talked to through two pipes.

Neither multiprocessing's "fork" (Open3D's and SUMO's threads must never be forked) nor its
"spawn" (which re-runs the user's main script in the child, and fails on a script without an
``if __name__ == "__main__":`` guard): a new interpreter with this process's ``sys.path`` runs
``module:function(inbox, outbox)``, in a session of its own so that Ctrl-C reaches only the
parent, which decides. Messages are pickled. A child that dies is reported with its exit
code and the last line it printed; a child whose parent dies sees its inbox close, and one
started to die with its parent (``dies_with_parent``: the traffic process, which holds nothing
worth keeping) is killed by the system then (Linux's parent-death signal), so no helper is
left running however the parent ends.
"""

from __future__ import annotations

import ctypes
import importlib
import json
import os
import signal
import subprocess
import sys
import tempfile
from multiprocessing.connection import Connection
from typing import Any

from gtgen.errors import GtgenError

ABORT_WAIT_S = 30.0
BOOT = "import json, sys; sys.path[:0] = json.loads(sys.argv[4]); import gtgen.child as c; c.child_main()"
PR_SET_PDEATHSIG = 1  # prctl(2)
M_TRIM_THRESHOLD, M_MMAP_THRESHOLD = -1, -3  # mallopt(3)
MMAP_THRESHOLD_BYTES = 32 << 20  # glibc's largest
TRIM_THRESHOLD_BYTES = 1 << 30


class ChildGoneError(GtgenError):
    """The child process has ended (or ended its side of the pipe)."""


class ChildProcess:
    """``target`` is ``"package.module:function"``; the function gets its inbox and outbox."""

    def __init__(self, target: str, dies_with_parent: bool = False) -> None:
        inbox_r, inbox_w = os.pipe()
        outbox_r, outbox_w = os.pipe()
        self._log = tempfile.TemporaryFile()  # noqa: SIM115 (closed in close())
        self._dies_with_parent = dies_with_parent
        parent = str(os.getpid()) if dies_with_parent else ""
        try:
            self._process = subprocess.Popen(
                [sys.executable, "-c", BOOT, target, str(inbox_r), str(outbox_w), json.dumps(sys.path), parent],
                pass_fds=(inbox_r, outbox_w), stdin=subprocess.DEVNULL, stdout=self._log, stderr=self._log,
                start_new_session=True,
            )  # fmt: skip
        finally:
            os.close(inbox_r)
            os.close(outbox_w)
        self._tx = Connection(inbox_w, readable=False)
        self._rx = Connection(outbox_r, writable=False)

    @property
    def pid(self) -> int:
        return self._process.pid

    def send(self, message: Any) -> None:
        try:
            self._tx.send(message)
        except OSError as err:
            raise ChildGoneError(self.last_words()) from err

    def poll(self, timeout_s: float = 0.0) -> bool:
        """Whether a message (or the end of the child's side) is waiting."""
        return self._rx.poll(timeout_s)

    def receive(self) -> Any:
        try:
            return self._rx.recv()
        except EOFError:
            raise ChildGoneError(self.last_words()) from None

    def alive(self) -> bool:
        return self._process.poll() is None

    def join(self, timeout_s: float = ABORT_WAIT_S) -> None:
        """Wait for the child to end; kill it if it has not within ``timeout_s`` (or, for a child
        that dies with its parent, if the wait is interrupted: a second Ctrl-C)."""
        try:
            self._process.wait(timeout_s)
        except subprocess.TimeoutExpired:
            self.kill()
        except BaseException:
            if self._dies_with_parent:
                self.kill()
            raise

    def kill(self) -> None:
        self._process.kill()
        self._process.wait()

    def last_words(self) -> str:
        """``exit code N: <the last line it printed>`` once it has ended (waits for that)."""
        self.join()
        if self._log.closed:
            return f"exit code {self._process.returncode}"
        self._log.seek(0)
        lines = [line.strip() for line in self._log.read().decode(errors="replace").splitlines() if line.strip()]
        return f"exit code {self._process.returncode}" + (f": {lines[-1]}" if lines else "")

    def close(self) -> None:
        """Close the pipes (a child still reading its inbox sees it end) and the output log."""
        self._tx.close()
        self._rx.close()
        self._log.close()


def child_main() -> None:
    """Run in the child by ``BOOT``: argv holds the target, the pipes' descriptors and, for a
    child that dies with its parent, the parent's process id."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    if sys.argv[5]:
        _die_with(int(sys.argv[5]))
    module, function = sys.argv[1].split(":")
    inbox = Connection(int(sys.argv[2]), writable=False)
    outbox = Connection(int(sys.argv[3]), readable=False)
    getattr(importlib.import_module(module), function)(inbox, outbox)


def _die_with(parent_pid: int) -> None:
    """Have the system kill this process when its parent ends (Linux); end now if it has."""
    if sys.platform.startswith("linux"):
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
    if os.getppid() != parent_pid:  # the parent ended before the signal was set up
        os._exit(1)


def keep_freed_memory() -> None:
    """Have the C allocator (glibc's) keep memory this process frees for its next allocations:
    blocks up to 32 MB come from its heap, whose free top is not handed back to the system below
    1 GB. A process that makes and drops arrays of several megabytes every frame (the writer's
    images) would otherwise map them afresh each time and fault every page in again: about 7,000
    page faults a frame, a tenth of its CPU time. Elsewhere than on Linux, or without glibc's
    ``mallopt``, nothing changes."""
    if not sys.platform.startswith("linux"):
        return
    mallopt = getattr(ctypes.CDLL(None), "mallopt", None)
    if mallopt is not None:
        mallopt(M_MMAP_THRESHOLD, MMAP_THRESHOLD_BYTES)
        mallopt(M_TRIM_THRESHOLD, TRIM_THRESHOLD_BYTES)
