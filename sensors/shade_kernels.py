"""Compiled loops (Numba) of the realistic camera: the same float32 arithmetic as the numpy
forms they replace, one pixel at a time instead of one array pass per step (no temporaries the
size of the image). Compiled on first use and cached beside this file."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
from numba import njit

F32 = npt.NDArray[np.float32]


@njit(cache=True, nogil=True)
def shadow_rays(
    origin: F32, dirs: F32, range_m: F32, normal: F32, sun: F32, max_range_m: np.float32, lift_m: np.float32
) -> tuple[npt.NDArray[np.int64], F32]:  # pragma: no cover - compiled
    """The rows that need a shadow ray (a hit nearer than ``max_range_m`` whose side facing the
    camera faces the ``sun``) and those rays ``(K, 6)``: from the hit, lifted ``lift_m`` off the
    surface towards the camera's side, along ``sun`` (as :func:`sensors.camera.sun_visibility`)."""
    n = range_m.shape[0]
    at = np.empty(n, np.int64)
    k = 0
    for i in range(n):
        r = range_m[i]
        if not (r < max_range_m):  # also inf and nan
            continue
        n0, n1, n2 = normal[i, 0], normal[i, 1], normal[i, 2]
        if n0 * dirs[i, 0] + n1 * dirs[i, 1] + n2 * dirs[i, 2] > 0:
            n0, n1, n2 = -n0, -n1, -n2
        if n0 * sun[0] + n1 * sun[1] + n2 * sun[2] > 0:
            at[k] = i
            k += 1
    rays = np.empty((k, 6), np.float32)
    for j in range(k):
        i = at[j]
        r = range_m[i]
        n0, n1, n2 = normal[i, 0], normal[i, 1], normal[i, 2]
        if n0 * dirs[i, 0] + n1 * dirs[i, 1] + n2 * dirs[i, 2] > 0:
            n0, n1, n2 = -n0, -n1, -n2
        rays[j, 0] = (origin[0] + dirs[i, 0] * r) + n0 * lift_m
        rays[j, 1] = (origin[1] + dirs[i, 1] * r) + n1 * lift_m
        rays[j, 2] = (origin[2] + dirs[i, 2] * r) + n2 * lift_m
        rays[j, 3] = sun[0]
        rays[j, 4] = sun[1]
        rays[j, 5] = sun[2]
    return at[:k], rays
