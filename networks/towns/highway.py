"""Motorways with diamond interchanges: two carriageways, ramps, and a bridge over them.

At each interchange a crossing road passes over the motorway on a bridge; each
carriageway leaves to the bridge's near end by an off-ramp and returns from it by an
on-ramp that adds an acceleration lane, dropped again further on.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from networks.geometry import polyline_length
from networks.towns.layout import Point, StreetStyle, TownBuilder, bezier, polyline_between, polyline_frame, smooth_z

RAMP_LEVEL_SHARE = 0.3  # of a ramp's length, at the carriageway's end, kept level


@dataclass(frozen=True, slots=True)
class MotorwaySpec:
    lanes: int = 3
    speed_mps: float = 30.0
    median_m: float = 3.0  # between the two carriageways
    ramp_m: float = 230.0  # along the motorway from a ramp's end to the bridge
    accel_lane_m: float = 180.0  # acceleration lane after an on-ramp
    bridge_z_m: float = 7.5
    bridge_offset_m: float = 50.0  # from the motorway axis to each end of the bridge
    approach_m: float = 150.0  # of the crossing road, from the bridge down to the ground

    @property
    def carriageway_offset_m(self) -> float:
        return self.median_m / 2.0 + self.lanes * 3.5 / 2.0


@dataclass(frozen=True, slots=True)
class Interchange:
    """Node ids at ground level where the crossing road of an interchange ends (right and
    left of the motorway's forward direction)."""

    right_ground: str
    left_ground: str


def motorway(
    b: TownBuilder,
    name: str,
    centre: npt.NDArray[np.float64],
    interchange_s: list[float],
    spec: MotorwaySpec,
    closed: bool = False,
) -> list[Interchange]:
    """Lay out both carriageways along ``centre`` (``(K, 2)``; for ``closed`` the first
    point is repeated at the end) with interchanges at the arc lengths ``interchange_s``."""
    total = polyline_length(centre)
    road = StreetStyle(lanes=1, lane_width_m=3.3, sidewalk_width_m=2.0, speed_mps=13.89)
    out = []
    for k, s in enumerate(interchange_s):
        out.append(_crossing(b, f"{name}x{k}", centre, s, spec, road))
    for direction in (1, -1):
        _carriageway(b, f"{name}{'f' if direction > 0 else 'b'}", centre, total, interchange_s, spec, direction, closed)
    return out


def _crossing(
    b: TownBuilder, name: str, centre: npt.NDArray[np.float64], s: float, spec: MotorwaySpec, road: StreetStyle
) -> Interchange:
    p, _, n = polyline_frame(centre, s)
    ends = []
    for side, tag in ((-1.0, "r"), (1.0, "l")):
        top = p + n * side * spec.bridge_offset_m
        ground = p + n * side * (spec.bridge_offset_m + spec.approach_m)
        b.node(f"{name}{tag}", (top[0], top[1]), spec.bridge_z_m, "traffic_light")
        b.node(f"{name}{tag}g", (ground[0], ground[1]), 0.0, "priority")
        via = _straight(b.point(f"{name}{tag}"), b.point(f"{name}{tag}g"), 12)
        b.street(f"{name}{tag}", f"{name}{tag}g", road, smooth_z(via, spec.bridge_z_m, 0.0))
        ends.append(f"{name}{tag}g")
    deck = _straight(b.point(f"{name}r"), b.point(f"{name}l"), 6)
    b.street(f"{name}r", f"{name}l", road, deck)
    return Interchange(ends[0], ends[1])


def _straight(p0: Point, p1: Point, n: int) -> list[Point]:
    t = np.linspace(0.0, 1.0, n + 2)[1:-1]
    return [tuple(float(v) for v in np.array(p0) + ti * (np.array(p1) - np.array(p0))) for ti in t]  # type: ignore[misc]


def _carriageway(
    b: TownBuilder,
    name: str,
    centre: npt.NDArray[np.float64],
    total: float,
    interchange_s: list[float],
    spec: MotorwaySpec,
    direction: int,
    closed: bool,
) -> None:
    """Nodes along one carriageway (in forward arc length), then its edges and ramps."""
    offset = -direction * spec.carriageway_offset_m  # right of the travel direction
    marks: list[tuple[float, str, str]] = []  # (s, node id, role)
    for k, s in enumerate(interchange_s):
        off_s, on_s = s - direction * spec.ramp_m, s + direction * spec.ramp_m
        marks.append((off_s, f"{name}{k}off", "off"))
        marks.append((on_s, f"{name}{k}on", "on"))
        marks.append((on_s + direction * spec.accel_lane_m, f"{name}{k}drop", "drop"))
    if not closed:
        first, last = (0.0, total) if direction > 0 else (total, 0.0)
        marks += [(first, f"{name}start", "end"), (last, f"{name}end", "end")]
    marks = sorted(((s % total if closed else s), nid, role) for s, nid, role in marks)
    if direction < 0:
        marks.reverse()
    for s, nid, _ in marks:
        p, _, n = polyline_frame(centre, s)
        q = p + n * offset
        b.node(nid, (q[0], q[1]), 0.0, "priority")
    pairs = list(zip(marks, marks[1:] + (marks[:1] if closed else []), strict=False))
    for (s0, a, role), (s1, c, _) in pairs:
        lanes = spec.lanes + (1 if role == "on" else 0)
        lo, hi = (s0, s1) if direction > 0 else (s1, s0)
        via = _wrapped(centre, lo, hi, total, offset)
        b.carriageway(a, c, lanes, spec.speed_mps, via if direction > 0 else list(reversed(via)))
    for k, s in enumerate(interchange_s):
        end = f"{name[:-1]}x{k}{'r' if direction > 0 else 'l'}"
        travel = polyline_frame(centre, s)[1] * direction
        _ramp(b, f"{name}{k}off", end, travel, spec.ramp_m)
        _ramp(b, end, f"{name}{k}on", travel, spec.ramp_m)


def _wrapped(centre: npt.NDArray[np.float64], s0: float, s1: float, total: float, offset: float) -> list[Point]:
    if s1 >= s0:
        return polyline_between(centre, s0, s1, offset)
    return polyline_between(centre, s0, total, offset) + polyline_between(centre, 0.0, s1, offset)


def _ramp(b: TownBuilder, a: str, c: str, travel: npt.NDArray[np.float64], ramp_m: float) -> None:
    """A one-lane ramp from node ``a`` to node ``c``, leaving and arriving along ``travel``."""
    p0, p3 = np.array(b.point(a)), np.array(b.point(c))
    t = np.array([travel[0], travel[1], 0.0])
    p1, p2 = p0 + t * ramp_m * 0.45, p3 - t * ramp_m * 0.4
    via = bezier(tuple(p0), tuple(p1), tuple(p2), tuple(p3), 24)
    # Level where the ramp still runs beside the carriageway (it must not rise over its lanes).
    t0, t1 = (RAMP_LEVEL_SHARE, 1.0) if p0[2] <= p3[2] else (0.0, 1.0 - RAMP_LEVEL_SHARE)
    b.carriageway(a, c, 1, 19.0, smooth_z(via, float(p0[2]), float(p3[2]), t0, t1))
