"""The hazard controller: when events are due, their preparation, start and end."""

from __future__ import annotations

import contextlib
from collections.abc import Callable

import numpy as np

from cosim.hazards.plan import Schedule
from cosim.scenario import HazardConfig
from cosim.sumo.hazards.base import KEEP_LANE, LATE_S, Event
from cosim.sumo.hazards.jaywalkers import JAYWALK_LEAD_S, Jaywalkers
from cosim.sumo.hazards.red_lights import RED_LEAD_S, RedLights
from cosim.sumo.hazards.vehicles import LEADER_LEAD_S, MAKE_LEAD_S, Vehicles
from gtgen.frame import ActiveHazard
from networks.sumo_tools import sumo_home
from networks.vocabulary import HazardKind

sumo_home()  # exports SUMO_HOME before libsumo loads
import libsumo  # noqa: E402

LEADS_S = {
    HazardKind.CUT_IN: MAKE_LEAD_S,
    HazardKind.HARD_BRAKE: LEADER_LEAD_S,
    HazardKind.JAYWALKER: JAYWALK_LEAD_S,
    HazardKind.RED_LIGHT: RED_LEAD_S,
}
PREPARED_AT_ONCE = {HazardKind.CUT_IN: 2, HazardKind.HARD_BRAKE: 1, HazardKind.JAYWALKER: 2, HazardKind.RED_LIGHT: 1}


class HazardController(Vehicles, Jaywalkers, RedLights):
    """The scenario's hazards near the ego: call :meth:`step` after each simulation step."""

    @property
    def lead_s(self) -> float:
        """How long before an event is due its preparation may start."""
        return max(LEADS_S[h.kind] for h in self._hazards)

    @property
    def busy(self) -> bool:
        """Whether an event is being prepared or is under way."""
        return bool(self._events)

    def begin(self, start_s: float) -> None:
        """Events are due from ``start_s`` on (the first step's time, if not called)."""
        self._schedules = [
            Schedule(60.0 / h.per_minute, start_s, np.random.default_rng([self._seed, 0x5C4E, i]))
            for i, h in enumerate(self._hazards)
        ]

    def step(self, ego: str, now: float) -> None:
        """Move the events under way and those being prepared, end those that are over,
        prepare those due soon."""
        if not self._schedules:
            self.begin(now)
        self._way_back.note(ego)
        self._take_back_unmade()
        self._hold_people(ego)
        for event in list(self._events):
            self._move(event, ego, now)
        for index, hazard in enumerate(self._hazards):
            self._prepare(index, hazard, ego, now)
        self._hold_ego_lane(ego)
        if any(h.kind == HazardKind.RED_LIGHT for h in self._hazards):
            self._green_ahead(ego, actuate=True)  # the ego does not wait at a red: it is to approach greens

    def active(self, track_id: Callable[[str], int], ego: str) -> tuple[ActiveHazard, ...]:
        shown = sorted((e for e in self._events if e.number), key=lambda e: e.number)
        return tuple(
            ActiveHazard(f"{e.kind}-{e.number}", e.kind, tuple(track_id(a) for a in e.actors), track_id(ego))
            for e in shown
        )

    def _prepare(self, index: int, hazard: HazardConfig, ego: str, now: float) -> None:
        """Start preparing the next event of a kind when it is due within its lead time."""
        preparing = {e.due_s for e in self._events if e.index == index and not e.number}
        if now < self._retry[index] or len(preparing) >= PREPARED_AT_ONCE[hazard.kind]:
            return
        due = next(d for d in map(self._schedules[index].due_s, range(len(preparing) + 1)) if d not in preparing)
        if now < due - LEADS_S[hazard.kind]:
            return
        make = {
            HazardKind.CUT_IN: self._make_cut_in,
            HazardKind.HARD_BRAKE: self._make_hard_brake,
            HazardKind.JAYWALKER: self._make_jaywalker,
            HazardKind.RED_LIGHT: self._make_red_light,
        }[hazard.kind]
        try:
            event = make(Event(index, hazard, [], due, due + LATE_S), ego, now)
        except libsumo.TraCIException:
            event = None
        if event is not None:
            self._events.append(event)

    def _move(self, event: Event, ego: str, now: float) -> None:
        prepared = not event.number
        try:
            done = self._ready(event, ego, now) if prepared else self._advance(event, ego, now)
        except libsumo.TraCIException:
            done = True  # an actor left the simulation
        if done:
            for undo in reversed(event.restore):  # the last change first
                with contextlib.suppress(libsumo.TraCIException):  # an actor gone
                    undo()
            self._events.remove(event)
            if not event.number:
                self._retry[event.index] = now + 1.0  # it came to nothing: another actor soon

    def _ready(self, event: Event, ego: str, now: float) -> bool:
        """One step of a preparation (it may start the event); True: it is given up."""
        ready = {
            HazardKind.CUT_IN: self._cut_in_ready,
            HazardKind.HARD_BRAKE: self._hard_brake_ready,
            HazardKind.JAYWALKER: self._jaywalker_ready,
            HazardKind.RED_LIGHT: self._red_light_ready,
        }[event.kind]
        return ready(event, ego, now)

    def _take_back_unmade(self) -> None:
        """Vehicles made last step that could not enter the road are taken back (rather than
        entering later, when they could be in sight); their preparations end."""
        waiting = set(libsumo.simulation.getPendingVehicles())
        for vid in sorted(self._pending & waiting):
            libsumo.vehicle.remove(vid)
        self._pending.clear()

    def _hold_ego_lane(self, ego: str) -> None:
        """The ego keeps its lane while a cut-in or a hard brake is prepared or under way (lane
        changes its route needs only; its leader stays its leader) and changes none while a
        cut-in is under way; then it gets its own lane changes back."""
        cut_ins = [e for e in self._events if e.kind == HazardKind.CUT_IN]
        held = cut_ins or [e for e in self._events if e.kind == HazardKind.HARD_BRAKE]
        mode = 0 if any(e.number for e in cut_ins) else KEEP_LANE if held else None
        if mode is None and self._ego_mode is not None:
            libsumo.vehicle.setLaneChangeMode(ego, self._ego_mode)
            self._ego_mode = None
        elif mode is not None:
            if self._ego_mode is None:
                self._ego_mode = libsumo.vehicle.getLaneChangeMode(ego)
            libsumo.vehicle.setLaneChangeMode(ego, mode)

    def _advance(self, event: Event, ego: str, now: float) -> bool:
        """One step of an event under way; True: it is over."""
        if event.kind == HazardKind.JAYWALKER and event.path is not None:
            return self._walk(event, ego, now)
        return now >= event.ends_s
