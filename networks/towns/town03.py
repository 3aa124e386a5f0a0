"""town03: an urban grid of 4-way and 3-way signalised junctions around a multi-lane
roundabout. A few grid links are left out (by seed) to make T-junctions."""

from __future__ import annotations

import numpy as np

from networks.plain import PlainEdge, PlainNetwork
from networks.towns.layout import Point, StreetStyle, TownBuilder, arc

ARMS = ((1, 0), (0, 1), (-1, 0), (0, -1))  # east, north, west, south


def town03(seed: int, size: int = 5, spacing_m: float = 150.0, roundabout_radius_m: float = 32.0) -> PlainNetwork:
    rng = np.random.default_rng(seed)
    centre = (size // 2, size // 2)
    jitter = rng.uniform(-0.12, 0.12, (size, size, 2)) * spacing_m
    jitter[centre] = 0.0
    b = TownBuilder()
    for i in range(size):
        for j in range(size):
            if (i, j) == centre:
                continue
            corner = i in (0, size - 1) and j in (0, size - 1)
            xy = (i * spacing_m + jitter[i, j, 0], j * spacing_m + jitter[i, j, 1])
            b.node(f"g{i}_{j}", xy, 0.0, "priority" if corner else "traffic_light")
    main = StreetStyle(lanes=2, lane_width_m=3.2, sidewalk_width_m=3.0)
    side = StreetStyle(lanes=1, lane_width_m=3.3, sidewalk_width_m=2.5, speed_mps=11.11)
    links = _grid_links(size, centre, rng)
    for (i, j), (k, m) in links:
        style = main if (centre[0] in (i, k) and i == k) or (centre[1] in (j, m) and j == m) else side
        b.street(f"g{i}_{j}", f"g{k}_{m}", style, parking=style is side)
    _roundabout(b, centre, spacing_m, roundabout_radius_m, main)
    return b.network()


def _grid_links(size: int, centre: tuple[int, int], rng: np.random.Generator) -> list[tuple[tuple[int, int], ...]]:
    """Grid links not touching the roundabout, minus a few inner ones (T-junctions)."""
    links = []
    for i in range(size):
        for j in range(size):
            for di, dj in ((1, 0), (0, 1)):
                a, c = (i, j), (i + di, j + dj)
                if c[0] < size and c[1] < size and centre not in (a, c):
                    links.append((a, c))
    inner = [k for k, (a, c) in enumerate(links) if all(0 < v < size - 1 for v in (*a, *c))]
    drop = set(rng.choice(inner, size=min(2, len(inner)), replace=False).tolist()) if inner else set()
    return [link for k, link in enumerate(links) if k not in drop]


def _roundabout(b: TownBuilder, centre: tuple[int, int], spacing_m: float, radius_m: float, arm: StreetStyle) -> None:
    """A two-lane roundabout in place of the centre junction, one arm per neighbour."""
    cx, cy = centre[0] * spacing_m, centre[1] * spacing_m
    ring = StreetStyle(lanes=2, lane_width_m=3.5, sidewalk_width_m=2.5, speed_mps=8.33)
    for k, (dx, dy) in enumerate(ARMS):
        b.node(f"r{k}", (cx + dx * radius_m, cy + dy * radius_m), 0.0, "priority")
    for k in range(4):
        a0 = k * np.pi / 2
        via = arc(cx, cy, radius_m, a0, a0 + np.pi / 2, 4.0)
        b.edges.append(_ring_edge(b, f"r{k}", f"r{(k + 1) % 4}", ring, via))
    for k, (dx, dy) in enumerate(ARMS):
        b.street(f"r{k}", f"g{centre[0] + dx}_{centre[1] + dy}", arm)


def _ring_edge(b: TownBuilder, a: str, c: str, style: StreetStyle, via: list[Point]) -> PlainEdge:
    shape = (b.point(a), *via, b.point(c))
    return PlainEdge(f"{a}-{c}", a, c, style.lanes, style.speed_mps, style.sidewalk_width_m, style.lane_width_m,
                     shape, spread="center")  # fmt: skip
