"""town10: a dense downtown of short blocks, one-way and two-way streets, signals everywhere.

Avenues along the town's edges and through its middle are two-way; the streets between
them are one-way, alternating in direction so that every block can be driven around.
"""

from __future__ import annotations

import numpy as np

from networks.plain import PlainNetwork
from networks.towns.layout import StreetStyle, TownBuilder


def town10(seed: int, blocks: int = 6) -> PlainNetwork:
    rng = np.random.default_rng(seed)
    xs = np.concatenate([[0.0], np.cumsum(rng.uniform(75.0, 100.0, blocks))])
    ys = np.concatenate([[0.0], np.cumsum(rng.uniform(70.0, 95.0, blocks))])
    b = TownBuilder()
    for i, x in enumerate(xs):
        for j, y in enumerate(ys):
            corner = i in (0, blocks) and j in (0, blocks)
            b.node(f"d{i}_{j}", (float(x), float(y)), 0.0, "priority" if corner else "traffic_light")
    avenue = StreetStyle(lanes=2, lane_width_m=3.1, sidewalk_width_m=3.5, speed_mps=13.89)
    street = StreetStyle(lanes=1, lane_width_m=3.2, sidewalk_width_m=3.0, speed_mps=11.11)
    one_way = StreetStyle(lanes=2, lane_width_m=3.0, sidewalk_width_m=3.0, speed_mps=11.11)
    two_way_lines = {0, blocks // 2, blocks}
    for axis in ("x", "y"):
        for line in range(blocks + 1):
            for k in range(blocks):
                a, c = (f"d{k}_{line}", f"d{k + 1}_{line}") if axis == "x" else (f"d{line}_{k}", f"d{line}_{k + 1}")
                if line in two_way_lines:
                    b.street(a, c, avenue if line == blocks // 2 else street, parking=line != blocks // 2)
                elif line % 2:
                    b.one_way(a, c, one_way, parking=True)
                else:
                    b.one_way(c, a, one_way, parking=True)
    return b.network()
