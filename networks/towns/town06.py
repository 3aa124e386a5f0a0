"""town06: a long motorway (3-4 lanes per direction) with entrance and exit ramps.

Diamond interchanges carry crossing roads over the motorway on bridges (the
overpass); local streets with sidewalks link the crossing roads on either side, and
small loops at both ends let traffic turn back.
"""

from __future__ import annotations

import itertools

import numpy as np

from networks.plain import PlainNetwork
from networks.towns.highway import MotorwaySpec, motorway
from networks.towns.layout import StreetStyle, TownBuilder, arc, wiggle


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
    _turning_loop(b, "mfstart", "mbend", spec.carriageway_offset_m, at_start=True)
    _turning_loop(b, "mfend", "mbstart", spec.carriageway_offset_m, at_start=False)
    return b.network()


def _turning_loop(b: TownBuilder, start: str, end: str, offset_m: float, at_start: bool) -> None:
    """A one-lane loop road from the end of one carriageway to the start of the other."""
    p_from, p_to = b.point(end if at_start else start), b.point(start if at_start else end)
    cx, cy = (p_from[0] + p_to[0]) / 2.0, (p_from[1] + p_to[1]) / 2.0
    radius = max(offset_m, float(np.hypot(p_from[0] - cx, p_from[1] - cy)))
    # At the start the loop bulges to -x (from the backward carriageway's end), else to +x.
    a0, a1 = (np.pi / 2, 3 * np.pi / 2) if at_start else (-np.pi / 2, np.pi / 2)
    via = arc(cx, cy, radius, a0, a1, 4.0)
    b.carriageway(end if at_start else start, start if at_start else end, 1, 14.0, via)
