"""The frame loop's source of world states: SUMO in a process of its own, one frame ahead.

:class:`TrafficProcess` starts a new interpreter (:mod:`gtgen.child`) that runs
:class:`~cosim.sumo.traffic.Traffic` (libsumo runs one simulation per process): it warms the
traffic up, then steps it and reads the frame's world state while the loop senses the
previous frame, so SUMO's work leaves the loop's process and only small world states
cross the pipe. It makes the same libsumo calls in the same order as stepping in line
would, so the traffic is the same. An error there comes back as one line
(:class:`~cosim.errors.TrafficError`). A run that stops (Ctrl-C, SIGTERM, an error) kills it at
once, and so does the system when the run's process ends, however it ends (it never outlives
the run). :class:`TrafficInline` does the same in this process.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from multiprocessing.connection import Connection
from pathlib import Path
from typing import Protocol

import numpy as np
import numpy.typing as npt

from cosim.errors import CosimError, TrafficError
from cosim.scenario import Scenario
from cosim.state import WorldState
from gtgen.channel import Close, Closed, Go, Link, Ready, Result, Start
from gtgen.channel import serve as serve_child
from gtgen.lifetime import ClosedOnExit
from gtgen.timing import NO_CLOCK, StageClock, StageTimes, is_timing
from networks.errors import NetworkError

STOP_WAIT_S = 30.0


class TrafficFeed(Protocol):
    """A source of world states, used as a context manager: closed when the ``with`` block
    ends, aborted when it raises."""

    def __enter__(self) -> TrafficFeed: ...

    def __exit__(self, kind: type[BaseException] | None, error: BaseException | None, *_: object) -> None: ...

    def warm_up(self) -> list[str]:
        """Fill the town and pick the ego; returns notices for the user."""
        ...

    def next(self) -> WorldState:
        """Step one frame; the agents within the radius of the ego."""
        ...

    def close(self) -> None: ...

    def abort(self) -> None: ...


class TrafficInline(ClosedOnExit):
    """SUMO in this process, stepped in line with the frames."""

    def __init__(
        self, net_path: Path, scenario: Scenario, radius_m: float, clock: StageClock = NO_CLOCK, skip_frames: int = 0
    ) -> None:
        from cosim.sumo.traffic import Traffic
        from networks.world import load_net

        self._traffic = Traffic(net_path, load_net(net_path), scenario)
        self._radius_m, self._clock, self._skip = radius_m, clock, skip_frames
        self._closed = False
        self._before: npt.NDArray[np.uint32] | None = None  # the agents read the step before the next frame's
        self._ahead: WorldState | None = None  # the step after the last frame handed out, read ahead

    def warm_up(self) -> list[str]:
        """The warm-up, then the frames to skip: simulated as for the frames handed out
        (world states read, track ids given), so the next frame is the one a run without
        skipping would make."""
        self._traffic.warm_up()
        self._traffic.watch_near_ego(self._radius_m)
        for _ in range(self._skip):
            self._traffic.step()
            self._before = self._traffic.world_state().agents.instance_id
        return list(self._traffic.notices)

    def next(self) -> WorldState:
        """The next step's world state with its bodies' rates of turn before and after its time
        (:func:`turn_rates_across`): the step after it is read ahead (the same steps and reads in
        the same order; one step more at the end)."""
        if self._ahead is None:
            self._ahead = self._read()
        now, self._ahead = self._ahead, self._read()
        turning = turn_rates_across(now, self._ahead, self._before)
        self._before = now.agents.instance_id
        return turning.near(self._radius_m)

    def _read(self) -> WorldState:
        with self._clock.stage("sumo step"):
            self._traffic.step()
        with self._clock.stage("world state"):
            return self._traffic.world_state()

    def close(self) -> None:
        if not self._closed:
            self._closed = True
            self._traffic.close()

    def abort(self) -> None:
        self.close()


def turn_rates_across(now: WorldState, ahead: WorldState, before: npt.NDArray[np.uint32] | None) -> WorldState:
    """``now`` with each body's rate of turn on both sides of its time: up to it, the heading's
    change over the step that ended then (the traffic's own rate); from it on, that over the next
    step (``ahead``'s), so a timed LiDAR sweep turns each body as its headings interpolated between
    the steps do, from half a period before the frame's time to half after. An agent not read the
    step before (``before``: the ids read then; None: none) takes the next step's rate on both
    sides, one gone by the next step its own; the ego likewise across a scene cut (another ego
    before or after)."""
    a, b = now.agents, ahead.agents
    order = np.argsort(b.instance_id, kind="stable")
    ids = b.instance_id[order]
    later = ids.shape[0] > 0
    at = np.minimum(np.searchsorted(ids, a.instance_id), max(ids.shape[0] - 1, 0))
    found = ids[at] == a.instance_id if later else np.zeros(a.instance_id.shape[0], np.bool_)
    after = np.where(found, b.yaw_rate_rad_s[order[at]] if later else 0.0, a.yaw_rate_rad_s)
    read_before = np.zeros(a.instance_id.shape[0], np.bool_) if before is None else np.isin(a.instance_id, before)
    rates = replace(a, yaw_rate_rad_s=np.where(read_before, a.yaw_rate_rad_s, after), yaw_rate_after_rad_s=after)
    ego_before, ego_after = now.ego.yaw_rate_rad_s, now.ego.yaw_rate_rad_s
    if not ahead.scene_cut:
        ego_after = ahead.ego.yaw_rate_rad_s
        if now.scene_cut or before is None:
            ego_before = ego_after
    ego = replace(now.ego, yaw_rate_rad_s=ego_before, yaw_rate_after_rad_s=ego_after)
    return replace(now, agents=rates, ego=ego)


@dataclass(frozen=True, slots=True)
class TrafficJob:
    """What the traffic process runs: the network, the scenario, the radius of the agents
    sent back around the ego."""

    net_path: Path
    scenario: Scenario
    radius_m: float
    skip_frames: int = 0


class TrafficProcess(ClosedOnExit):
    """SUMO in a traffic process that computes each frame's world state one frame ahead.
    With a ``clock``: "sumo wait" here, the process's own stage times on ``close``."""

    def __init__(
        self, net_path: Path, scenario: Scenario, radius_m: float, clock: StageClock = NO_CLOCK, skip_frames: int = 0
    ) -> None:
        self._link = Link("cosim.traffic_feed:serve", "traffic process", TrafficError, dies_with_parent=True)
        self._clock = clock
        self._left = scenario.frames - skip_frames
        self._link.send(Start(TrafficJob(net_path, scenario, radius_m, skip_frames), is_timing(clock)))

    def warm_up(self) -> list[str]:
        notices = list(self._link.expect(Ready).notices)
        if self._left > 0:
            self._link.send(Go())  # frame 0 is stepped ahead
        return notices

    def next(self) -> WorldState:
        with self._clock.stage("sumo wait"):
            result = self._link.expect(Result)
        self._left -= 1
        if self._left > 0:
            self._link.send(Go())  # the next frame is stepped while this one is sensed
        if not isinstance(result.value, WorldState):
            raise TrafficError(f"traffic process: expected a world state, got {type(result.value).__name__}")
        return result.value

    def close(self) -> None:
        self._link.send(Close())
        times = self._link.expect(Closed).times
        self._link.join(STOP_WAIT_S)
        self._link.close()
        for name, seconds in times.seconds.items():
            self._clock.add(name, seconds, times.calls[name])

    def abort(self) -> None:
        """End the traffic process now: it holds nothing to keep, and may be in a long warm-up
        that reads no message until it ends."""
        self._link.kill()


def serve(inbox: Connection, outbox: Connection) -> None:  # runs in the traffic process
    """Start SUMO, warm up, then one world state per :class:`Go` until :class:`Close` (answered
    with :class:`Closed`) or :class:`Abort`; errors as one :class:`Failed` line."""
    feed: TrafficInline | None = None

    def work() -> None:
        nonlocal feed
        start: Start[TrafficJob] = inbox.recv()
        job, times = start.job, StageTimes()
        feed = TrafficInline(
            job.net_path, job.scenario, job.radius_m, times if start.timed else NO_CLOCK, job.skip_frames
        )
        outbox.send(Ready(tuple(feed.warm_up())))
        message = inbox.recv()
        while isinstance(message, Go):
            outbox.send(Result(feed.next()))
            message = inbox.recv()
        if isinstance(message, Close):
            outbox.send(Closed(times))

    try:
        serve_child(outbox, work, (CosimError, NetworkError), "traffic process")
    finally:
        if feed is not None:
            feed.close()
