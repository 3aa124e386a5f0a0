"""town05: a grid town of wide avenues (2-3 lanes per direction) and signalised
intersections, inside a ring motorway whose interchanges bridge over it."""

from __future__ import annotations

import numpy as np

from networks.plain import PlainNetwork
from networks.towns.highway import MotorwaySpec, motorway
from networks.towns.layout import StreetStyle, TownBuilder, arc


def town05(seed: int, size: int = 5, spacing_m: float = 170.0) -> PlainNetwork:
    rng = np.random.default_rng(seed)
    b = TownBuilder()
    for i in range(size):
        for j in range(size):
            corner = i in (0, size - 1) and j in (0, size - 1)
            b.node(f"g{i}_{j}", (i * spacing_m, j * spacing_m), 0.0, "priority" if corner else "traffic_light")
    wide = int(rng.integers(2, 4))
    avenue = StreetStyle(lanes=wide, lane_width_m=3.3, sidewalk_width_m=3.5, speed_mps=13.89)
    street = StreetStyle(lanes=2, lane_width_m=3.2, sidewalk_width_m=3.0, speed_mps=13.89)
    avenues = {int(v) for v in rng.choice(range(1, size - 1), size=2, replace=False)}
    for i in range(size):
        for j in range(size):
            if i + 1 < size:
                b.street(f"g{i}_{j}", f"g{i + 1}_{j}", avenue if j in avenues else street, parking=j not in avenues)
            if j + 1 < size:
                b.street(f"g{i}_{j}", f"g{i}_{j + 1}", avenue if i in avenues else street, parking=i not in avenues)
    _ring_motorway(b, size, spacing_m, sorted(avenues)[0])
    return b.network()


def _ring_motorway(b: TownBuilder, size: int, spacing_m: float, avenue: int) -> None:
    """A counter-clockwise ring motorway around the grid with one interchange per side on
    the line of ``avenue``; each crossing road's inner end joins the grid's edge node."""
    spec = MotorwaySpec(lanes=2, speed_mps=25.0, bridge_offset_m=45.0, approach_m=130.0, ramp_m=200.0)
    gap = spec.bridge_offset_m + spec.approach_m + 80.0
    lo, hi, r = -gap, (size - 1) * spacing_m + gap, 110.0
    pts: list[tuple[float, float]] = []
    for cx, cy, a0 in ((hi - r, lo + r, -np.pi / 2), (hi - r, hi - r, 0.0), (lo + r, hi - r, np.pi / 2),
                       (lo + r, lo + r, np.pi)):  # fmt: skip
        pts.append((cx + r * np.cos(a0), cy + r * np.sin(a0)))
        pts += [(x, y) for x, y, _ in arc(cx, cy, r, a0, a0 + np.pi / 2, 6.0)]
        pts.append((cx + r * np.cos(a0 + np.pi / 2), cy + r * np.sin(a0 + np.pi / 2)))
    centre = np.array([*pts, pts[0]])
    side, quarter = (hi - lo) - 2 * r, np.pi * r / 2
    v = avenue * spacing_m
    s_marks = [  # east, north, west and south sides, in the ring's order
        quarter + (v - (lo + r)),
        2 * quarter + side + ((hi - r) - v),
        3 * quarter + 2 * side + ((hi - r) - v),
        4 * quarter + 3 * side + (v - (lo + r)),
    ]
    links = motorway(b, "m", centre, s_marks, spec, closed=True)
    grid_nodes = [f"g{size - 1}_{avenue}", f"g{avenue}_{size - 1}", f"g0_{avenue}", f"g{avenue}_0"]
    link_road = StreetStyle(lanes=1, lane_width_m=3.3, sidewalk_width_m=2.0, speed_mps=13.89)
    for link, node in zip(links, grid_nodes, strict=True):
        b.street(link.left_ground, node, link_road)  # counter-clockwise: the left side is inside
