"""Building blocks shared by the town generators: a network builder and curve helpers.

Points are ``(x, y)`` or ``(x, y, z)`` metres in the town's plain-XML frame.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from networks.plain import MOTORWAY_DISALLOW, PlainEdge, PlainNetwork, PlainNode

Point = tuple[float, float, float]
URBAN_SPEED_MPS = 13.89


@dataclass(frozen=True, slots=True)
class StreetStyle:
    """Cross-section of a street: lanes per direction, widths, speed."""

    lanes: int = 1
    lane_width_m: float = 3.2
    sidewalk_width_m: float = 2.5
    speed_mps: float = URBAN_SPEED_MPS


@dataclass
class TownBuilder:
    """Collects nodes and edges while a generator lays out a town (mutable on purpose:
    it lives only inside one generator call)."""

    nodes: dict[str, PlainNode] = field(default_factory=dict)
    edges: list[PlainEdge] = field(default_factory=list)
    parking: list[str] = field(default_factory=list)

    def node(self, node_id: str, xy: tuple[float, float], z_m: float = 0.0, kind: str = "priority") -> str:
        self.nodes[node_id] = PlainNode(node_id, round(xy[0], 2), round(xy[1], 2), round(z_m, 2), kind)
        return node_id

    def point(self, node_id: str) -> Point:
        n = self.nodes[node_id]
        return (n.x_m, n.y_m, n.z_m)

    def street(self, a: str, b: str, style: StreetStyle, via: list[Point] | None = None, parking: bool = False) -> None:
        """A two-way street between nodes ``a`` and ``b`` through the points ``via``."""
        shape = self._shape(a, b, via)
        for src, dst, pts in ((a, b, shape), (b, a, tuple(reversed(shape)))):
            edge_id = f"{src}-{dst}"
            self.edges.append(
                PlainEdge(
                    edge_id, src, dst, style.lanes, style.speed_mps, style.sidewalk_width_m, style.lane_width_m, pts
                )
            )
            if parking:
                self.parking.append(edge_id)

    def one_way(
        self, a: str, b: str, style: StreetStyle, via: list[Point] | None = None, parking: bool = False
    ) -> None:
        """A one-way street from ``a`` to ``b`` with sidewalks on both sides."""
        self.edges.append(
            PlainEdge(f"{a}-{b}", a, b, style.lanes, style.speed_mps, style.sidewalk_width_m, style.lane_width_m,
                      self._shape(a, b, via), left_sidewalk=True, spread="center")
        )  # fmt: skip
        if parking:
            self.parking.append(f"{a}-{b}")

    def carriageway(self, a: str, b: str, lanes: int, speed_mps: float, via: list[Point] | None = None) -> None:
        """One motorway carriageway (or ramp) from ``a`` to ``b``: no sidewalk, no pedestrians."""
        self.edges.append(
            PlainEdge(f"{a}-{b}", a, b, lanes, speed_mps, 0.0, 3.5, self._shape(a, b, via), spread="center",
                      priority=10 if lanes > 1 else 5, disallow=MOTORWAY_DISALLOW)
        )  # fmt: skip

    def _shape(self, a: str, b: str, via: list[Point] | None) -> tuple[Point, ...]:
        if not via:
            return ()
        return (self.point(a), *((round(x, 2), round(y, 2), round(z, 2)) for x, y, z in via), self.point(b))

    def network(self, *options: str) -> PlainNetwork:
        return PlainNetwork(tuple(self.nodes.values()), tuple(self.edges), tuple(options), tuple(self.parking))


def bezier(p0: Point, p1: Point, p2: Point, p3: Point, n: int) -> list[Point]:
    """The ``n`` interior points of a cubic Bezier curve (end points excluded)."""
    t = np.linspace(0.0, 1.0, n + 2)[1:-1, None]
    pts = (1 - t) ** 3 * np.array(p0) + 3 * (1 - t) ** 2 * t * np.array(p1)
    pts += 3 * (1 - t) * t**2 * np.array(p2) + t**3 * np.array(p3)
    return [(float(x), float(y), float(z)) for x, y, z in pts]


def smooth_z(points: list[Point], z0_m: float, z1_m: float, t0: float = 0.0, t1: float = 1.0) -> list[Point]:
    """Give interior ``points`` a smooth-step height profile from ``z0_m`` to ``z1_m``,
    level before the fraction ``t0`` of the way and after ``t1``."""
    t = np.clip((np.linspace(0.0, 1.0, len(points) + 2)[1:-1] - t0) / (t1 - t0), 0.0, 1.0)
    z = z0_m + (z1_m - z0_m) * (3 * t**2 - 2 * t**3)
    return [(x, y, float(zz)) for (x, y, _), zz in zip(points, z, strict=True)]


def arc(cx: float, cy: float, radius_m: float, a0_rad: float, a1_rad: float, step_m: float = 5.0) -> list[Point]:
    """Interior points of a circular arc from angle ``a0`` to ``a1`` (counter-clockwise if a1 > a0)."""
    n = max(1, int(abs(a1_rad - a0_rad) * radius_m / step_m))
    angles = np.linspace(a0_rad, a1_rad, n + 2)[1:-1]
    return [(cx + radius_m * float(np.cos(a)), cy + radius_m * float(np.sin(a)), 0.0) for a in angles]


def wiggle(p0: Point, p1: Point, rng: np.random.Generator, amplitude_m: float, step_m: float = 6.0) -> list[Point]:
    """Interior points of a gently curved road from ``p0`` to ``p1`` (a random sine bend)."""
    a, b = np.array(p0[:2]), np.array(p1[:2])
    length = float(np.linalg.norm(b - a))
    n = max(2, int(length / step_m))
    t = np.linspace(0.0, 1.0, n + 2)[1:-1]
    normal = np.array([-(b - a)[1], (b - a)[0]]) / max(length, 1e-9)
    bends = float(rng.integers(1, 3))
    offset = amplitude_m * float(rng.uniform(0.5, 1.0)) * np.sin(np.pi * bends * t) * rng.choice([-1.0, 1.0])
    xy = a + np.outer(t, b - a) + np.outer(offset, normal)
    z = p0[2] + (p1[2] - p0[2]) * t
    return [(float(x), float(y), float(zz)) for (x, y), zz in zip(xy, z, strict=True)]


def polyline_frame(centre: npt.NDArray[np.float64], s_m: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Point, unit direction and unit left normal of a ``(K, 2)`` polyline at arc length ``s_m``."""
    seg = np.diff(centre, axis=0)
    seg_len = np.linalg.norm(seg, axis=1)
    cum = np.concatenate([[0.0], np.cumsum(seg_len)])
    i = int(np.clip(np.searchsorted(cum, s_m, side="right") - 1, 0, len(seg) - 1))
    d = seg[i] / seg_len[i]
    p = centre[i] + d * (s_m - cum[i])
    return p, d, np.array([-d[1], d[0]])


def polyline_between(centre: npt.NDArray[np.float64], s0_m: float, s1_m: float, offset_m: float) -> list[Point]:
    """Interior points of the polyline between arc lengths ``s0 < s1``, offset to the left."""
    seg_len = np.linalg.norm(np.diff(centre, axis=0), axis=1)
    cum = np.concatenate([[0.0], np.cumsum(seg_len)])
    out = []
    for s in cum[(cum > s0_m + 1.0) & (cum < s1_m - 1.0)]:
        p, _, n = polyline_frame(centre, float(s))
        q = p + n * offset_m
        out.append((float(q[0]), float(q[1]), 0.0))
    return out
