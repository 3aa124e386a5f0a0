"""Street trees: a trunk (TRUNK) that forks into limbs (TRUNK) reaching into a crown (VEGETATION).

Three kinds stand along the streets: round broadleaf trees, tall narrow (columnar) ones and, where
no building stands close, conifers. A broadleaf or columnar crown is the outline of a cluster of
overlapping leaf clumps (a core and several lobes of varied size pushed out from it): each vertex
of a band-and-sides closed surface lies where the ray from the crown's centre leaves the last clump,
so the outline has lobes and dents between them, no two trees alike. A conifer's crown is a stack
of tiers, each wide at its hanging foot and narrow at its top, with ragged edges. Every closed
surface is star-shaped about its centre (it never crosses itself), so the solids' ray parity
(:mod:`sensors.solids`) fills crowns, trunks and limbs; the limbs' ends lie well inside the crown.

Each tree's kind, size and shape come from its own generator, seeded by the world's seed and the
tree's position to the centimetre: the same network and seed give the same trees.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from networks.classes import SemanticClass
from networks.mesh import ClassedMesh, merge

KINDS = ("broadleaf", "columnar", "conifer")
CROWN_RINGS, CROWN_SEGMENTS = 8, 14  # bands and sides of a broadleaf or columnar crown
CONIFER_TIERS, CONIFER_SEGMENTS = 4, 12
TRUNK_SIDES = 6
LIMB_SIDES = 4


def tree_rng(x_m: float, y_m: float, seed: int) -> np.random.Generator:
    """The generator of the tree standing at ``(x_m, y_m)``: its position to the centimetre and
    the world's seed."""
    return np.random.default_rng([seed & 0xFFFFFFFF, round(x_m * 100.0) & 0xFFFFFFFF, round(y_m * 100.0) & 0xFFFFFFFF])


def tree_kind(x_m: float, y_m: float, seed: int, conifer_fits: bool = True) -> str:
    """The kind of the tree at ``(x_m, y_m)``: broadleaf (about 6 in 10), columnar (about 1 in 4)
    or conifer (the rest, where ``conifer_fits``; else broadleaf)."""
    pick = float(tree_rng(x_m, y_m, seed).random())
    if pick < 0.6 or (pick >= 0.85 and not conifer_fits):
        return "broadleaf"
    return "columnar" if pick < 0.85 else "conifer"


def street_tree(
    x_m: float, y_m: float, z0_m: float, seed: int, conifer_fits: bool = True, kind: str | None = None
) -> ClassedMesh:
    """One street tree with its foot at ``(x_m, y_m, z0_m)``, of its :func:`tree_kind` (or ``kind``,
    one of :data:`KINDS`)."""
    kind = tree_kind(x_m, y_m, seed, conifer_fits) if kind is None else kind
    rng = tree_rng(x_m, y_m, seed)
    rng.random()  # the draw that chose the kind
    if kind == "conifer":
        return _conifer(rng, x_m, y_m, z0_m)
    return _leafy(rng, x_m, y_m, z0_m, columnar=kind == "columnar")


def ring_mesh(
    rings: npt.NDArray[np.float64], bottom: npt.NDArray[np.float64], top: npt.NDArray[np.float64],
    cls: SemanticClass,
) -> ClassedMesh:  # fmt: skip
    """A closed surface of ``rings: (R, S, 3)`` (from the bottom up, each ring's points counter-
    clockwise seen from above) between a ``bottom`` and a ``top`` pole, facing outwards."""
    n_ring, segments = rings.shape[0], rings.shape[1]
    b, t = n_ring * segments, n_ring * segments + 1
    j = np.arange(segments)
    k = (j + 1) % segments
    tris = [np.stack([np.full(segments, b), k, j], axis=1)]
    for i in range(n_ring - 1):
        lo0, lo1, hi0, hi1 = i * segments + j, i * segments + k, (i + 1) * segments + j, (i + 1) * segments + k
        tris += [np.stack([lo0, lo1, hi1], axis=1), np.stack([lo0, hi1, hi0], axis=1)]
    top_ring = (n_ring - 1) * segments
    tris.append(np.stack([np.full(segments, t), top_ring + j, top_ring + k], axis=1))
    triangles = np.concatenate(tris)
    vertices = np.vstack([rings.reshape(-1, 3), bottom, top])
    return ClassedMesh(vertices, triangles, np.full(len(triangles), cls, np.uint8))


def limb(
    foot: tuple[float, float, float], tip: tuple[float, float, float], radius_m: float, sides: int, turn_rad: float,
    cls: SemanticClass = SemanticClass.TRUNK,
) -> ClassedMesh:  # fmt: skip
    """A straight piece of trunk or limb from ``foot`` up to ``tip``: the regular polygon of
    ``sides`` corners ``radius_m`` from its axis (turned by ``turn_rad``), level at both ends
    (its sides lean with the limb), closed at the top, open at the foot (it stands on the
    trunk or the ground)."""
    angle = turn_rad + np.arange(sides) * (2.0 * math.pi / sides)
    ring = np.stack([np.cos(angle), np.sin(angle), np.zeros(sides)], axis=1) * radius_m
    low, high = ring + np.asarray(foot), ring + np.asarray(tip)
    j = np.arange(sides)
    k = (j + 1) % sides
    walls = np.concatenate([np.stack([j, k, sides + k], axis=1), np.stack([j, sides + k, sides + j], axis=1)])
    cap = np.stack([np.full(sides - 2, sides), sides + j[1:-1], sides + j[2:]], axis=1)
    triangles = np.concatenate([walls, cap])
    return ClassedMesh(np.vstack([low, high]), triangles, np.full(len(triangles), cls, np.uint8))


def _directions(rings: int, segments: int, turn_rad: float) -> npt.NDArray[np.float64]:
    """``(rings - 1, segments, 3)`` unit directions on the bands between the poles (bottom up)."""
    polar = np.linspace(0.0, math.pi, rings + 1)[1:-1]
    azimuth = turn_rad + np.linspace(0.0, 2.0 * math.pi, segments, endpoint=False)
    p, a = np.meshgrid(polar, azimuth, indexing="ij")
    a = a + (np.arange(rings - 1)[:, None] % 2) * (math.pi / segments)  # every other band turned half a side
    return np.stack([np.sin(p) * np.cos(a), np.sin(p) * np.sin(a), -np.cos(p)], axis=-1)


def clump_radius(
    directions: npt.NDArray[np.float64], centres: npt.NDArray[np.float64], radii: npt.NDArray[np.float64]
) -> npt.NDArray[np.float64]:
    """How far the ray from the origin along each unit direction ``(..., 3)`` runs before it
    leaves the last of the spheres ``centres: (K, 3)``, ``radii: (K,)`` it meets (0 if none)."""
    along = directions @ centres.T  # (..., K)
    disc = along**2 - (centres**2).sum(axis=1) + radii**2
    far = np.where(disc >= 0.0, along + np.sqrt(np.maximum(disc, 0.0)), 0.0)
    return np.asarray(far.max(axis=-1), np.float64)


def _clumps(rng: np.random.Generator, lobes: int) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """A crown's leaf clumps in a unit crown (about 1 across its middle): a core holding the centre
    and ``lobes`` clumps pushed out from it, more upwards and sideways than down."""
    z = rng.uniform(-0.45, 0.9, lobes)
    a = rng.uniform(0.0, 2.0 * math.pi, lobes)
    side = np.sqrt(1.0 - z**2)
    out = np.stack([side * np.cos(a), side * np.sin(a), z], axis=1)
    radius = rng.uniform(0.3, 0.5, lobes)
    reach = rng.uniform(0.85, 1.05, lobes)  # how far each lobe's outside lies from the centre
    centres = np.vstack([[0.0, 0.0, -0.08], out * (reach - radius)[:, None]])
    return centres, np.concatenate([[rng.uniform(0.5, 0.58)], radius])


def _leafy(rng: np.random.Generator, x: float, y: float, z0: float, columnar: bool) -> ClassedMesh:
    """A broadleaf (round, 3-6 m wide) or columnar (1.6-2.6 m wide, 2-3 times as tall) tree."""
    if columnar:
        half_w = float(rng.uniform(0.8, 1.3))
        half_h = half_w * float(rng.uniform(2.0, 3.0))
        lobes = int(rng.integers(8, 12))
    else:
        half_w = float(rng.uniform(1.5, 3.0))
        half_h = half_w * float(rng.uniform(0.75, 1.05))
        lobes = int(rng.integers(6, 10))
    stretch = np.array([half_w * rng.uniform(0.9, 1.1), half_w * rng.uniform(0.9, 1.1), half_h])
    centres, radii = _clumps(rng, lobes)
    turn = float(rng.uniform(0.0, 2.0 * math.pi))
    dirs = _directions(CROWN_RINGS, CROWN_SEGMENTS, turn)
    reach = clump_radius(dirs, centres, radii) * rng.uniform(0.93, 1.04, dirs.shape[:2])
    bottom_dir, top_dir = np.array([[0.0, 0.0, -1.0]]), np.array([[0.0, 0.0, 1.0]])
    low, high = clump_radius(bottom_dir, centres, radii)[0], clump_radius(top_dir, centres, radii)[0]
    trunk_r = float(rng.uniform(0.13, 0.2)) * (0.8 if columnar else 1.0)
    clear = float(rng.uniform(1.8, 2.8))  # the crown's lowest point above the ground
    centre = np.array([x, y, z0 + clear + low * half_h])
    crown = ring_mesh(
        centre + dirs * reach[..., None] * stretch,
        centre - np.array([0.0, 0.0, low * half_h]),
        centre + np.array([0.0, 0.0, high * half_h]),
        SemanticClass.VEGETATION,
    )
    fork = z0 + clear - float(rng.uniform(0.3, 0.7))
    sides_turn = float(rng.uniform(0.0, math.pi))
    parts = [crown, limb((x, y, z0), (x, y, fork), trunk_r, TRUNK_SIDES, sides_turn)]
    limbs = int(rng.integers(2, 4))
    first = float(rng.uniform(0.0, 2.0 * math.pi))
    for n in range(limbs):
        a = first + n * 2.0 * math.pi / limbs + float(rng.uniform(-0.4, 0.4))
        out_m = float(rng.uniform(0.2, 0.3)) * half_w * (0.6 if columnar else 1.0)
        foot = (x + 0.3 * trunk_r * math.cos(a), y + 0.3 * trunk_r * math.sin(a), fork)
        tip = (x + out_m * math.cos(a), y + out_m * math.sin(a), float(centre[2]) - 0.15 * half_h)
        parts.append(limb(foot, tip, 0.5 * trunk_r, LIMB_SIDES, a))
    return merge(parts)


def _conifer(rng: np.random.Generator, x: float, y: float, z0: float) -> ClassedMesh:
    """A conifer 5.5-9 m tall, limbed up to 1.8-2.4 m: tiers of drooping branches, each wide at
    its foot and narrow at its top, smaller upwards, with ragged edges."""
    base = z0 + float(rng.uniform(1.8, 2.4))
    tall = float(rng.uniform(3.5, 6.5))
    wide = float(rng.uniform(1.2, 1.8))
    tiers = CONIFER_TIERS
    step = tall / (tiers + 0.6)
    turn = float(rng.uniform(0.0, 2.0 * math.pi))
    azimuth = turn + np.linspace(0.0, 2.0 * math.pi, CONIFER_SEGMENTS, endpoint=False)
    around = np.stack([np.cos(azimuth), np.sin(azimuth), np.zeros_like(azimuth)], axis=1)
    rings: list[npt.NDArray[np.float64]] = []
    collar_z = -math.inf
    for i in range(tiers):
        foot_z = base + i * step
        taper = 1.0 - i / (tiers + 0.6)
        skirt = wide * taper * rng.uniform(0.8, 1.1, CONIFER_SEGMENTS)
        collar = wide * taper * rng.uniform(0.3, 0.42, CONIFER_SEGMENTS)
        droop = rng.uniform(0.0, 0.25, CONIFER_SEGMENTS) * step
        a = around * skirt[:, None] + np.array([x, y, 0.0])
        a[:, 2] = np.maximum(foot_z - droop, collar_z + 0.02)  # a tier's foot over the top of the one below
        collar_z = foot_z + step * float(rng.uniform(0.85, 0.95))
        b = around * collar[:, None] + np.array([x, y, 0.0])
        b[:, 2] = collar_z
        rings += [a, b]
    crown = ring_mesh(
        np.asarray(rings), np.array([x, y, base - 0.05 * step]), np.array([x, y, base + tall]), SemanticClass.VEGETATION
    )
    trunk = limb((x, y, z0), (x, y, base + 0.5 * step), float(rng.uniform(0.12, 0.18)), TRUNK_SIDES, turn)
    return merge([crown, trunk])
