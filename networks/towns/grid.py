"""Grid towns: blocks of streets meeting at signalised junctions."""

from __future__ import annotations

from networks.plain import PlainEdge, PlainNetwork, PlainNode


def grid_network(
    nx: int,
    ny: int,
    spacing_m: float,
    lanes: int = 1,
    speed_mps: float = 13.89,
    signalised: bool = True,
) -> PlainNetwork:
    """An ``nx`` by ``ny`` grid of two-way streets with sidewalks on both sides."""
    nodes = []
    for i in range(nx):
        for j in range(ny):
            inner = 0 < i < nx - 1 or 0 < j < ny - 1
            kind = "traffic_light" if signalised and inner else "priority"
            nodes.append(PlainNode(f"n{i}_{j}", i * spacing_m, j * spacing_m, 0.0, kind))
    edges = []
    for i in range(nx):
        for j in range(ny):
            for di, dj in ((1, 0), (0, 1)):
                a, b = (i, j), (i + di, j + dj)
                if b[0] >= nx or b[1] >= ny:
                    continue
                na, nb = f"n{a[0]}_{a[1]}", f"n{b[0]}_{b[1]}"
                edges.append(PlainEdge(f"{na}-{nb}", na, nb, lanes, speed_mps))
                edges.append(PlainEdge(f"{nb}-{na}", nb, na, lanes, speed_mps))
    return PlainNetwork(tuple(nodes), tuple(edges))


def skeleton_town(seed: int) -> PlainNetwork:
    """3x3 grid of two-lane roads (one lane each way) with sidewalks, 140 m blocks."""
    del seed  # the skeleton town has no random parts
    return grid_network(3, 3, 140.0, lanes=1)
