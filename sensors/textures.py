"""Procedural surface textures: albedo from where a ray hits, no image files.

Every function takes hit points in the map frame (metres) and returns a per-point factor or
colour, deterministic in the point (the same wall looks the same from every frame). Asphalt
has grain and worn patches, paving its joints, kerbs their stones, facades floors, windows and
doors in a style per wall, grass its patches, dry spots and blades' grain, canopies their mottling.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt
from numba import njit

F32 = npt.NDArray[np.float32]


_STEP_X, _STEP_Y, _MIX = np.uint32(374761393), np.uint32(668265263), np.uint32(1274126177)


def _lattice(ix: npt.NDArray[np.integer], iy: npt.NDArray[np.integer], seed: int) -> npt.NDArray[np.uint32]:
    """The hash's first step, ``ix * 374761393 + iy * 668265263 + seed * 2147483647`` modulo 2**32."""
    s = np.uint32((seed * 2147483647) & 0xFFFFFFFF)
    return ix.astype(np.uint32) * _STEP_X + iy.astype(np.uint32) * _STEP_Y + s


def _mixed01(h: npt.NDArray[np.uint32]) -> F32:
    """The hash's mixing of a lattice value, as a float in [0, 1) (32-bit arithmetic wraps as
    the masks to 32 bits did)."""
    h = (h ^ (h >> np.uint32(13))) * _MIX
    h ^= h >> np.uint32(16)
    return (h & np.uint32(0xFFFFFF)).astype(np.float32) / np.float32(16777216.0)


def hash01(ix: npt.NDArray[np.int64], iy: npt.NDArray[np.int64], seed: int) -> F32:
    """A float in [0, 1) per integer lattice point, well mixed (an integer hash)."""
    return _mixed01(_lattice(ix, iy, seed))


_U32 = np.uint64(0xFFFFFFFF)
_U24 = np.uint64(0xFFFFFF)


@njit(cache=True, nogil=True, inline="always")
def _mixed_at(h: np.uint64, mix: np.uint64) -> np.float32:  # pragma: no cover - compiled
    h = ((h ^ (h >> np.uint64(13))) * mix) & _U32
    h ^= h >> np.uint64(16)
    return np.float32(h & _U24) / np.float32(16777216.0)


@njit(cache=True, nogil=True)
def _noise_at(x: float, y: float, seed32: np.uint64) -> np.float32:  # pragma: no cover - compiled
    """:func:`value_noise` at one point, in the arithmetic of its numpy form (32-bit hash steps
    done in 64 bits and masked; ``x``, ``y`` of the arrays' own float type)."""
    fx, fy = np.floor(x), np.floor(y)
    ix = np.uint64(np.uint32(np.int64(fx)))
    iy = np.uint64(np.uint32(np.int64(fy)))
    step_x, step_y, mix = np.uint64(374761393), np.uint64(668265263), np.uint64(1274126177)
    corner = (ix * step_x + iy * step_y + seed32) & _U32
    tx, ty = x - fx, y - fy
    tx = tx * tx * (np.float32(3.0) - np.float32(2.0) * tx)
    ty = ty * ty * (np.float32(3.0) - np.float32(2.0) * ty)
    a = _mixed_at(corner, mix)
    b = _mixed_at((corner + step_x) & _U32, mix)
    c = _mixed_at((corner + step_y) & _U32, mix)
    d = _mixed_at((corner + step_x + step_y) & _U32, mix)
    top = a + (b - a) * tx
    return np.float32(top + (c + (d - c) * tx - top) * ty)


@njit(cache=True, nogil=True)
def _value_noise(x: F32, y: F32, seed32: np.uint64) -> F32:  # pragma: no cover - compiled
    out = np.empty(x.shape[0], np.float32)
    for i in range(x.shape[0]):
        out[i] = _noise_at(x[i], y[i], seed32)
    return out


@njit(cache=True, nogil=True)
def _fbm(
    x: F32, y: F32, seeds32: npt.NDArray[np.uint64], f0: np.float32, norm: np.float32
) -> F32:  # pragma: no cover - compiled
    """Per point the octaves' sum in octave order, ``total / norm`` (an octave's pass over every
    point at a time: the loop over points is compiled to vector instructions)."""
    out = np.zeros(x.shape[0], np.float32)
    amp, f = 1.0, f0
    for o in range(seeds32.shape[0]):
        a, seed = np.float32(amp), seeds32[o]
        for i in range(x.shape[0]):
            out[i] += a * _noise_at(x[i] * f, y[i] * f, seed)
        amp *= 0.5
        f *= np.float32(2.0)
    for i in range(x.shape[0]):
        out[i] = out[i] / norm
    return out


def _seed32(seed: int) -> np.uint64:
    return np.uint64((seed * 2147483647) & 0xFFFFFFFF)


def _flat(x: npt.NDArray[np.floating], y: npt.NDArray[np.floating]) -> tuple[npt.NDArray[np.floating], ...]:
    """``x`` and ``y`` as 1-D arrays of one float type (numpy's promotion of the two)."""
    kind = np.result_type(x, y, np.float32)
    return np.ascontiguousarray(x, kind).ravel(), np.ascontiguousarray(y, kind).ravel()


def value_noise(x: F32, y: F32, seed: int) -> F32:
    """Smooth noise in [0, 1) with features one unit apart: per point, the hash of its lattice
    cell's four corners (:func:`hash01`) blended by smoothstep."""
    fx, fy = _flat(np.asarray(x), np.asarray(y))
    return _value_noise(fx, fy, _seed32(seed)).reshape(np.shape(x))


def fbm(x: F32, y: F32, seed: int, octaves: int = 3, scale: float = 1.0) -> F32:
    """Fractal noise in about [0, 1): octaves of :func:`value_noise`, each half the size."""
    fx, fy = _flat(np.asarray(x), np.asarray(y))
    norm = sum(0.5**o for o in range(octaves))
    seeds = np.array([_seed32(seed + o) for o in range(octaves)], np.uint64)
    return _fbm(fx, fy, seeds, np.float32(1.0 / scale), np.float32(norm)).reshape(np.shape(x))


def asphalt(p: F32) -> F32:
    """``(N,)`` brightness factor of asphalt: fine grain (:func:`value_noise` of the points 9 times
    as dense, seed 3), patches of wear and repair (:func:`fbm`, seed 5, 3 octaves, scale 7)."""
    seeds = np.array([_seed32(3), _seed32(5), _seed32(6), _seed32(7)], np.uint64)
    return _asphalt(np.ascontiguousarray(p, np.float32), seeds, np.float32(1.0 / 7.0))


@njit(cache=True, nogil=True)
def _asphalt(p: F32, seeds32: npt.NDArray[np.uint64], f0: np.float32) -> F32:  # pragma: no cover - compiled
    """:func:`asphalt` per point in its numpy form's float32 arithmetic: ``1 + 0.14 * (grain - 0.5)
    + 0.25 * (patches - 0.5)``, the grain's noise of seed ``seeds32[0]``, the patches' octaves of
    the others (the first at frequency ``f0``, each next twice it, weights 1, 1/2, 1/4 summed in
    order over 1.75)."""
    n = p.shape[0]
    x, y = np.empty(n, np.float32), np.empty(n, np.float32)
    for i in range(n):
        x[i], y[i] = p[i, 0], p[i, 1]
    half, nine = np.float32(0.5), np.float32(9.0)
    grain = np.empty(n, np.float32)
    for i in range(n):  # a pass over every point at a time: the loops are compiled to vector instructions
        grain[i] = _noise_at(x[i] * nine, y[i] * nine, seeds32[0])
    total = np.zeros(n, np.float32)
    a, f = np.float32(1.0), f0
    for o in range(3):
        seed = seeds32[1 + o]
        for i in range(n):
            total[i] += a * _noise_at(x[i] * f, y[i] * f, seed)
        a = a * half
        f = f * np.float32(2.0)
    out = np.empty(n, np.float32)
    for i in range(n):
        patches = total[i] / np.float32(1.75) - half
        out[i] = np.float32(1.0) + np.float32(0.14) * (grain[i] - half) + np.float32(0.25) * patches
    return out


def paving(p: F32, tile_m: float = 0.5) -> F32:
    """Brightness factor of paving slabs: joints and a shade per slab."""
    x, y = p[:, 0] / np.float32(tile_m), p[:, 1] / np.float32(tile_m)
    fx, fy = x - np.floor(x), y - np.floor(y)
    joint = (np.minimum(fx, 1 - fx) < 0.04) | (np.minimum(fy, 1 - fy) < 0.04)
    slab = hash01(np.floor(x).astype(np.int64), np.floor(y).astype(np.int64), 17)
    out = np.float32(0.9) + np.float32(0.2) * slab + np.float32(0.1) * (value_noise(p[:, 0] * 6, p[:, 1] * 6, 2) - 0.5)
    out[joint] *= np.float32(0.55)
    return np.asarray(out, np.float32)


def kerb(p: F32) -> F32:
    """Kerb stones one metre long."""
    s = p[:, 0] + p[:, 1]
    f = s - np.floor(s)
    out = np.float32(0.92) + np.float32(0.15) * hash01(np.floor(s).astype(np.int64), np.zeros(len(s), np.int64), 21)
    out[np.minimum(f, 1 - f) < 0.02] *= np.float32(0.5)
    return np.asarray(out, np.float32)


def greenery(p: F32, seed: int) -> F32:
    """Mottling of grass or leaves."""
    return np.asarray(np.float32(0.6) + np.float32(0.9) * fbm(p[:, 0], p[:, 1] + p[:, 2], seed, 3, 1.5), np.float32)


# Grass's colour (BGR factors on its class albedo): lush, worn-dry (straw) and bare (soil).
GRASS_LUSH_BGR = np.array([0.75, 0.82, 0.7], np.float32)
GRASS_DRY_BGR = np.array([1.35, 1.15, 1.35], np.float32)
GRASS_BARE_BGR = np.array([1.25, 0.88, 1.15], np.float32)


def grass(p: F32, seed: int) -> F32:
    """``(N, 3)`` colour factors of a grass verge at ground points: lush and dry patches a few
    metres across, smaller dry and bare spots, clumps a decimetre across and the blades' grain."""
    x, y = np.ascontiguousarray(p[:, 0], np.float32), np.ascontiguousarray(p[:, 1], np.float32)
    patches = fbm(x, y, seed, 3, 4.0)
    spots = fbm(x, y, seed + 5, 2, 0.7)
    clumps = value_noise(x * np.float32(9.0), y * np.float32(9.0), seed + 7)
    grain = value_noise(x * np.float32(33.0), y * np.float32(33.0), seed + 9)
    return _grass_mix(patches, spots, clumps, grain, GRASS_LUSH_BGR, GRASS_DRY_BGR, GRASS_BARE_BGR)


@njit(cache=True, nogil=True)
def _grass_mix(
    patches: F32, spots: F32, clumps: F32, grain: F32, lush_bgr: F32, dry_bgr: F32, bare_bgr: F32
) -> F32:  # pragma: no cover - compiled
    """:func:`grass`'s colour from its noises: lush where the patches' noise is low, dry where it
    is high, bare where the spots' is high, brighter and darker by clumps and grain."""
    out = np.empty((patches.shape[0], 3), np.float32)
    for i in range(patches.shape[0]):
        dry = min(max((patches[i] - np.float32(0.52)) * np.float32(4.0), np.float32(0.0)), np.float32(1.0))
        lush = min(max((np.float32(0.45) - patches[i]) * np.float32(4.0), np.float32(0.0)), np.float32(1.0))
        bare = min(max((spots[i] - np.float32(0.7)) * np.float32(6.0), np.float32(0.0)), np.float32(1.0))
        bare = bare * (np.float32(1.0) - dry * np.float32(0.5))
        bright = (
            np.float32(1.0)
            + np.float32(0.35) * (clumps[i] - np.float32(0.5))
            + np.float32(0.4) * (grain[i] - np.float32(0.5))
        )
        for c in range(3):
            v = np.float32(1.0) + lush * (lush_bgr[c] - np.float32(1.0))
            v = v + dry * np.float32(0.8) * (dry_bgr[c] - np.float32(1.0))
            v = v + bare * (bare_bgr[c] - v)
            out[i, c] = v * bright
    return out


def leaf_tilt(p: F32, seed: int) -> F32:
    """``(N, 3)`` a crown's leaf clumps' tilt at its surface points: a vector of three value
    noises (each -0.5..0.5) over clumps about 0.3 m across, to add to the surface's normal (the
    crown's faces then light clump by clump, not face by face)."""
    u = np.ascontiguousarray(p[:, 0] + np.float32(0.6) * p[:, 2], np.float32) * np.float32(3.0)
    v = np.ascontiguousarray(p[:, 1] - np.float32(0.8) * p[:, 2], np.float32) * np.float32(3.0)
    out = np.empty((u.shape[0], 3), np.float32)
    for k in range(3):
        out[:, k] = value_noise(u, v, seed + k) - np.float32(0.5)
    return out


def foliage(p: F32, normal: F32, seed: int) -> F32:
    """A crown's leaves: clumps of lit leaves a few decimetres across with dark gaps between
    them (where light falls into the crown) and leaf-sized grain, laid on the plane the surface
    faces most (so they do not stretch), over the crown's big mottling (:func:`greenery`)."""
    n = np.abs(normal)
    across_x = (n[:, 0] >= n[:, 1]) & (n[:, 0] >= n[:, 2])
    across_y = ~across_x & (n[:, 1] >= n[:, 2])
    u = np.where(across_x, p[:, 1], p[:, 0]).astype(np.float32)
    v = np.where(across_x | across_y, p[:, 2], p[:, 1]).astype(np.float32)
    clumps = fbm(u, v, seed + 11, 3, 0.35)
    t = np.clip((clumps - np.float32(0.3)) / np.float32(0.4), 0.0, 1.0)
    lit = t * t * (np.float32(3.0) - np.float32(2.0) * t)  # smoothstep: gaps dark, clumps lit
    grain = value_noise(u * np.float32(12.0), v * np.float32(12.0), seed + 17) - np.float32(0.5)
    out = (np.float32(0.45) + np.float32(1.0) * lit + np.float32(0.35) * grain) * greenery(p, seed)
    return np.asarray(np.maximum(out, np.float32(0.1)), np.float32)


def bark(p: F32) -> F32:
    """Brightness factor of a trunk's bark: vertical furrows and patches."""
    around = (p[:, 0] + p[:, 1]) * np.float32(14.0)
    furrows = value_noise(around, p[:, 2] * np.float32(1.5), 91) - np.float32(0.5)
    patches = value_noise(around * np.float32(0.2), p[:, 2] * np.float32(2.0), 93) - np.float32(0.5)
    return np.asarray(np.float32(1.0) + np.float32(0.7) * furrows + np.float32(0.35) * patches, np.float32)


FACADE_BGR = np.array(
    [[0.72, 0.8, 0.86], [0.85, 0.86, 0.86], [0.25, 0.32, 0.55], [0.55, 0.6, 0.65], [0.45, 0.5, 0.52],
     [0.6, 0.72, 0.82], [0.35, 0.42, 0.6], [0.78, 0.78, 0.74], [0.5, 0.55, 0.62], [0.3, 0.3, 0.32]],
    np.float32,
)  # fmt: skip
"""Plaster, white, brick, grey render, concrete, sandstone, red-brown brick, cream, ... (BGR)."""


def facade(p: F32, normal: F32) -> tuple[F32, npt.NDArray[np.bool_], npt.NDArray[np.bool_]]:
    """Albedo ``(N, 3)`` of building walls with a style per wall (colour, window size and
    spacing, a shop front on the ground floor), and which points are window glass and which
    are lit at night (``(N,)`` bools). Roofs (normals up) are dark."""
    p = np.ascontiguousarray(p, np.float32)
    normal = np.ascontiguousarray(normal, np.float32)
    angle = np.round(np.arctan2(normal[:, 1], normal[:, 0]) * np.float32(8.0 / np.pi)).astype(np.int64)  # the wall's
    return _facade(p, normal, angle, FACADE_BGR, _BAYS, _seed32(4), _seed32(41), _seed32(7), _seed32(13))


@njit(cache=True, nogil=True)
def _hash_at(ix: np.int64, iy: np.int64, seed32: np.uint64) -> np.float32:  # pragma: no cover - compiled
    """:func:`hash01` of one lattice point."""
    h = (
        np.uint64(np.uint32(ix)) * np.uint64(374761393) + np.uint64(np.uint32(iy)) * np.uint64(668265263) + seed32
    ) & _U32
    return _mixed_at(h, np.uint64(1274126177))


_BAYS = hash01(np.arange(len(FACADE_BGR), dtype=np.int64), np.zeros(len(FACADE_BGR), np.int64), 5)
"""Each facade style's hash of its bay width (:func:`hash01` of ``(style, 0)``, seed 5)."""


@njit(cache=True, nogil=True)
def _facade(
    p: F32, normal: F32, angle: npt.NDArray[np.int64], colours: F32, bays: F32, s_noise: np.uint64,
    s_wall: np.uint64, s_glass: np.uint64, s_lit: np.uint64,
) -> tuple[F32, npt.NDArray[np.bool_], npt.NDArray[np.bool_]]:  # fmt: skip  # pragma: no cover - compiled
    """:func:`facade` per point, in its numpy form's float32 arithmetic (``angle``: the wall's
    direction in sixteenths of a turn, from numpy's arctan2; ``bays``: each style's hash of its
    bay width). A wall's shading noise is drawn only where its colour shows (not on glass,
    window frames, ledges and roofs, whose colour replaces it)."""
    n = p.shape[0]
    albedo = np.empty((n, 3), np.float32)
    glass_out = np.zeros(n, np.bool_)
    lit_out = np.zeros(n, np.bool_)
    f32 = np.float32
    half = f32(0.5)
    floor_h = f32(3.2)
    # What a point's normal and its wall decide, kept from the point before while they stay the
    # same (a wall's points come one after another): the normal's horizontal length and the
    # direction along the wall (the same normal, signs of zeros included), the wall's hash, style,
    # bay width and window width (the same wall).
    last_nx, last_ny = f32(np.nan), f32(np.nan)
    horiz, tx, ty = f32(1.0), f32(0.0), f32(0.0)
    last_key, last_angle = np.int64(0), np.int64(-1)
    wall, style, bay, win_w = f32(0.0), np.int64(0), f32(0.0), f32(0.0)
    for i in range(n):
        nx, ny = normal[i, 0], normal[i, 1]
        same_normal = nx == last_nx and ny == last_ny
        if not (
            same_normal
            and math.copysign(1.0, nx) == math.copysign(1.0, last_nx)
            and math.copysign(1.0, ny) == math.copysign(1.0, last_ny)
        ):
            horiz = np.sqrt(nx * nx + ny * ny) + f32(1e-6)
            tx, ty = -ny / horiz, nx / horiz  # along the wall
            last_nx, last_ny = nx, ny
        s = p[i, 0] * tx + p[i, 1] * ty
        offset = p[i, 0] * nx / horiz + p[i, 1] * ny / horiz  # which wall: its distance from the origin
        key = np.int64(np.round(offset / f32(2.0)))
        if i == 0 or key != last_key or angle[i] != last_angle:
            wall = _hash_at(key, angle[i], s_wall)
            style = np.int64(np.floor(wall * f32(10.0)))
            bay = f32(2.2) + f32(1.6) * bays[style]
            win_w = f32(0.45) + f32(0.25) * wall
            last_key, last_angle = key, angle[i]
        u = s / bay
        fu = u - np.floor(u)
        z = p[i, 2]
        storey = np.floor(z / floor_h)
        fz = z / floor_h - storey
        off = abs(fu - half)
        window = off < win_w / f32(2.0) and fz > f32(0.32) and fz < f32(0.85) and storey >= 1
        shop = storey < 1 and fz > f32(0.12) and fz < f32(0.8) and off < f32(0.42) and wall > f32(0.35)
        frame = abs(off - win_w / f32(2.0)) < f32(0.03) and fz > f32(0.3) and fz < f32(0.87) and storey >= 1
        ledge = storey >= 1 and fz > f32(0.28) and fz < f32(0.32) and off < win_w / f32(2.0) + f32(0.06)
        glass = window or shop
        iu, istorey = np.int64(np.floor(u)), np.int64(storey)
        if glass:
            albedo[i, 0] = albedo[i, 1] = albedo[i, 2] = f32(0.06) + f32(0.05) * _hash_at(iu, istorey, s_glass)
        elif frame or ledge:
            albedo[i, 0] = albedo[i, 1] = albedo[i, 2] = f32(0.8)
        elif normal[i, 2] <= f32(0.7):  # the wall's own colour, shaded (a roof's is set below)
            shade = f32(0.9) + f32(0.2) * _noise_at(s * f32(3.0), p[i, 2] * f32(3.0), s_noise)
            for c in range(3):
                albedo[i, c] = colours[style, c] * shade
        if normal[i, 2] > f32(0.7):  # a roof
            albedo[i, 0], albedo[i, 1], albedo[i, 2] = f32(0.22), f32(0.22), f32(0.24)
            glass = False
        glass_out[i] = glass
        lit_out[i] = glass and _hash_at(iu + 1000 * angle[i], istorey, s_lit) < f32(0.35)
    return albedo, glass_out, lit_out


def clouds(dirs: F32) -> F32:
    """``(N,)`` cloud cover 0..1 of sky directions (unit, map frame)."""
    up = np.maximum(dirs[:, 2], np.float32(0.02))
    x, y = dirs[:, 0] / up, dirs[:, 1] / up
    c = fbm((x * 2.0).astype(np.float32), (y * 2.0).astype(np.float32), 61, 4, 1.0)
    return np.asarray(np.clip((c - np.float32(0.45)) * np.float32(2.5), 0.0, 1.0), np.float32)
