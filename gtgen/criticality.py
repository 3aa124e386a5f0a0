"""Criticality of every labelled object: time to collision with the ego under constant
velocity, distance to the ego's predicted path, all in the ego frame (numpy, all at once).

Time to collision: the first time ``t >= 0`` at which the object's centre, moving at its
velocity relative to the ego (``vx, vy`` of the labels), comes within ``collision_radius``
of the ego's origin: ``|p + v t| = r`` with ``r`` the half-diagonal of the object's footprint
plus the ego's. 0 when already within; empty (NaN) when the object is not closing in or its
straight course passes farther than ``r``.

Path distance: from the object's centre to the ego's path over the next ``PATH_HORIZON_S``
at its speed: the segment from the ego's origin along its heading (x), in the plane.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

F64 = npt.NDArray[np.float64]
PATH_HORIZON_S = 3.0


def collision_radius(lw_m: F64, ego_lw_m: F64) -> F64:
    """``(N,)`` the object's footprint half-diagonal plus the ego's."""
    return np.hypot(lw_m[:, 0] / 2, lw_m[:, 1] / 2) + float(np.hypot(ego_lw_m[0] / 2, ego_lw_m[1] / 2))


def time_to_collision(p_xy: F64, v_xy: F64, radius_m: F64) -> F64:
    """``(N,)`` seconds until ``|p + v t|`` first equals ``radius_m`` (NaN: never)."""
    a = np.einsum("ij,ij->i", v_xy, v_xy)
    b = 2.0 * np.einsum("ij,ij->i", p_xy, v_xy)
    c = np.einsum("ij,ij->i", p_xy, p_xy) - radius_m**2
    disc = b * b - 4.0 * a * c
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (-b - np.sqrt(np.maximum(disc, 0.0))) / (2.0 * a)
    hits = (b < 0) & (a > 0) & (disc >= 0)
    return np.where(c <= 0, 0.0, np.where(hits, t, np.nan))


def path_distance(p_xy: F64, ego_speed_mps: float) -> F64:
    """``(N,)`` metres from each point to the segment ``[0, speed * PATH_HORIZON_S]`` on x."""
    x = np.clip(p_xy[:, 0], 0.0, max(ego_speed_mps, 0.0) * PATH_HORIZON_S)
    return np.hypot(p_xy[:, 0] - x, p_xy[:, 1])
