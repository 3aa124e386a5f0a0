"""The frame loop's source of world states: SUMO in a process of its own, one frame ahead.

:class:`TrafficProcess` starts a new interpreter (:mod:`gtgen.child`) that runs
:class:`~cosim.traffic.Traffic` (libsumo runs one simulation per process): it warms the
traffic up, then steps it and reads the frame's world state while the loop senses the
previous frame, so SUMO's work leaves the loop's process and only small world states
cross the pipe. It makes the same libsumo calls in the same order as stepping in line
would, so the traffic is the same. An error there comes back as one line
(:class:`~cosim.errors.TrafficError`). :class:`TrafficInline` does the same in this process.
"""

from __future__ import annotations

import contextlib
from multiprocessing.connection import Connection
from pathlib import Path
from typing import Any, Protocol

from cosim.errors import CosimError, TrafficError
from cosim.scenario import Scenario
from cosim.state import WorldState
from gtgen.child import ChildGoneError, ChildProcess
from gtgen.timing import NO_CLOCK, StageClock, StageTimes, is_timing
from networks.errors import NetworkError

STOP_WAIT_S = 30.0


class TrafficFeed(Protocol):
    def warm_up(self) -> list[str]:
        """Fill the town and pick the ego; returns notices for the user."""
        ...

    def next(self) -> WorldState:
        """Step one frame; the agents within the radius of the ego."""
        ...

    def close(self) -> None: ...

    def abort(self) -> None: ...


class TrafficInline:
    """SUMO in this process, stepped in line with the frames."""

    def __init__(self, net_path: Path, scenario: Scenario, radius_m: float, clock: StageClock = NO_CLOCK) -> None:
        from cosim.traffic import Traffic
        from networks.world import load_net

        self._traffic = Traffic(net_path, load_net(net_path), scenario)
        self._radius_m, self._clock = radius_m, clock
        self._closed = False

    def warm_up(self) -> list[str]:
        self._traffic.warm_up()
        self._traffic.watch_near_ego(self._radius_m)
        return list(self._traffic.notices)

    def next(self) -> WorldState:
        with self._clock.stage("sumo step"):
            self._traffic.step()
        with self._clock.stage("world state"):
            return self._traffic.world_state().near(self._radius_m)

    def close(self) -> None:
        if not self._closed:
            self._closed = True
            self._traffic.close()

    def abort(self) -> None:
        self.close()


class TrafficProcess:
    """SUMO in a traffic process that computes each frame's world state one frame ahead.
    With a ``clock``: "sumo wait" here, the process's own stage times on ``close``."""

    def __init__(self, net_path: Path, scenario: Scenario, radius_m: float, clock: StageClock = NO_CLOCK) -> None:
        self._child = ChildProcess("cosim.traffic_feed:serve")
        self._clock = clock
        self._left = scenario.frames
        self._send(("start", net_path, scenario, radius_m, is_timing(clock)))

    def warm_up(self) -> list[str]:
        notices: list[str] = self._receive("ready")
        if self._left > 0:
            self._send(("go",))  # frame 0 is stepped ahead
        return notices

    def next(self) -> WorldState:
        with self._clock.stage("sumo wait"):
            state: WorldState = self._receive("state")
        self._left -= 1
        if self._left > 0:
            self._send(("go",))  # the next frame is stepped while this one is sensed
        return state

    def close(self) -> None:
        self._send(("stop",))
        times: StageTimes = self._receive("closed")
        self._child.join(STOP_WAIT_S)
        self._child.close()
        for name, seconds in times.seconds.items():
            self._clock.add(name, seconds, times.calls[name])

    def abort(self) -> None:
        with contextlib.suppress(ChildGoneError):
            self._child.send(("stop",))
        self._child.join(STOP_WAIT_S)
        self._child.close()

    def _send(self, message: tuple[Any, ...]) -> None:
        try:
            self._child.send(message)
        except ChildGoneError as gone:
            while self._child.poll():  # the process's own error, if it said one
                self._receive("")
            raise _stopped(gone) from None

    def _receive(self, kind: str) -> Any:
        try:
            message = self._child.receive()
        except ChildGoneError as gone:
            raise _stopped(gone) from None
        if message[0] == "error":
            raise TrafficError(message[1])
        if message[0] != kind:
            raise TrafficError(f"traffic process: expected {kind!r}, got {message[0]!r}")
        return message[1]


def _stopped(gone: ChildGoneError) -> TrafficError:
    return TrafficError(f"traffic process stopped unexpectedly ({gone})")


def error_line(err: BaseException) -> str:
    text = " ".join(str(err).split())
    if isinstance(err, CosimError | NetworkError) and text:
        return text
    return f"traffic process: {type(err).__name__}: {text}"


def serve(inbox: Connection, outbox: Connection) -> None:  # runs in the traffic process
    """Start SUMO, warm up, then one world state per "go" until "stop"; errors as one line."""
    feed: TrafficInline | None = None
    times = StageTimes()
    try:
        _, net_path, scenario, radius_m, timed = inbox.recv()
        feed = TrafficInline(net_path, scenario, radius_m, times if timed else NO_CLOCK)
        outbox.send(("ready", feed.warm_up()))
        while inbox.recv()[0] == "go":
            outbox.send(("state", feed.next()))
        outbox.send(("closed", times))
    except BaseException as err:
        with contextlib.suppress(OSError):
            outbox.send(("error", error_line(err)))
    finally:
        if feed is not None:
            feed.close()
