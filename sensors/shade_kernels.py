"""Compiled loops (Numba) of the realistic camera: the same float32 arithmetic as the numpy
forms they replace, one pixel at a time instead of one array pass per step (no temporaries the
size of the image). Compiled on first use and cached beside this file."""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt
from numba import njit
from numba.np.random._constants import fi_float, ki_float, wi_float, ziggurat_nor_inv_r_f, ziggurat_nor_r_f

from sensors.textures import _noise_at

F32 = npt.NDArray[np.float32]


@njit(cache=True, nogil=True)
def ray_range(depth: F32, dirs: F32) -> F32:  # pragma: no cover - compiled
    """``(N,)`` the range along each ray of unit ``dirs (N, 3)`` (optical frame) to its hit at
    z-depth ``depth (N,)``: ``depth / dirs[:, 2]``, inf where ``depth`` is not above 0."""
    out = np.empty(depth.shape[0], np.float32)
    for i in range(depth.shape[0]):
        d = depth[i]
        out[i] = d / dirs[i, 2] if d > 0 else np.float32(np.inf)
    return out


@njit(cache=True, nogil=True)
def street_pixels(
    cls: npt.NDArray[np.uint8], depth: F32, light: int, sign: int
) -> npt.NDArray[np.int64]:  # pragma: no cover - compiled
    """The pixels (in order) of class ``light`` or ``sign`` with a hit (``depth`` above 0)."""
    at = np.empty(cls.shape[0], np.int64)
    k = 0
    for i in range(cls.shape[0]):
        c = cls[i]
        if ((c == light) | (c == sign)) and depth[i] > 0:
            at[k] = i
            k += 1
    return at[:k]


@njit(cache=True, nogil=True)
def split_hits_geometry(
    range_m: F32, max_range_m: np.float32, cls: npt.NDArray[np.uint8], instance: npt.NDArray[np.uint32],
    part: npt.NDArray[np.uint8], dirs: F32, normal: F32, origin: F32,
) -> tuple[npt.NDArray[np.int64], npt.NDArray[np.int64], npt.NDArray[np.uint8], npt.NDArray[np.uint32],
           npt.NDArray[np.uint8], F32, F32, F32]:  # fmt: skip  # pragma: no cover - compiled
    """The rays hitting something (a finite ``range_m`` up to ``max_range_m``) and the others, in
    order (``np.flatnonzero`` of the hits and of the misses), and of the hits: their class,
    instance and part, their points ``(K, 3)`` (``origin + dirs * range_m``), their normals
    turned towards the camera ``(K, 3)`` and the cosines between ray and surface ``(K,)``."""
    n = range_m.shape[0]
    at, miss = np.empty(n, np.int64), np.empty(n, np.int64)
    c, inst, pt = np.empty(n, np.uint8), np.empty(n, np.uint32), np.empty(n, np.uint8)
    p, nrm, cos_v = np.empty((n, 3), np.float32), np.empty((n, 3), np.float32), np.empty(n, np.float32)
    k = m = 0
    for i in range(n):
        r = range_m[i]
        if not (np.isfinite(r) and r <= max_range_m):
            miss[m] = i
            m += 1
            continue
        at[k] = i
        c[k], inst[k], pt[k] = cls[i], instance[i], part[i]
        for a in range(3):
            p[k, a] = origin[a] + dirs[i, a] * r
        n0, n1, n2 = normal[i, 0], normal[i, 1], normal[i, 2]
        facing = n0 * dirs[i, 0] + n1 * dirs[i, 1] + n2 * dirs[i, 2]
        if facing > 0:
            n0, n1, n2 = -n0, -n1, -n2
        nrm[k, 0], nrm[k, 1], nrm[k, 2] = n0, n1, n2
        cos_v[k] = abs(facing)
        k += 1
    return at[:k], miss[:m], c[:k], inst[:k], pt[:k], p[:k], nrm[:k], cos_v[:k]


@njit(cache=True, nogil=True)
def haze_exponent(at: npt.NDArray[np.int64], range_m: F32, haze_m: np.float32) -> F32:  # pragma: no cover - compiled
    """``(K,)`` ``-d / haze_m`` of the rays ``at``' ranges ``d`` (:func:`sensors.weather.haze_fraction`'s)."""
    out = np.empty(at.shape[0], np.float32)
    for j in range(at.shape[0]):
        out[j] = -range_m[at[j]] / haze_m
    return out


@njit(cache=True, nogil=True)
def haze_blend(
    at: npt.NDArray[np.int64], range_m: F32, fade: F32, near_m: np.float32, span_m: np.float32
) -> F32:  # pragma: no cover - compiled
    """:func:`sensors.weather.haze_fraction` of the rays ``at`` from ``fade`` (numpy's ``exp`` of
    :func:`haze_exponent`) in its float32 order: ``max(1 - fade, smoothstep of (d - near_m) /
    span_m clipped to 0..1)``, NaN kept as numpy keeps it; in place in ``fade``."""
    zero, one = np.float32(0.0), np.float32(1.0)
    for j in range(at.shape[0]):
        fog = one - fade[j]
        e = (range_m[at[j]] - near_m) / span_m
        if e < zero:
            e = zero
        elif e > one:
            e = one
        v = e * e * (np.float32(3.0) - np.float32(2.0) * e)
        fade[j] = fog if (fog >= v or fog != fog) else v
    return fade


@njit(cache=True, nogil=True)
def lit_colour(
    at: npt.NDArray[np.int64], dirs: F32, range_m: F32, part: npt.NDArray[np.uint8],
    instance: npt.NDArray[np.uint32], sun_lit: npt.NDArray[np.bool_], sky_open: F32,
    p: F32, nrm: F32, cos_v: F32, albedo: F32, mirror: F32, head: F32, pool: F32,
    sun: F32, light_k: F32, street_bgr: F32, specular: F32, shininess: F32,
) -> tuple[F32, npt.NDArray[np.int64], F32, F32, F32, F32]:  # fmt: skip  # pragma: no cover - compiled
    """The light each hit ``at`` sends to the camera before highlights, reflections, lamps and
    haze (``(K, 3)``: sky, sun, headlights, street light, the street lamps' key light), and
    the shiny ones (a ``specular`` part or a ``mirror``): which they are ``(S,)`` (rows of the
    hits, in order), their reflected directions ``(S, 3)``, cosines to the sun's half vector
    ``(S,)``, their parts' ``shininess`` ``(S,)`` and ``1 - cos_v`` ``(S,)``: the arithmetic of
    :func:`sensors.photo._radiance` in its order. ``head``: the headlights' cone (``forward **
    6``, by hit; used when they are on), ``pool``: the street lamps' pools at the hits (used
    when their key light is on). ``light_k``: ambient * 1.6, sun_gain * 2.2, headlight_gain *
    1.6, headlight_range_m, the camera's height, night * street light, lamp_key_gain * 2.2,
    whether headlights (1) and the lamps' key light (1) are on, the street light's fading
    distance, the dipped beams' cutoff height and share above it, the height the street lamps
    light up to and their fade over it (the constants of :mod:`sensors.photo`)."""
    k = at.shape[0]
    colour = np.empty((k, 3), np.float32)
    shiny_at = np.empty(k, np.int64)
    refl = np.empty((k, 3), np.float32)
    half_cos, shine, away = np.empty(k, np.float32), np.empty(k, np.float32), np.empty(k, np.float32)
    s = 0
    amb, sung, hg, hr, oz, nsl, lkg = light_k[0], light_k[1], light_k[2], light_k[3], light_k[4], light_k[5], light_k[6]
    headlights, key_on = light_k[7] > 0, light_k[8] > 0
    fade, cutoff, dipped, lit_up_to, lamp_fade = light_k[9], light_k[10], light_k[11], light_k[12], light_k[13]
    one, zero = np.float32(1.0), np.float32(0.0)
    for j in range(k):
        i = at[j]
        r = range_m[i]
        n0, n1, n2 = nrm[j, 0], nrm[j, 1], nrm[j, 2]
        lit = one if sun_lit[i] else zero
        sun_cos = max(n0 * sun[0] + n1 * sun[1] + n2 * sun[2], zero) * lit
        sky_share = (np.float32(0.6) + np.float32(0.4) * n2) * sky_open[i]
        light = amb * sky_share + sung * sun_cos
        above = p[j, 2] - oz
        if headlights:
            q = r / hr
            fall = one / (one + q * q)
            dip = one if above < cutoff else dipped
            light += hg * (np.float32(0.3) + np.float32(0.7) * cos_v[j]) * fall * head[j] * dip
        a0, a1, a2 = albedo[j, 0], albedo[j, 1], albedo[j, 2]
        c0, c1, c2 = a0 * light, a1 * light, a2 * light
        if nsl > 0:
            side = np.float32(0.35) if instance[i] > 0 else np.float32(0.12)
            lamps = nsl * (side + (one - side) * max(n2, zero))
            q = r / fade
            lamps = lamps / (one + q * q)
            c0 += a0 * lamps * street_bgr[0]
            c1 += a1 * lamps * street_bgr[1]
            c2 += a2 * lamps * street_bgr[2]
        if key_on:
            key = lkg * sun_cos
            q = r / fade
            key = key / (one + q * q)
            key = key * min(max(one - (above - lit_up_to) / lamp_fade, zero), one)
            key = key * pool[j]
            c0 += a0 * key * street_bgr[0]
            c1 += a1 * key * street_bgr[1]
            c2 += a2 * key * street_bgr[2]
        colour[j, 0], colour[j, 1], colour[j, 2] = c0, c1, c2
        if specular[part[i]] > 0 or mirror[j] > 0:
            shiny_at[s] = j
            d0, d1, d2 = dirs[i, 0], dirs[i, 1], dirs[i, 2]
            h0, h1, h2 = sun[0] - d0, sun[1] - d1, sun[2] - d2
            hn = np.sqrt(h0 * h0 + h1 * h1 + h2 * h2)
            half_cos[s] = max(n0 * (h0 / hn) + n1 * (h1 / hn) + n2 * (h2 / hn), zero)
            dd = np.float32(2.0) * (d0 * n0 + d1 * n1 + d2 * n2)
            refl[s, 0], refl[s, 1], refl[s, 2] = d0 - dd * n0, d1 - dd * n1, d2 - dd * n2
            shine[s] = shininess[part[i]]
            away[s] = one - cos_v[j]
            s += 1
    return colour, shiny_at[:s], refl[:s], half_cos[:s], shine[:s], away[:s]


@njit(cache=True, nogil=True)
def finish_colour(
    colour: F32, shiny_at: npt.NDArray[np.int64], highlight: F32, grazing: F32, env: F32, mirror: F32,
    at: npt.NDArray[np.int64], part: npt.NDArray[np.uint8], sun_lit: npt.NDArray[np.bool_], lamp: F32,
    glow: F32, specular: F32, lamp_bgr: F32, glint: np.float32, window: F32, haze_f: F32, haze: F32, out: F32,
) -> None:  # fmt: skip  # pragma: no cover - compiled
    """``out[at]``: ``colour`` with, at the rows ``shiny_at``, the sun's ``highlight`` (the
    half vector's cosine to the shininess) times ``glint`` and the reflections ``env`` blended
    in by Schlick's term (``grazing``: (1 - cos) ** 5); lamps' light, lit windows (``window``:
    their light, 0 by day) and ``haze_f`` of the way to the colour ``haze``."""
    one, zero = np.float32(1.0), np.float32(0.0)
    for s in range(shiny_at.shape[0]):
        j = shiny_at[s]
        i = at[j]
        lit = one if sun_lit[i] else zero
        g = specular[part[i]] * highlight[s] * lit * glint * np.float32(3.0)
        m = mirror[j]
        f = min(m + (one - m) * grazing[s] * (one if m > 0 else zero), np.float32(0.45))
        for c in range(3):
            v = colour[j, c] + g
            colour[j, c] = v * (one - f) + env[s, c] * f
    for j in range(at.shape[0]):
        i = at[j]
        g = lamp[i]
        if g > 0:
            pt = part[i]
            for c in range(3):
                colour[j, c] += lamp_bgr[pt, c] * g
        if glow[j] > 0:
            for c in range(3):
                colour[j, c] += window[c]
        f = haze_f[j]
        for c in range(3):
            out[i, c] = colour[j, c] * (one - f) + haze[c] * f


@njit(cache=True, nogil=True)
def hit_points(at: npt.NDArray[np.int64], dirs: F32, range_m: F32, origin: F32) -> F32:  # pragma: no cover - compiled
    """``(K, 3)`` the hit points ``origin + dirs * range_m`` of the rays ``at``."""
    p = np.empty((at.shape[0], 3), np.float32)
    for j in range(at.shape[0]):
        i = at[j]
        for c in range(3):
            p[j, c] = origin[c] + dirs[i, c] * range_m[i]
    return p


@njit(cache=True, nogil=True)
def depth_units(
    depth: npt.NDArray[np.floating], units: float, in_float32: bool, most: float
) -> npt.NDArray[np.uint16]:  # pragma: no cover - compiled
    """``(N,) uint16`` :func:`sensors.camera.depth_to_uint16` of 1-D ``depth``: ``rint(depth *
    units)`` (``in_float32``: the product in float32, else in float64), 0 where that is not
    finite, not above 0 or above ``most``."""
    out = np.empty(depth.shape[0], np.uint16)
    u32 = np.float32(units)
    for i in range(depth.shape[0]):
        u = np.float64(np.rint(np.float32(depth[i]) * u32)) if in_float32 else np.rint(np.float64(depth[i]) * units)
        out[i] = np.uint16(u) if (np.isfinite(u) and u > 0 and u <= most) else np.uint16(0)
    return out


@njit(cache=True, nogil=True)
def _levelled(g: np.float32, black: np.float32, scale: np.float32, toe: np.float32) -> np.float32:  # pragma: no cover
    """A grey ``g`` with the black level set: ``toe + (g - black) * scale`` at or above ``black``,
    below it scaled onto 0..``toe`` (unchanged when ``black <= 0``)."""
    if black <= 0:
        return g
    if g >= black:
        return toe + (g - black) * scale
    return g * (toe / black)


@njit(cache=True, nogil=True)
def _byte(value: np.float32, noise: np.float32) -> np.uint8:  # pragma: no cover - compiled
    """``value`` plus ``noise``, rounded and clipped to 0..255."""
    v = (value + noise) + np.float32(0.5)
    return np.uint8(min(max(v, np.float32(0.0)), np.float32(255.0)))


@njit(cache=True, nogil=True)
def ids_seen(
    pixel_ids: npt.NDArray[np.uint32], ids: npt.NDArray[np.uint32]
) -> npt.NDArray[np.bool_]:  # pragma: no cover - compiled
    """``(K,)`` whether each of ``ids`` is among ``pixel_ids`` (``np.isin(ids, pixel_ids)``;
    runs of one id, as along an image's rows, are looked up once)."""
    order = np.argsort(ids)
    ordered = ids[order]
    k = ordered.shape[0]
    seen = np.zeros(k, np.bool_)
    if k == 0:
        return seen
    last = pixel_ids[0] if pixel_ids.shape[0] else np.uint32(0)
    for n in range(pixel_ids.shape[0]):
        v = pixel_ids[n]
        if n > 0 and v == last:
            continue
        last = v
        pos = np.searchsorted(ordered, v)
        while pos < k and ordered[pos] == v:  # every agent row holding this id
            seen[order[pos]] = True
            pos += 1
    return seen


@njit(cache=True, nogil=True)
def edges(
    cls: npt.NDArray[np.uint8], part: npt.NDArray[np.uint8], instance: npt.NDArray[np.uint32], range_m: F32,
    h: int, w: int,
) -> npt.NDArray[np.bool_]:  # fmt: skip  # pragma: no cover - compiled
    """``(H * W,)`` :func:`sensors.camera.edge_pixels` of row-major ``cls``, ``part``,
    ``instance`` and ``range_m`` (ranges capped at 1e4 m)."""
    edge = np.zeros(h * w, np.bool_)
    cap, jump = np.float32(1e4), np.float32(0.03)
    for v in range(h):
        for u in range(w):
            i = v * w + u
            ra = min(range_m[i], cap)
            for j in (i + 1, i + w):
                if (j == i + 1 and u + 1 >= w) or (j == i + w and v + 1 >= h):
                    continue
                rb = min(range_m[j], cap)
                if (
                    cls[i] != cls[j] or part[i] != part[j] or instance[i] != instance[j]
                    or abs(ra - rb) > jump * min(ra, rb)
                ):  # fmt: skip
                    edge[i] = True
                    edge[j] = True
    return edge


@njit(cache=True, nogil=True)
def contact_pairs(
    dirs: F32, range_m: F32, cls: npt.NDArray[np.uint8], instance: npt.NDArray[np.uint32],
    is_ground: npt.NDArray[np.bool_], origin: F32, cx: npt.NDArray[np.float64], cy: npt.NDArray[np.float64],
    reach: npt.NDArray[np.float64], cs: F32, sn: F32,
) -> tuple[npt.NDArray[np.int64], npt.NDArray[np.int64], F32, F32]:  # fmt: skip  # pragma: no cover - compiled
    """The rays hitting the static world's ground (a finite ``range_m``, ``is_ground[cls]``,
    instance 0) whose hit point ``origin + dirs * range_m`` (float32, as :func:`hit_points`)
    lies within each box's ``reach`` of its centre ``(cx, cy)`` along x and along y (``|g - c| <
    reach`` in float64, as :func:`sensors.photo.contact_light` tests them): per pair the ray,
    the box, and the point's distances along the box's axes from its centre (``cs``, ``sn``:
    the box's yaw's cosine and sine; float32). Pairs come ray by ray (boxes in order within a
    ray). The boxes' squares (widened by :data:`CELL_MARGIN_M`) are listed on a grid of cells
    (1 m or wider, at most 256 a side), so a point looks at the boxes of its own cell only."""
    n, k = range_m.shape[0], cx.shape[0]
    if n == 0 or k == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0, np.float32), np.zeros(0, np.float32)
    x0, y0, x1, y1 = np.inf, np.inf, -np.inf, -np.inf
    for j in range(k):
        x0, x1 = min(x0, cx[j] - reach[j] - CELL_MARGIN_M), max(x1, cx[j] + reach[j] + CELL_MARGIN_M)
        y0, y1 = min(y0, cy[j] - reach[j] - CELL_MARGIN_M), max(y1, cy[j] + reach[j] + CELL_MARGIN_M)
    cell = max(1.0, max(x1 - x0, y1 - y0) / 256.0)
    nx, ny = int((x1 - x0) / cell) + 1, int((y1 - y0) / cell) + 1
    start = np.zeros(nx * ny + 1, np.int64)
    listed = np.empty(0, np.int64)
    fill = start[:-1]
    for b in range(2):  # count, then fill: the boxes whose widened square touches each cell
        if b == 1:
            for c in range(nx * ny):
                start[c + 1] += start[c]
            fill = start[:-1].copy()
            listed = np.empty(start[nx * ny], np.int64)
        for j in range(k):
            ux0 = min(max(int((cx[j] - reach[j] - CELL_MARGIN_M - x0) / cell), 0), nx - 1)
            ux1 = min(max(int((cx[j] + reach[j] + CELL_MARGIN_M - x0) / cell), 0), nx - 1)
            uy0 = min(max(int((cy[j] - reach[j] - CELL_MARGIN_M - y0) / cell), 0), ny - 1)
            uy1 = min(max(int((cy[j] + reach[j] + CELL_MARGIN_M - y0) / cell), 0), ny - 1)
            for u in range(ux0, ux1 + 1):
                for v in range(uy0, uy1 + 1):
                    if b == 0:
                        start[u * ny + v + 1] += 1
                    else:
                        listed[fill[u * ny + v]] = j
                        fill[u * ny + v] += 1
    cell_of = np.empty(n, np.int32)  # each ray's cell when it is a ground hit in a listed one, else -1
    total = 0
    for i in range(n):
        cell_of[i] = -1
        r = range_m[i]
        if not np.isfinite(r) or instance[i] != 0 or not is_ground[cls[i]]:
            continue
        fx, fy = np.float64(origin[0] + dirs[i, 0] * r), np.float64(origin[1] + dirs[i, 1] * r)
        if fx >= x0 and fx < x1 and fy >= y0 and fy < y1:
            c = int((fx - x0) / cell) * ny + int((fy - y0) / cell)
            if start[c + 1] > start[c]:
                cell_of[i] = c
                total += start[c + 1] - start[c]
    pt, box = np.empty(total, np.int64), np.empty(total, np.int64)
    ax, ay = np.empty(total, np.float32), np.empty(total, np.float32)
    m = 0
    for i in range(n):
        c = cell_of[i]
        if c < 0:
            continue
        r = range_m[i]
        gx, gy = origin[0] + dirs[i, 0] * r, origin[1] + dirs[i, 1] * r
        fx, fy = np.float64(gx), np.float64(gy)
        for s in range(start[c], start[c + 1]):
            j = listed[s]
            if abs(fx - cx[j]) < reach[j] and abs(fy - cy[j]) < reach[j]:
                dx, dy = gx - np.float32(cx[j]), gy - np.float32(cy[j])
                pt[m], box[m] = i, j
                ax[m] = abs(cs[j] * dx + sn[j] * dy)
                ay[m] = abs(-sn[j] * dx + cs[j] * dy)
                m += 1
    return pt[:m], box[:m], ax[:m], ay[:m]


CELL_MARGIN_M = 0.05
"""How much wider than a box's square the cells :func:`contact_pairs` lists it in are: far more
than the rounding of the cell arithmetic, so every point within reach finds its box."""


@njit(cache=True, nogil=True)
def agents_low_light(
    out: F32, dirs: F32, range_m: F32, instance: npt.NDArray[np.uint32], origin: F32,
    ids: npt.NDArray[np.uint32], floor_z: F32,
) -> None:  # fmt: skip  # pragma: no cover - compiled
    """In place: ``out`` at the rays hitting an agent (a finite ``range_m``, an instance found
    among the sorted ``ids``) set to the sky light of its lower parts, ``0.45 + 0.55 *
    clip(height / 0.5, 0, 1)`` of the hit's height (``origin + dirs * range_m``, float32) over
    its box's floor ``floor_z`` (by the first of ``ids`` equal to its instance)."""
    k = ids.shape[0]
    if k == 0:
        return
    zero, one = np.float32(0.0), np.float32(1.0)
    last, pos = np.uint32(0), 0  # the last instance looked up (0: none) and where it was found
    for i in range(range_m.shape[0]):
        r = range_m[i]
        if instance[i] == 0 or not np.isfinite(r):
            continue
        if instance[i] != last:  # runs of one agent's pixels, as along an image's rows, looked up once
            last, pos = instance[i], min(np.searchsorted(ids, instance[i]), k - 1)
        if ids[pos] != instance[i]:
            continue
        height = (origin[2] + dirs[i, 2] * r) - floor_z[pos]
        out[i] = np.float32(0.45) + np.float32(0.55) * min(max(height / np.float32(0.5), zero), one)


@njit(cache=True, nogil=True)
def sky(
    dirs: F32, horizon: F32, zenith: F32, seeds32: npt.NDArray[np.uint64], norm: np.float32
) -> F32:  # pragma: no cover - compiled
    """``(N, 3)`` :func:`sensors.photo.sky_linear` along unit ``dirs``: the gradient from
    ``horizon`` to ``zenith`` and the clouds (:func:`sensors.textures.clouds`: fractal noise of
    ``seeds32``' octaves, summed weights ``norm``) above the horizon, in their float32 order
    (the noise drawn for the rays above the horizon only)."""
    out = np.empty((dirs.shape[0], 3), np.float32)
    sky_rows(dirs, np.arange(dirs.shape[0]), horizon, zenith, seeds32, norm, out)
    return out


@njit(cache=True, nogil=True)
def sky_rows(
    dirs: F32, rows: npt.NDArray[np.int64], horizon: F32, zenith: F32, seeds32: npt.NDArray[np.uint64],
    norm: np.float32, out: F32,
) -> None:  # fmt: skip  # pragma: no cover - compiled
    """:func:`sky` of the ``rows`` of ``dirs`` written into those rows of ``out`` (``out[rows] =
    sky(dirs[rows], ...)``, no gathered copies)."""
    n = rows.shape[0]
    zero, one = np.float32(0.0), np.float32(1.0)
    up_at = np.empty(n, np.int64)  # the rays above the horizon: the only ones with clouds
    m = 0
    for r in range(n):
        if dirs[rows[r], 2] > 0:
            up_at[m] = rows[r]
            m += 1
    x, y, total = np.empty(m, np.float32), np.empty(m, np.float32), np.zeros(m, np.float32)
    for j in range(m):
        i = up_at[j]
        up = max(dirs[i, 2], np.float32(0.02))
        x[j], y[j] = (dirs[i, 0] / up) * np.float32(2.0), (dirs[i, 1] / up) * np.float32(2.0)
    amp, f = 1.0, one
    for o in range(seeds32.shape[0]):  # an octave at a time over every ray (vector instructions)
        a, seed = np.float32(amp), seeds32[o]
        for j in range(m):
            total[j] += a * _noise_at(x[j] * f, y[j] * f, seed)
        amp *= 0.5
        f *= np.float32(2.0)
    j = 0
    for r in range(n):
        i = rows[r]
        dz = dirs[i, 2]
        t = np.sqrt(min(max(dz, zero), one))
        cover = zero
        if dz > 0:  # clouds lie above the horizon
            c = min(max((total[j] / norm - np.float32(0.45)) * np.float32(2.5), zero), one)
            cover = c * np.float32(0.85) * min(max(dz * np.float32(6.0), zero), one)
            j += 1
        for k in range(3):
            s = horizon[k] + t * (zenith[k] - horizon[k])
            cloud = horizon[k] * np.float32(1.05) + np.float32(0.02)
            out[i, k] = s + cover * (cloud - s)


@njit(cache=True, nogil=True)
def below_horizon(env: F32, dirs: F32, value: np.float32) -> None:  # pragma: no cover - compiled
    """``env[dirs[:, 2] < 0] = value`` in place."""
    for i in range(dirs.shape[0]):
        if dirs[i, 2] < 0:
            for c in range(env.shape[1]):
                env[i, c] = value


@njit(cache=True, nogil=True)
def turned_and_ratios(
    normal: F32, dirs: F32, instance: npt.NDArray[np.uint32], depth: F32, size_px_m: np.float32,
    nearest_m: np.float32, levels: F32,
) -> tuple[F32, F32]:  # fmt: skip  # pragma: no cover - compiled
    """``(N, 3)`` the normals turned to face the camera: negated where they face along the ray
    (``einsum("ij,ij->i", normal, dirs) > 0``, its sum taken in the same order); and per agent
    pixel (``instance`` above 0, row-major order) the pixels ``size_px_m`` spans at its ``depth``
    (no nearer than ``nearest_m``) over each of ``levels``: ``(K, L)``, as numpy's ``size_px_m /
    np.maximum(depth[on_agent], nearest_m)`` over ``levels``."""
    n = normal.shape[0]
    out = np.empty((n, 3), np.float32)
    k = 0
    for i in range(n):
        n0, n1, n2 = normal[i, 0], normal[i, 1], normal[i, 2]
        if n0 * dirs[i, 0] + n1 * dirs[i, 1] + n2 * dirs[i, 2] > 0:
            n0, n1, n2 = -n0, -n1, -n2
        out[i, 0], out[i, 1], out[i, 2] = n0, n1, n2
        if instance[i] > 0:
            k += 1
    ratio = np.empty((k, levels.shape[0]), np.float32)
    if k == 0:
        return out, ratio
    j = 0
    for i in range(n):
        if instance[i] > 0:
            d = depth[i]
            want = size_px_m / (nearest_m if d < nearest_m else d)
            for m in range(levels.shape[0]):
                ratio[j, m] = want / levels[m]
            j += 1
    return out, ratio


@njit(cache=True, nogil=True)
def nearest_levels(
    instance: npt.NDArray[np.uint32], log_ratio: F32
) -> npt.NDArray[np.int8]:  # pragma: no cover - compiled
    """``(N,)`` per pixel the level whose log ratio (:func:`turned_and_ratios`', logged) is nearest 0,
    the first of equals (numpy's ``np.abs(log_ratio).argmin(axis=-1)``, no NaNs) on agents'
    pixels (``instance`` above 0, in row-major order), -1 elsewhere."""
    out = np.full(instance.shape[0], -1, np.int8)
    j = 0
    for i in range(instance.shape[0]):
        if instance[i] > 0:
            best, at = abs(log_ratio[j, 0]), 0
            for m in range(1, log_ratio.shape[1]):
                v = abs(log_ratio[j, m])
                if v < best:
                    best, at = v, m
            out[i] = at
            j += 1
    return out


@njit(cache=True, nogil=True)
def agent_weighted(
    grid: F32, instance: npt.NDArray[np.uint32], row0: int, row1: int, col0: int, col1: int
) -> tuple[F32, F32]:  # pragma: no cover - compiled
    """Of the window ``row0:row1, col0:col1`` of ``grid (H, W, 3)`` and ``instance (H, W)``: the
    window times each pixel's agent weight ``(h, w, 3)`` (1 where ``instance`` is above 0, else
    0: the float32 products, -0 and NaN kept) and the weights ``(h, w)``, both contiguous."""
    h, w = row1 - row0, col1 - col0
    weighted = np.empty((h, w, 3), np.float32)
    near = np.empty((h, w), np.float32)
    for y in range(h):
        for x in range(w):
            a = np.float32(1.0) if instance[row0 + y, col0 + x] > 0 else np.float32(0.0)
            near[y, x] = a
            for c in range(3):
                weighted[y, x, c] = grid[row0 + y, col0 + x, c] * a
    return weighted, near


@njit(cache=True, nogil=True)
def level_spans(level: npt.NDArray[np.int8], count: int) -> npt.NDArray[np.int64]:  # pragma: no cover - compiled
    """``(count, 4)`` per level ``k`` the first and last row and column of ``level (H, W)`` equal
    to ``k`` (-1, -1, -1, -1: none)."""
    out = np.full((count, 4), -1, np.int64)
    for v in range(level.shape[0]):
        for u in range(level.shape[1]):
            k = level[v, u]
            if k < 0 or k >= count:
                continue
            if out[k, 0] < 0:
                out[k, 0], out[k, 2], out[k, 3] = v, u, u
            out[k, 1] = v
            out[k, 2] = min(out[k, 2], u)
            out[k, 3] = max(out[k, 3], u)
    return out


@njit(cache=True, nogil=True)
def blurred_unit(
    grid: F32, row0: int, col0: int, level: npt.NDArray[np.int8], k: int, num: F32, den: F32
) -> None:  # pragma: no cover - compiled
    """Where ``level`` (``(H, W)``, as ``grid``) is ``k`` in the window of ``num``'s shape from
    ``row0``, ``col0``: ``grid`` set to ``num / max(den, 1e-6)`` made unit (its length as
    ``np.linalg.norm``'s: squares summed left to right, floored at 1e-6); in place."""
    tiny = np.float32(1e-6)
    for y in range(num.shape[0]):
        for x in range(num.shape[1]):
            if level[row0 + y, col0 + x] != k:
                continue
            d = den[y, x]
            d = d if d > tiny else tiny
            m0, m1, m2 = num[y, x, 0] / d, num[y, x, 1] / d, num[y, x, 2] / d
            length = np.sqrt(m0 * m0 + m1 * m1 + m2 * m2)
            length = length if length > tiny else tiny
            grid[row0 + y, col0 + x, 0] = m0 / length
            grid[row0 + y, col0 + x, 1] = m1 / length
            grid[row0 + y, col0 + x, 2] = m2 / length


@njit(cache=True, nogil=True)
def scale_rows(table: F32, rows: npt.NDArray[np.int64], factor: F32) -> None:  # pragma: no cover - compiled
    """``table[rows] *= factor[:, None]`` in place (``rows`` distinct)."""
    for j in range(rows.shape[0]):
        i = rows[j]
        for c in range(table.shape[1]):
            table[i, c] = table[i, c] * factor[j]


@njit(cache=True, nogil=True)
def tint_rows(table: F32, rows: npt.NDArray[np.int64], factor: F32) -> None:  # pragma: no cover - compiled
    """``table[rows] *= factor`` in place, a factor per row and column (``rows`` distinct)."""
    for j in range(rows.shape[0]):
        i = rows[j]
        for c in range(table.shape[1]):
            table[i, c] = table[i, c] * factor[j, c]


@njit(cache=True, nogil=True)
def bent_rows(
    normal: F32, rows: npt.NDArray[np.int64], tilt: F32, dirs: F32, strength: np.float32
) -> None:  # pragma: no cover - compiled
    """Each of ``normal[rows]`` plus ``strength`` times its row of ``tilt``, moved back to face
    against its ray (``dirs``) where the tilt turned it away (its dot product with the ray then
    -0.05), made unit length again; in place."""
    for j in range(rows.shape[0]):
        i = rows[j]
        b0 = normal[i, 0] + strength * tilt[j, 0]
        b1 = normal[i, 1] + strength * tilt[j, 1]
        b2 = normal[i, 2] + strength * tilt[j, 2]
        facing = b0 * dirs[i, 0] + b1 * dirs[i, 1] + b2 * dirs[i, 2]
        if facing > 0.0:
            back = facing + np.float32(0.05)
            b0, b1, b2 = b0 - back * dirs[i, 0], b1 - back * dirs[i, 1], b2 - back * dirs[i, 2]
        length = max(np.sqrt(b0 * b0 + b1 * b1 + b2 * b2), np.float32(1e-6))
        normal[i, 0], normal[i, 1], normal[i, 2] = b0 / length, b1 / length, b2 / length


@njit(cache=True, nogil=True)
def minimum_at(values: F32, rows: npt.NDArray[np.int64], other: F32) -> None:  # pragma: no cover - compiled
    """``np.minimum.at(values, rows, other)`` (no NaNs): each row the least of what it holds and
    every value given for it; in place."""
    for j in range(rows.shape[0]):
        i = rows[j]
        if other[j] < values[i]:
            values[i] = other[j]


@njit(cache=True, nogil=True, error_model="numpy")
def filmic(linear: F32, keep: F32, gain: np.float32) -> F32:  # pragma: no cover - compiled
    """:func:`sensors.photo.tone_curve`'s curve before its gamma: Narkowicz's ACES fit of ``linear
    (N, 3)`` times ``keep (N,)`` (the vignetting, rounded to float32 as an in-place product) times
    ``gain``, clipped to 0..1 (NaN stays NaN, as ``np.clip``), in its numpy form's float32 order.
    (numpy's error model: the curve's denominator is never 0, and the loop is compiled to vector
    instructions.)"""
    flat = linear.ravel()
    out = np.empty(flat.shape[0], np.float32)
    a, b, c, d, e = np.float32(2.51), np.float32(0.03), np.float32(2.43), np.float32(0.59), np.float32(0.14)
    zero, one = np.float32(0.0), np.float32(1.0)
    for i in range(keep.shape[0]):  # the product and the curve in one pass over the values
        k = keep[i]
        for ch in range(3):
            x = (flat[3 * i + ch] * k) * gain
            y = (x * (a * x + b)) / (x * (c * x + d) + e)
            y = zero if y < zero else y
            y = one if y > one else y
            out[3 * i + ch] = y
    return out.reshape(linear.shape)


@njit(cache=True, nogil=True)
def add_subsamples(
    linear: F32, pixel: npt.NDArray[np.int64], sub: F32, per_pixel: int
) -> None:  # pragma: no cover - compiled
    """``linear[pixel] = (linear[pixel] + sub.reshape(-1, per_pixel, 3).sum(axis=1)) / (per_pixel + 1)``
    in place (the sub-rays summed left to right, as numpy sums that axis; ``pixel`` distinct)."""
    count = np.float32(per_pixel + 1)
    for j in range(pixel.shape[0]):
        i = pixel[j]
        for c in range(3):
            total = sub[j * per_pixel, c]
            for s in range(1, per_pixel):
                total = total + sub[j * per_pixel + s, c]
            linear[i, c] = (linear[i, c] + total) / count


@njit(cache=True, nogil=True)
def subpixel_directions(
    pixel: npt.NDArray[np.int64], width: int, offsets: npt.NDArray[np.float64], fx: float, cx: float, fy: float,
    cy: float,
) -> F32:  # fmt: skip  # pragma: no cover - compiled
    """``(K * S, 3)`` unit directions (optical frame) of a pinhole's rays through each of
    ``pixel`` (row-major index) shifted by each of ``offsets (S, 2)`` pixels, sub-rays of a pixel
    together: :meth:`sensors.pinhole.Pinhole.pixel_directions` of an undistorted lens in its
    float64 order (the length's squares summed left to right), rounded to float32."""
    per = offsets.shape[0]
    out = np.empty((pixel.shape[0] * per, 3), np.float32)
    for j in range(pixel.shape[0]):
        v, u = pixel[j] // width, pixel[j] % width
        for s in range(per):
            x = (np.float64(u) + offsets[s, 0] - cx) / fx
            y = (np.float64(v) + offsets[s, 1] - cy) / fy
            length = np.sqrt(x * x + y * y + 1.0)
            out[j * per + s, 0] = np.float32(x / length)
            out[j * per + s, 1] = np.float32(y / length)
            out[j * per + s, 2] = np.float32(1.0 / length)
    return out


@njit(cache=True, nogil=True)
def lamp_offsets_sq(points: F32, spacing: np.float32) -> F32:  # pragma: no cover - compiled
    """``(N,)`` squared distance in the plane from each point to the nearest node of a square grid
    of ``spacing`` (per axis ``p - rint(p / spacing) * spacing``, as numpy computes it)."""
    out = np.empty(points.shape[0], np.float32)
    for i in range(points.shape[0]):
        x = points[i, 0] - np.rint(points[i, 0] / spacing) * spacing
        y = points[i, 1] - np.rint(points[i, 1] / spacing) * spacing
        out[i] = x * x + y * y
    return out


@njit(cache=True, nogil=True)
def palette_row(
    instance: np.uint32, part: np.uint8, first: npt.NDArray[np.int64], size: npt.NDArray[np.int64],
    salt: npt.NDArray[np.uint64],
) -> int:  # fmt: skip  # pragma: no cover - compiled
    """The row of the colour a part with a palette (``size[part] > 0``, its colours from row
    ``first[part]``) takes on ``instance``, as :func:`sensors.parts.part_albedo` picks it: the
    instance's key ``(id * 2654435761 >> 7) + salt[part]`` (modulo 2**64) modulo the palette's size."""
    key = ((np.uint64(instance) * np.uint64(2654435761)) >> np.uint64(7)) + salt[part]
    return int(first[part] + np.int64(key % np.uint64(size[part])))


@njit(cache=True, nogil=True)
def part_rows(
    albedo: F32, rows: npt.NDArray[np.int64], part: npt.NDArray[np.uint8], instance: npt.NDArray[np.uint32],
    by_part: F32, palettes: F32, first: npt.NDArray[np.int64], size: npt.NDArray[np.int64],
    salt: npt.NDArray[np.uint64],
) -> None:  # fmt: skip  # pragma: no cover - compiled
    """``albedo[rows[j]]`` set to the colour of ``part[j]`` on ``instance[j]`` in place, as
    :func:`sensors.parts.part_albedo` picks it: ``by_part[part]``, or for a part with a palette
    (``size[part] > 0``) its row :func:`palette_row` of ``palettes``."""
    for j in range(rows.shape[0]):
        p = part[j]
        src = palettes[palette_row(instance[j], p, first, size, salt)] if size[p] > 0 else by_part[p]
        i = rows[j]
        for c in range(3):
            albedo[i, c] = src[c]


@njit(cache=True, nogil=True)
def class_order(
    cls: npt.NDArray[np.uint8],
) -> tuple[npt.NDArray[np.int64], npt.NDArray[np.int64]]:  # pragma: no cover - compiled
    """Each class's rows in order (``np.argsort(cls, kind="stable")``) and where each class's
    run ends in it (``np.cumsum(np.bincount(cls, minlength=256))``): a counting sort. A run of
    one class (as along an image's rows) is counted and placed with its position held in a
    register, not read back from the table at every row."""
    n = cls.shape[0]
    end = np.zeros(256, np.int64)
    start = 0
    for i in range(1, n + 1):
        if i == n or cls[i] != cls[start]:
            end[cls[start]] += i - start
            start = i
    for c in range(1, 256):
        end[c] += end[c - 1]
    fill = np.empty(256, np.int64)
    fill[0] = 0
    fill[1:] = end[:-1]
    order = np.empty(n, np.int64)
    if n == 0:
        return order, end
    c = cls[0]
    pos = fill[c]
    for i in range(n):
        if cls[i] != c:
            fill[c] = pos
            c = cls[i]
            pos = fill[c]
        order[pos] = i
        pos += 1
    return order, end


@njit(cache=True, nogil=True)
def rows_taken(table: F32, rows: npt.NDArray[np.integer]) -> F32:  # pragma: no cover - compiled
    """``(K, C)`` the ``rows`` of ``(N, C)`` ``table`` (``table[rows]``; rows of any integer type,
    a class per row too), contiguous."""
    out = np.empty((rows.shape[0], table.shape[1]), table.dtype)
    for j in range(rows.shape[0]):
        i = rows[j]
        for c in range(table.shape[1]):
            out[j, c] = table[i, c]
    return out


@njit(cache=True, nogil=True)
def facade_rows(
    albedo: F32, mirror: F32, glow: F32, rows: npt.NDArray[np.int64], wall: F32, glass: npt.NDArray[np.bool_],
    lit: npt.NDArray[np.bool_], glass_mirror: np.float32,
) -> None:  # fmt: skip  # pragma: no cover - compiled
    """In place, per row ``rows[j]``: ``albedo`` set to ``wall[j]``, ``mirror`` to
    ``glass_mirror`` where ``glass[j]``, ``glow`` to 1 where ``lit[j]`` (the building walls'
    :func:`sensors.textures.facade`)."""
    for j in range(rows.shape[0]):
        i = rows[j]
        for c in range(3):
            albedo[i, c] = wall[j, c]
        if glass[j]:
            mirror[i] = glass_mirror
        if lit[j]:
            glow[i] = np.float32(1.0)


@njit(cache=True, nogil=True)
def over_span(image: F32, threshold: np.float32) -> tuple[int, int, int, int]:  # pragma: no cover - compiled
    """The first and last row and column of ``(H, W, C)`` ``image`` holding a pixel with a
    channel above ``threshold`` (-1, -1, -1, -1: none)."""
    r0, r1, c0, c1 = -1, -1, image.shape[1], -1
    for v in range(image.shape[0]):
        row = image[v].ravel()
        over = False
        for k in range(row.shape[0]):  # without a branch: compiled to vector instructions
            over |= row[k] > threshold
        if not over:
            continue
        for u in range(image.shape[1]):
            for c in range(image.shape[2]):
                if image[v, u, c] > threshold:
                    if r0 < 0:
                        r0 = v
                    r1 = v
                    c0 = min(c0, u)
                    c1 = max(c1, u)
                    break
    if r0 < 0:
        return -1, -1, -1, -1
    return r0, r1, c0, c1


@njit(cache=True, nogil=True)
def emitting_rows(
    range_m: F32, part: npt.NDArray[np.uint8], cls: npt.NDArray[np.uint8], emits: npt.NDArray[np.bool_],
    lit_buses: bool, glass: int, bus: int,
) -> npt.NDArray[np.int64]:  # fmt: skip  # pragma: no cover - compiled
    """The rows with a finite ``range_m`` whose part ``emits`` light, and when ``lit_buses`` the
    ``glass`` of a ``bus`` (class ``cls``) too (:func:`sensors.photo._emits`), in order."""
    at = np.empty(range_m.shape[0], np.int64)
    k = 0
    for i in range(range_m.shape[0]):
        if np.isfinite(range_m[i]) and (emits[part[i]] or (lit_buses and part[i] == glass and cls[i] == bus)):
            at[k] = i
            k += 1
    return at[:k]


_LOW32 = np.uint64(0xFFFFFFFF)
_PCG_MULT_HI, _PCG_MULT_LO = np.uint64(2549297995355413924), np.uint64(4865540595714422341)
"""PCG64's 128-bit multiplier, its high and low 64 bits."""


@njit(cache=True, nogil=True, inline="always")
def _pcg64_next32(st: npt.NDArray[np.uint64]) -> np.uint64:  # pragma: no cover - compiled
    """The next 32 bits of a PCG64 stream as numpy's ``PCG64`` hands them out, ``st`` its state
    (state's high and low 64 bits, increment's high and low 64 bits, whether a 32-bit half is
    kept, that half) advanced in place: each 64-bit output (the 128-bit state times the multiplier
    plus the increment, then its halves xored and rotated by its top 6 bits) gives its low half,
    then its high half."""
    if st[4] != 0:
        st[4] = np.uint64(0)
        return np.uint64(st[5])
    hi, lo = st[0], st[1]
    s32 = np.uint64(32)
    a0, a1 = lo & _LOW32, lo >> s32  # the high 64 bits of lo * the multiplier's low word, by 32-bit halves
    b0, b1 = _PCG_MULT_LO & _LOW32, _PCG_MULT_LO >> s32
    t = a1 * b0 + ((a0 * b0) >> s32)
    u = a0 * b1 + (t & _LOW32)
    carried = a1 * b1 + (t >> s32) + (u >> s32)
    low = lo * _PCG_MULT_LO
    new_lo = low + st[3]
    new_hi = carried + hi * _PCG_MULT_LO + lo * _PCG_MULT_HI + st[2] + (np.uint64(1) if new_lo < low else np.uint64(0))
    st[0], st[1] = new_hi, new_lo
    x = new_hi ^ new_lo
    rot = new_hi >> np.uint64(58)
    out = (x >> rot) | (x << ((np.uint64(64) - rot) & np.uint64(63)))
    st[4], st[5] = np.uint64(1), out >> s32
    return np.uint64(out & _LOW32)


@njit(cache=True, nogil=True, inline="always")
def _pcg64_float(st: npt.NDArray[np.uint64]) -> np.float32:  # pragma: no cover - compiled
    """numpy's float32 uniform in [0, 1) from the next 32 bits: their top 24 over 2**24."""
    return np.float32(_pcg64_next32(st) >> np.uint64(8)) * np.float32(1.0 / 16777216.0)


@njit(cache=True, nogil=True, inline="always")
def _standard_normal(st: npt.NDArray[np.uint64]) -> np.float32:  # pragma: no cover - compiled
    """The next float32 draw of numpy's ``Generator.standard_normal(dtype=np.float32)`` on the
    PCG64 state ``st`` (:func:`_pcg64_next32`'s six words, advanced in place): the same ziggurat
    (numpy's tables, as numba keeps them), 32 bits a draw, its rare tail and wedge draws with the
    same float32 and float64 steps (``log1pf``, ``exp``)."""
    one, byte, low23 = np.uint64(1), np.uint64(0xFF), np.uint64(0x7FFFFF)
    while True:
        r = _pcg64_next32(st)
        idx = np.int64(r & byte)
        rabs = (r >> np.uint64(9)) & low23
        x = np.float32(rabs) * wi_float[idx]
        if (r >> np.uint64(8)) & one:
            x = -x
        if rabs < ki_float[idx]:
            return np.float32(x)
        if idx == 0:  # the tail beyond the base strip
            while True:
                xx = -ziggurat_nor_inv_r_f * np.float32(math.log1p(-_pcg64_float(st)))
                yy = -np.float32(math.log1p(-_pcg64_float(st)))
                if yy + yy > xx * xx:
                    tail = ziggurat_nor_r_f + xx
                    return np.float32(-tail if (rabs >> np.uint64(8)) & one else tail)
        wedge = (fi_float[idx - 1] - fi_float[idx]) * _pcg64_float(st) + fi_float[idx]
        xd = np.float64(x)
        if np.float64(wedge) < math.exp(-0.5 * xd * xd):
            return np.float32(x)


@njit(cache=True, nogil=True)
def grey_sample(image: F32, k: np.float32, step: int) -> F32:  # pragma: no cover - compiled
    """The greys (the mean of the three values: their sum in order, over 3) of every
    ``step``-th row of ``image (N, 3)`` times ``k`` (rows 0, step, 2 * step, ...), ``image`` left
    as it is."""
    n = (image.shape[0] + step - 1) // step
    out = np.empty(n, np.float32)
    for j in range(n):
        i = j * step
        a, b, c = image[i, 0] * k, image[i, 1] * k, image[i, 2] * k
        out[j] = (a + b + c) / np.float32(3.0)
    return out


@njit(cache=True, nogil=True)
def scaled_levelled_bytes(
    image: F32, k: np.float32, black: np.float32, scale: np.float32, saturation: np.float32, toe: np.float32,
    state: npt.NDArray[np.uint64], sigma: np.float32,
) -> npt.NDArray[np.uint8]:  # fmt: skip  # pragma: no cover - compiled
    """``(N, 3) uint8`` of ``image`` times ``k`` (``image`` left as it is), in one pass: each
    row's grey (the mean of its three values) with the black level set (:func:`_levelled`), its
    colours ``saturation`` times further from it than from their own grey, plus ``sigma`` times
    one draw of numpy's ``standard_normal(dtype=np.float32)`` per row (:func:`_standard_normal`
    from the PCG64 ``state``, left as it is), rounded and clipped to 0..255 (:func:`_byte`)."""
    st = state.copy()
    out = np.empty(image.shape, np.uint8)
    for i in range(image.shape[0]):
        a, b, c = image[i, 0] * k, image[i, 1] * k, image[i, 2] * k
        g = (a + b + c) / np.float32(3.0)
        levelled = _levelled(g, black, scale, toe)
        nz = _standard_normal(st) * sigma
        out[i, 0] = _byte((a - g) * saturation + levelled, nz)
        out[i, 1] = _byte((b - g) * saturation + levelled, nz)
        out[i, 2] = _byte((c - g) * saturation + levelled, nz)
    return out
