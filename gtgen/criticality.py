"""Criticality of every labelled object: time to collision with the ego under constant
velocity, distance to the ego's predicted path, all in the ego frame (numpy, all at once).

Time to collision: the first time ``t >= 0`` at which the object's box footprint, moving at
its velocity relative to the ego (``vx, vy`` of the labels) without turning, touches the
ego's footprint (the ``ego_length`` x ``ego_width`` rectangle centred on the ego frame's
origin, along x). Two rectangles overlap exactly when they overlap along each of their four
edge normals, so the time is where the four intervals of overlap in time meet. 0 when they
overlap already; empty (NaN) when the object does not come to touch the ego (moving away,
standing still relative to it, or passing beside it: a car overtaken in the next lane).

Path distance: from the object's centre to the ego's path over the next ``PATH_HORIZON_S``
at its speed: the segment from the ego's origin along its heading (x), in the plane.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

F64 = npt.NDArray[np.float64]
PATH_HORIZON_S = 3.0


def time_to_collision(p_xy: F64, v_xy: F64, yaw_rad: F64, lw_m: F64, ego_lw_m: F64) -> F64:
    """``(N,)`` seconds until the box footprints of the objects (centres ``p_xy``, relative
    velocities ``v_xy``, headings ``yaw_rad``, lengths and widths ``lw_m``, all ``(N, ...)`` in
    the ego frame) first touch the ego's (``ego_lw_m``, centred on the origin); NaN: never."""
    cos, sin = np.cos(yaw_rad), np.sin(yaw_rad)
    ones, zeros = np.ones_like(cos), np.zeros_like(cos)
    axes = np.stack([np.stack([ones, zeros], -1), np.stack([zeros, ones], -1),  # the ego's edge normals
                     np.stack([cos, sin], -1), np.stack([-sin, cos], -1)], axis=1)  # the object's  # fmt: skip
    along = np.stack([cos, sin], -1)[:, None, :]  # the object's length and width directions
    across = np.stack([-sin, cos], -1)[:, None, :]
    reach = (np.abs(axes[..., 0]) * ego_lw_m[0] / 2 + np.abs(axes[..., 1]) * ego_lw_m[1] / 2
             + np.abs(np.sum(axes * along, -1)) * lw_m[:, None, 0] / 2
             + np.abs(np.sum(axes * across, -1)) * lw_m[:, None, 1] / 2)  # half-width of the overlap slab  # fmt: skip
    offset = np.einsum("nkj,nj->nk", axes, p_xy)
    rate = np.einsum("nkj,nj->nk", axes, v_xy)
    with np.errstate(divide="ignore", invalid="ignore"):
        t1, t2 = (-reach - offset) / rate, (reach - offset) / rate
    still = rate == 0.0
    inside_now = np.abs(offset) <= reach
    enter = np.where(still, np.where(inside_now, -np.inf, np.inf), np.minimum(t1, t2)).max(axis=1)
    leave = np.where(still, np.where(inside_now, np.inf, -np.inf), np.maximum(t1, t2)).min(axis=1)
    touches = (enter <= leave) & (leave >= 0.0)
    return np.where(touches, np.maximum(enter, 0.0), np.nan)


def path_distance(p_xy: F64, ego_speed_mps: float) -> F64:
    """``(N,)`` metres from each point to the segment ``[0, speed * PATH_HORIZON_S]`` on x."""
    x = np.clip(p_xy[:, 0], 0.0, max(ego_speed_mps, 0.0) * PATH_HORIZON_S)
    return np.hypot(p_xy[:, 0] - x, p_xy[:, 1])
