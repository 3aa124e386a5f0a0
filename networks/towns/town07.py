"""town07: a village of curved, narrow two-lane roads meeting at T-junctions.

A winding main road and a back road run side by side, joined by curved lanes whose
ends form T-junctions; a few dead-end lanes branch off outwards.
"""

from __future__ import annotations

import numpy as np

from networks.plain import PlainNetwork
from networks.towns.layout import StreetStyle, TownBuilder, wiggle


def town07(seed: int, length_m: float = 900.0, links: int = 4) -> PlainNetwork:
    rng = np.random.default_rng(seed)
    road = StreetStyle(lanes=1, lane_width_m=3.0, sidewalk_width_m=1.8, speed_mps=11.11)
    lane = StreetStyle(lanes=1, lane_width_m=2.8, sidewalk_width_m=1.5, speed_mps=8.33)
    gap = float(rng.uniform(200.0, 260.0))
    b = TownBuilder()
    xs = np.linspace(0.0, length_m, 2 * links + 1)
    for row, y0 in (("a", 0.0), ("b", gap)):
        shift = 0.0 if row == "a" else (xs[1] - xs[0])  # offset so the links make T-junctions
        for k, x in enumerate(xs):
            xk = min(float(x) + shift * (0 < k < len(xs) - 1), length_m)
            b.node(f"{row}{k}", (xk, y0 + float(rng.uniform(-25.0, 25.0))))
        for k in range(len(xs) - 1):
            a, c = f"{row}{k}", f"{row}{k + 1}"
            b.street(a, c, road, wiggle(b.point(a), b.point(c), rng, 12.0), parking=True)
    for k in range(1, 2 * links - 1, 2):
        a, c = f"a{k}", f"b{k + 1}"
        b.street(a, c, lane, wiggle(b.point(a), b.point(c), rng, 30.0))
    b.street("a0", "b0", road, wiggle(b.point("a0"), b.point("b0"), rng, 30.0))
    last = 2 * links
    b.street(f"a{last}", f"b{last}", road, wiggle(b.point(f"a{last}"), b.point(f"b{last}"), rng, 30.0))
    for k in range(2, 2 * links, 2):
        _dead_end(b, f"a{k}", -1.0, lane, rng)
        _dead_end(b, f"b{k - 1}", 1.0, lane, rng)
    return b.network()


def _dead_end(b: TownBuilder, start: str, side: float, style: StreetStyle, rng: np.random.Generator) -> None:
    """A short curved lane from ``start`` away from the village (``side``: -1 south, +1 north)."""
    x, y, _ = b.point(start)
    end = b.node(f"{start}e", (x + float(rng.uniform(-60.0, 60.0)), y + side * float(rng.uniform(110.0, 170.0))))
    b.street(start, end, style, wiggle(b.point(start), b.point(end), rng, 20.0))
