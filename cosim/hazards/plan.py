"""When hazard events are due, and where the rig cannot see (pure functions, no SUMO).

:class:`Schedule`: events of one kind are due one in each period of ``60 / per_minute``
seconds from the first step, at a point drawn in the middle half of the period (so two are
0.5 to 1.5 periods apart, and any stretch of the run holds the number asked to within 1.5).

:class:`Sight`: the places around the ego that no sensor of the rig reaches and that are too
far to be labelled: an actor made there for an event enters the sensors' view by driving or
walking into it, never by appearing in it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from cosim.scenario import SensorsConfig

SLOT_SPREAD = (0.25, 0.75)  # where in its period an event is due
BACKLOG = 2  # events of a kind owed at most, when the traffic held them back


@dataclass(slots=True)
class Schedule:
    """The due times of one hazard kind: one in each ``period_s`` from ``start_s``, at a point
    of the period drawn from ``rng`` (in the order of the periods)."""

    period_s: float
    start_s: float
    rng: np.random.Generator
    taken: int = 0  # periods whose event started or was given up
    offsets: list[float] = field(default_factory=list)

    def due_s(self, ahead: int = 0) -> float:
        """When the next event is due (``ahead``: the one that many after it)."""
        slot = self.taken + ahead
        while len(self.offsets) <= slot:
            self.offsets.append(float(self.rng.uniform(*SLOT_SPREAD)))
        return self.start_s + (slot + self.offsets[slot]) * self.period_s

    def take(self, now_s: float) -> None:
        """An event started at ``now_s``: the next one is due in the next period; periods
        more than ``BACKLOG`` behind ``now_s`` are given up."""
        self.taken += 1
        while self.due_s() < now_s - BACKLOG * self.period_s:
            self.taken += 1


@dataclass(frozen=True, slots=True)
class Sight:
    """What the rig sees, in the ego frame: per sensor ``(x_m, y_m, yaw_rad, half_fov_rad,
    range_m)`` (its mount, where it looks, its horizontal field of view and range); objects
    within ``label_m`` of the ego are labelled whether or not a ray meets them."""

    sensors: tuple[tuple[float, float, float, float, float], ...]
    label_m: float

    @classmethod
    def of_rig(cls, rig: SensorsConfig) -> Sight:
        views = [(s.mount_xyz_m, s.mount_rpy_deg[2], 360.0, s.range_m) for s in rig.lidars]
        views += [(s.mount_xyz_m, s.mount_rpy_deg[2], s.hfov_deg, s.range_m) for s in rig.cameras]
        views += [(s.mount_xyz_m, s.mount_rpy_deg[2], s.hfov_deg, s.range_m) for s in rig.radars]
        sensors = tuple(
            (xyz[0], xyz[1], math.radians(yaw), math.radians(fov / 2.0), rng) for xyz, yaw, fov, rng in views
        )
        label = max((s.range_m for s in rig.lidars), default=max(v[3] for v in views))
        return cls(sensors, label)

    def sees(self, xy_ego_m: np.ndarray, radius_m: float) -> bool:
        """Whether any part of a disc of ``radius_m`` around ``xy_ego_m`` (ego frame, metres)
        may be labelled or lie in a sensor's field of view and range."""
        x, y = float(xy_ego_m[0]), float(xy_ego_m[1])
        if math.hypot(x, y) - radius_m <= self.label_m:
            return True
        for sx, sy, yaw, half_fov, range_m in self.sensors:
            dist = math.hypot(x - sx, y - sy)
            if dist - radius_m > range_m:
                continue
            if half_fov >= math.pi or dist <= radius_m:
                return True
            bearing = math.atan2(y - sy, x - sx) - yaw
            off = abs(math.atan2(math.sin(bearing), math.cos(bearing)))
            if off <= half_fov + math.asin(radius_m / dist):
                return True
        return False

    def clear_behind_m(self, across_m: float, radius_m: float) -> float:
        """How far behind the ego a disc ``across_m`` to either side of it is out of sight (5 m steps)."""
        back = 0.0
        while self.sees(np.array([-back, across_m]), radius_m) or self.sees(np.array([-back, -across_m]), radius_m):
            back += 5.0
        return back

    def clear_ahead_m(self, radius_m: float) -> float:
        """How far ahead of the ego a disc on its heading line is out of sight (5 m steps)."""
        ahead = 0.0
        while self.sees(np.array([ahead, 0.0]), radius_m):
            ahead += 5.0
        return ahead
