"""Red-light runners: while the ego approaches its green, a vehicle on a crossing approach runs
its red (the ego's light turns green as it comes, as an actuated light would; a crossing car
is made out of the rig's sight where none could run). In a scene with red-light runners every
light the ego comes to turns green for it so: an ego waiting at a red when an event is due
would pass its light too close to it, and its next light may be far away."""

from __future__ import annotations

import numpy as np

from cosim.hazards.decisions import JUNCTION_M, RED_LIGHT_S, RED_MARGIN_S, phase_to_green, red_run
from cosim.sumo.hazards import roads
from cosim.sumo.hazards.base import CAR_RADIUS_M, HIDDEN_MARGIN_M, SPEED_DEFAULT, Base, Event, free
from networks.sumo_tools import sumo_home
from networks.vocabulary import SignalState

sumo_home()  # exports SUMO_HOME before libsumo loads
import libsumo  # noqa: E402

IGNORE_RED_AND_RIGHT_OF_WAY = 7  # speed mode: safe speed, acceleration and deceleration limits only
RED_NEAR_M = 60.0  # a runner is within this of its stop line
RED_LEAD_S, RED_LATE_S = 15.0, 30.0  # a red-light runner is prepared this long before it is due, given up after
RED_EARLY_S = 2.0  # and may run this long before it is due
RED_ACTUATE_S = 10.0  # the ego's light turns green for it if it would reach it within this, from this before due
RED_PLAN_M = 200.0  # the ego's next light is looked at within this


class RedLights(Base):
    def _make_red_light(self, event: Event, ego: str, now: float) -> Event | None:
        """A red-light runner to come (the ego's light is made green as it comes, and a crossing
        vehicle made where none could run the red)."""
        event.ends_s = event.due_s + RED_LATE_S
        return event

    def _red_light_ready(self, event: Event, ego: str, now: float) -> bool:
        if now >= event.due_s - RED_EARLY_S and not self._under_way(event.index) and self._run_red(event, ego, now):
            return False
        soon = now >= event.due_s - RED_ACTUATE_S
        ahead = self._green_ahead(ego, soon)
        if soon and ahead is not None and event.spot[0] != ahead[0] and self._make_crosser(ego, *ahead):
            event.spot = (ahead[0], 0.0)  # one for each light
        return now >= event.ends_s

    def _green_ahead(self, ego: str, actuate: bool) -> tuple[str, int, float] | None:
        """The ego's next light (its id, the ego's link and distance) if it shows the ego green,
        within ``RED_PLAN_M``; with ``actuate``, a red one the ego would stop at is switched to
        green for it first (as a light that detects it coming would: the crossing direction's
        green ends at once, through its yellow)."""
        ahead = roads.next_lights(ego)
        if not ahead or ahead[0][2] > RED_PLAN_M:
            return None
        tls, link, dist, state = ahead[0]
        if state.is_green:
            return tls, link, dist
        lane = libsumo.vehicle.getLaneID(ego)
        speed = max(libsumo.vehicle.getSpeed(ego), 0.5 * libsumo.lane.getMaxSpeed(lane) if lane else 1.0)
        waiting = libsumo.vehicle.getSpeed(ego) < 1.0  # in the queue at the light: it may turn green at once
        if actuate and state.is_red and dist / speed <= RED_ACTUATE_S:
            _green_for(tls, link, float("inf") if waiting else dist / speed)
        return None

    def _make_crosser(self, ego: str, tls: str, ego_link: int, ego_dist: float) -> bool:
        """A car made on a crossing approach of a light the ego comes to (one whose link has red
        when the ego's has green), where no sensor sees it, routed across; none is made where a
        vehicle could run the red already. True: made (or not needed)."""
        links = libsumo.trafficlight.getControlledLinks(tls)
        state = SignalState.decode(libsumo.trafficlight.getRedYellowGreenState(tls))
        ego_in = links[ego_link][0][0].rsplit("_", 1)[0] if links[ego_link] else ""
        crossing = [i for i, link in enumerate(links) if link and (state[i].is_red or state[i].is_yellow)
                    and link[0][0].rsplit("_", 1)[0] != ego_in
                    and "passenger" not in libsumo.lane.getDisallowed(link[0][0])]  # fmt: skip
        if not crossing or any(self._runners(tls, i, ego) for i in crossing):
            return bool(crossing)
        index = crossing[int(self._rng.integers(0, len(crossing)))]
        in_lane, out_lane, _ = links[index][0]
        road, lane_index = in_lane.rsplit("_", 1)
        length = libsumo.lane.getLength(in_lane)
        for pos in np.arange(length - RED_NEAR_M, 5.0, -10.0):
            xy = np.array(libsumo.simulation.convert2D(road, float(pos), int(lane_index)))
            if free(in_lane, float(pos), 20.0) and not self._sight.sees(
                roads.in_ego_frame(ego, xy), CAR_RADIUS_M + HIDDEN_MARGIN_M
            ):
                self._add_car([road, out_lane.rsplit("_", 1)[0]], float(pos), int(lane_index))
                return True
        return False

    def _runners(self, tls: str, index: int, ego: str) -> list[str]:
        """Vehicles on the approach lane of a link that could run its red: within ``RED_NEAR_M``
        of the stop line, moving, or the first in the queue."""
        lane = libsumo.trafficlight.getControlledLinks(tls)[index][0][0]
        queue = libsumo.lane.getLastStepVehicleIDs(lane)
        front = max(queue, key=libsumo.vehicle.getLanePosition, default="")  # the nearest the stop line
        length = libsumo.lane.getLength(lane)
        return [vid for vid in queue if self._movable(vid, ego)
                and (libsumo.vehicle.getSpeed(vid) >= 2.0 or vid == front)
                and 0.5 <= length - libsumo.vehicle.getLanePosition(vid) <= RED_NEAR_M]  # fmt: skip

    def _run_red(self, event: Event, ego: str, now: float) -> bool:
        """While the ego approaches its green within ``distance_m``, a vehicle on a crossing
        approach with red runs it, timed to clear the junction before the ego or to enter it
        after. True: it started."""
        lo, hi = event.config.distance_m
        ahead = [t for t in roads.next_lights(ego) if lo <= t[2] <= hi]
        if not ahead or not ahead[0][3].is_green:
            return False
        tls, ego_link, ego_dist, _ = ahead[0]
        ego_speed = max(libsumo.vehicle.getSpeed(ego), 1.0)
        ego_time = ego_dist / ego_speed  # until the ego reaches its stop line
        ego_clear = (ego_dist + JUNCTION_M) / ego_speed + RED_MARGIN_S  # until it has crossed, with a margin
        state = SignalState.decode(libsumo.trafficlight.getRedYellowGreenState(tls))
        links = libsumo.trafficlight.getControlledLinks(tls)
        ego_in = links[ego_link][0][0] if links[ego_link] else ""
        candidates = []
        for index, link in enumerate(links):
            if not link or not state[index].is_red or link[0][0].rsplit("_", 1)[0] == ego_in.rsplit("_", 1)[0]:
                continue
            lane = link[0][0]
            for vid in self._runners(tls, index, ego):
                dist = libsumo.lane.getLength(lane) - libsumo.vehicle.getLanePosition(vid)
                run = red_run(dist, libsumo.vehicle.getSpeed(vid), ego_time, ego_clear)  # before or behind the ego
                if run is not None:
                    candidates.append((vid, *run))
        if not candidates:
            return False
        vid, speed, lasts_s = sorted(candidates)[int(self._rng.integers(0, len(candidates)))]
        libsumo.vehicle.setSpeedMode(vid, IGNORE_RED_AND_RIGHT_OF_WAY)
        libsumo.vehicle.setSpeed(vid, speed)
        event.actors.append(vid)
        event.restore += [
            lambda: libsumo.vehicle.setSpeed(vid, -1.0),
            lambda: libsumo.vehicle.setSpeedMode(vid, SPEED_DEFAULT),
        ]
        self._turn_on(event, now, now + max(RED_LIGHT_S, lasts_s))
        return True


def _green_for(tls: str, link: int, eta_s: float) -> bool:
    """Switch a light to the yellow that ends the current green, and leads to the phase giving
    ``link`` green, if the ego gets there no sooner than that yellow ends (and the program's
    own order allows it: a link green now is yellow or green then, or goes red next anyway)."""
    program = libsumo.trafficlight.getProgram(tls)
    phases = next(logic.phases for logic in libsumo.trafficlight.getAllProgramLogics(tls) if logic.programID == program)
    states = [SignalState.decode(phase.state) for phase in phases]
    phase = phase_to_green(states, [p.duration for p in phases], libsumo.trafficlight.getPhase(tls), link, eta_s)
    if phase is None:
        return False
    libsumo.trafficlight.setPhase(tls, phase)
    return True
