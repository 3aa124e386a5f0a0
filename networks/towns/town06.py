"""town06: a long motorway (3-4 lanes per direction) with entrance and exit ramps.

Diamond interchanges carry crossing roads over the motorway on bridges (the
overpass); local streets with sidewalks link the crossing roads on either side, and
loops at both ends, as wide as the carriageways, let traffic turn back.
"""

from __future__ import annotations

import itertools

import numpy as np
import numpy.typing as npt

from networks.plain import PlainNetwork
from networks.towns.highway import MotorwaySpec, motorway
from networks.towns.layout import StreetStyle, TownBuilder, wiggle

LOOP_RADIUS_M = 45.0  # of every bend of the turning loops at the motorway's ends
LOOP_PIECES = 4  # edges per loop


def town06(seed: int, length_m: float = 2400.0, interchanges: int = 2) -> PlainNetwork:
    rng = np.random.default_rng(seed)
    spec = MotorwaySpec(lanes=int(rng.integers(3, 5)), speed_mps=float(rng.uniform(27.0, 33.0)))
    bend = float(rng.uniform(-60.0, 60.0))
    x = np.linspace(0.0, length_m, 49)
    centre = np.column_stack([x, bend * np.sin(np.pi * x / length_m)])
    spacing = length_m / (interchanges + 1)
    jitter = rng.uniform(-0.1, 0.1, interchanges) * spacing
    b = TownBuilder()
    links = motorway(b, "m", centre, [spacing * (k + 1) + jitter[k] for k in range(interchanges)], spec)
    street = StreetStyle(lanes=1, lane_width_m=3.3, sidewalk_width_m=2.0, speed_mps=13.89)
    for side in ("right_ground", "left_ground"):
        ends = [getattr(link, side) for link in links]
        for a, c in itertools.pairwise(ends):
            b.street(a, c, street, wiggle(b.point(a), b.point(c), rng, 25.0), parking=True)
    _turning_loop(b, "mfstart", "mbend", spec.lanes, centre[0] - centre[1], at_start=True)
    _turning_loop(b, "mfend", "mbstart", spec.lanes, centre[-1] - centre[-2], at_start=False)
    return b.network()


def _turning_loop(
    b: TownBuilder, start: str, end: str, lanes: int, ahead_xy: npt.NDArray[np.float64], at_start: bool
) -> None:
    """A loop road from the end of one carriageway to the start of the other, as wide as
    the carriageways (no lane has to merge before it). It leaves and rejoins straight
    ahead, so that netconvert keeps every lane, and has no bend tighter than
    ``LOOP_RADIUS_M``."""
    a, c = (end, start) if at_start else (start, end)
    p_from, p_to = np.array(b.point(a)), np.array(b.point(c))
    mid = (p_from[:2] + p_to[:2]) / 2.0
    across = (p_from[:2] - p_to[:2]) / max(float(np.linalg.norm(p_from[:2] - p_to[:2])), 1e-9)
    ahead = ahead_xy / float(np.linalg.norm(ahead_xy))
    uv = balloon_loop(float(np.linalg.norm(p_from[:2] - p_to[:2])), LOOP_RADIUS_M)
    points = [(float(x), float(y), 0.0) for x, y in mid + uv[:, :1] * ahead + uv[:, 1:] * across]
    # In pieces: netconvert cuts every lane of an edge at the same offsets, which mangles
    # the inner lanes of a single edge that turns right round.
    cuts = np.linspace(0, len(points) - 1, LOOP_PIECES + 1).round().astype(int)
    names = [a, *(b.node(f"{a}loop{k}", points[i][:2]) for k, i in enumerate(cuts[1:-1], 1)), c]
    for k in range(LOOP_PIECES):
        b.carriageway(names[k], names[k + 1], lanes, 14.0, points[cuts[k] + 1 : cuts[k + 1]])


def balloon_loop(gap_m: float, radius_m: float, step_m: float = 4.0) -> npt.NDArray[np.float64]:
    """A balloon loop in a local frame (u ahead, v across): from ``(0, gap/2)`` heading +u,
    a bend away from the other end, a wide turn back round, and the mirror bend into
    ``(0, -gap/2)`` heading -u; every bend has ``radius_m``. Returns ``(K, 2)`` points."""
    r, h = radius_m, gap_m / 2.0 + radius_m
    c = float(np.sqrt((2 * r) ** 2 - h**2))  # the big turn's centre (c, 0) touches both small bends
    turn_in = np.arctan2(-h, c)  # where the first bend meets the big turn, seen from its centre
    first = _arc_points((0.0, h), r, -np.pi / 2, turn_in, step_m)
    big = _arc_points((c, 0.0), r, np.pi + turn_in, -np.pi - turn_in, step_m)  # clockwise round the far side
    last = first[::-1] * np.array([1.0, -1.0])
    return np.vstack([first, big[1:-1], last])


def _arc_points(
    centre: tuple[float, float], radius_m: float, a0: float, a1: float, step_m: float
) -> npt.NDArray[np.float64]:
    n = max(2, int(abs(a1 - a0) * radius_m / step_m) + 1)
    angles = np.linspace(a0, a1, n)
    return np.column_stack([centre[0] + radius_m * np.cos(angles), centre[1] + radius_m * np.sin(angles)])
