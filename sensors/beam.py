"""A LiDAR beam's width at depth edges: mixed returns and dual returns.

A real beam is not a ray: its spot widens with range (``beam_divergence_mrad``, horizontal and
vertical). Where it straddles an edge between two surfaces, part of its light returns from
each, and the sensor sees two echoes. Echoes closer in range than a pulse's length
(:data:`MERGE_M`) overlap and are read as one, at a range between the two (a mixed return: a
point on neither surface, left unlabelled: class NONE, instance 0, unless it lies within
:data:`ON_SURFACE_M` of the stronger surface); farther apart they stay apart, and a sensor in
its ``strongest`` return mode reports the stronger, in ``dual`` mode the strongest and the last
(the second strongest where those coincide: Velodyne's VLP-16 and HDL-32E manuals, dual return
mode; Hesai's Pandar manuals: "the last return, and the strongest; if they coincide, the second
strongest"). With two echoes at most, dual mode reports both. Each echo is reported along the
shot's own direction, as a sensor does: an edge reaches out by up to half a spot.

Only shots next to an edge are looked at closely: those whose neighbour in the grid (the same
ring's next column, or the same column's next ring) hits something else (another class or
instance, or nothing). Across each such shot's spot, along the edge's axis, :data:`SLICES`
evenly spaced rays (its own ray in the middle) are cast at the shot's time; the surfaces they
meet share the spot's power by their count. The shot's own surface gives one echo, the most
frequent other surface the other; light on a third surface or on nothing is lost.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from sensors.hits import RayHits

MERGE_M = 1.0  # echoes closer than this overlap into one (a pulse of a few ns is about a metre long)
ON_SURFACE_M = 0.05  # a merged echo this close to the stronger surface keeps that surface's labels
SLICES = 5  # rays across a spot (odd: the shot's own ray in the middle)
OFFSETS = (np.arange(SLICES) - SLICES // 2) / SLICES  # each slice's centre, in spot widths from the middle


@dataclass(frozen=True, slots=True)
class BeamEchoes:
    """Per echo (rows): ``hits`` (range, labels, normal, part of the surface it comes from),
    ``ray: (M,) intp`` the shot it belongs to and ``share: (M,) float64`` the part of the
    shot's power it carries (1 off edges; a merged echo's summed power against its surface's
    own at its range). The first rows are the shots' own, in order; ``dual`` adds rows after."""

    hits: RayHits
    ray: npt.NDArray[np.intp]
    share: npt.NDArray[np.float64]


def surface_codes(hits: RayHits) -> npt.NDArray[np.int64]:
    """``(N,)`` one number per surface met (class and instance); -1 where nothing was met."""
    code = (hits.semantic_class.astype(np.int64) << 32) | hits.instance_id.astype(np.int64)
    return np.where(hits.hit, code, -1)


def edge_shots(
    hits: RayHits, beams: int, azimuth_steps: int, left_out: npt.NDArray[np.bool_]
) -> tuple[npt.NDArray[np.intp], npt.NDArray[np.intp]]:
    """The shots (``ring * azimuth_steps + column``) next to an edge across the grid (axis 0:
    a neighbour in the same ring) and up it (axis 1: in the same column), ``left_out`` never."""
    code = surface_codes(hits)
    grid = np.arange(beams * azimuth_steps).reshape(beams, azimuth_steps)
    out = []
    for a, b in ((grid, np.roll(grid, -1, axis=1)), (grid[:-1], grid[1:])):
        differ = code[a] != code[b]
        mine = np.zeros(beams * azimuth_steps, np.bool_)
        mine[a[differ]] = True
        mine[b[differ]] = True
        out.append(np.flatnonzero(mine & ~left_out))
    return out[0], out[1]


def spot_directions(dirs_lidar: npt.NDArray[np.float64], axis: int, width_rad: float) -> npt.NDArray[np.float64]:
    """``(N * SLICES, 3)`` unit directions across each direction's spot (LiDAR frame), shot by
    shot: turned about the LiDAR's z axis (axis 0) or raised (axis 1) by each slice's offset."""
    az = np.arctan2(dirs_lidar[:, 1], dirs_lidar[:, 0])[:, None]
    el = np.arcsin(np.clip(dirs_lidar[:, 2], -1.0, 1.0))[:, None]
    step = np.broadcast_to(OFFSETS * width_rad, (dirs_lidar.shape[0], SLICES))
    az, el = (az + step, el + 0.0 * step) if axis == 0 else (az + 0.0 * step, el + step)
    return np.stack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)], axis=-1).reshape(-1, 3)


def beam_echoes(
    hits: RayHits,
    spots: list[tuple[npt.NDArray[np.intp], RayHits]],
    power_of: Callable[[RayHits], npt.NDArray[np.float64]],
    dual: bool,
) -> BeamEchoes:
    """The echoes of a sweep's shots: ``hits`` are the shots' own, ``spots`` per axis the shots
    looked at closely and what their :data:`SLICES` rays each met (shot by shot), ``power_of``
    the received power of a whole spot on each hit (reflectance / range^2 in any unit);
    ``dual`` adds the weaker of two separate echoes."""
    n = hits.range_m.shape[0]
    code = surface_codes(hits)
    best_other = np.zeros(n)  # the other surface's share of each shot's spot
    own_share = np.ones(n)
    other_src: list[RayHits] = []
    other_at = np.full(n, -1, np.intp)  # row in the concatenated other-surface hits
    own_range = hits.range_m.astype(np.float64).copy()
    other_range = np.zeros(n)
    offset = 0
    for shots, sub in spots:
        if shots.size == 0:
            continue
        c = surface_codes(sub).reshape(-1, SLICES)
        r = np.where(c >= 0, sub.range_m.reshape(-1, SLICES).astype(np.float64), 0.0)
        mine = c == code[shots][:, None]
        counts = (c[:, :, None] == c[:, None, :]).sum(axis=2)  # how many slices meet each slice's surface
        candidate = np.where((c >= 0) & ~mine, counts, 0)
        pick = np.argmax(candidate, axis=1)
        f_other = candidate[np.arange(shots.size), pick] / SLICES
        better = f_other > best_other[shots]
        at = shots[better]
        best_other[at] = f_other[better]
        own_share[at] = mine[better].sum(axis=1) / SLICES
        n_own = np.maximum(mine[better].sum(axis=1), 1)
        own_range[at] = np.where(code[at] >= 0, (r[better] * mine[better]).sum(axis=1) / n_own, own_range[at])
        same = c[better] == c[better, pick[better]][:, None]
        other_range[at] = (r[better] * same).sum(axis=1) / same.sum(axis=1)
        rows = np.flatnonzero(better) * SLICES + pick[better]
        other_src.append(_rows(sub, rows))
        other_at[at] = offset + np.arange(at.size)
        offset += at.size
    range_m, cls, inst = hits.range_m.copy(), hits.semantic_class.copy(), hits.instance_id.copy()
    normal, part = hits.normal.copy(), hits.part.copy()
    share = np.ones(n)
    edge = np.flatnonzero(best_other > 0)
    if edge.size == 0:
        return BeamEchoes(hits, np.arange(n, dtype=np.intp), share)
    other = _cat(other_src)
    o = _rows(other, other_at[edge])
    o = RayHits(other_range[edge].astype(np.float32), o.semantic_class, o.instance_id, o.normal, o.part)
    p_b = best_other[edge] * power_of(o)
    own_hit = code[edge] >= 0
    mine_here = _rows(hits, edge)
    own_at_range = RayHits(own_range[edge].astype(np.float32), mine_here.semantic_class, mine_here.instance_id,
                           mine_here.normal, mine_here.part)  # fmt: skip
    p_a = np.where(own_hit, own_share[edge] * power_of(own_at_range), 0.0)
    r_a, r_b = own_range[edge], other_range[edge]
    b_wins = p_b > p_a
    merge = own_hit & (np.abs(r_a - r_b) < MERGE_M)
    # one echo: the stronger of two apart, or the two merged at their power-weighted range
    r_a_met = np.where(own_hit, r_a, 0.0)
    r_one = np.where(merge, (p_a * r_a_met + p_b * r_b) / np.maximum(p_a + p_b, 1e-300), np.where(b_wins, r_b, r_a))
    r_strong = np.where(b_wins, r_b, r_a)
    range_m[edge] = r_one.astype(np.float32)
    take = b_wins
    cls[edge[take]], inst[edge[take]] = o.semantic_class[take], o.instance_id[take]
    normal[edge[take]], part[edge[take]] = o.normal[take], o.part[take]
    off = merge & (np.abs(r_one - r_strong) > ON_SURFACE_M)
    cls[edge[off]], inst[edge[off]] = 0, 0
    p_strong = np.where(b_wins, p_b / np.maximum(best_other[edge], 1e-300), p_a / np.maximum(own_share[edge], 1e-300))
    met = np.isfinite(r_one)
    ratio = np.where(met, np.where(met, r_strong, 1.0) / np.maximum(np.where(met, r_one, 1.0), 1e-6), 1.0)
    whole = p_strong * ratio**2  # the stronger surface's whole-spot power at r_one
    share[edge] = np.where(
        merge, (p_a + p_b) / np.maximum(whole, 1e-300), np.where(b_wins, best_other[edge], own_share[edge])
    )
    out = RayHits(range_m, cls, inst, normal, part)
    ray_of = np.arange(n, dtype=np.intp)
    apart = np.flatnonzero(own_hit & ~merge)
    if dual and apart.size:
        s, weak_is_own = edge[apart], b_wins[apart]
        mine = _rows(hits, s)
        theirs = _rows(o, apart)
        add = RayHits(
            np.where(weak_is_own, r_a[apart], r_b[apart]).astype(np.float32),
            np.where(weak_is_own, mine.semantic_class, theirs.semantic_class),
            np.where(weak_is_own, mine.instance_id, theirs.instance_id),
            np.where(weak_is_own[:, None], mine.normal, theirs.normal).astype(np.float32),
            np.where(weak_is_own, mine.part, theirs.part),
        )
        out = _cat([out, add])
        ray_of = np.concatenate([ray_of, s]).astype(np.intp)
        share = np.concatenate([share, np.where(weak_is_own, own_share[s], best_other[s])])
    return BeamEchoes(out, ray_of, share)


def _rows(hits: RayHits, at: npt.NDArray[np.intp]) -> RayHits:
    return RayHits(*(getattr(hits, f)[at] for f in RayHits.__slots__))


def _cat(parts: list[RayHits]) -> RayHits:
    return RayHits(*(np.concatenate([getattr(p, f) for p in parts]) for f in RayHits.__slots__))
