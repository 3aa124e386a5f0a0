"""Counting sensor returns per object."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
from numba import njit

_BINCOUNT_LIMIT = 1 << 22


def count_hits(instance_ids: npt.NDArray[np.uint32], track_ids: npt.NDArray[np.uint32]) -> npt.NDArray[np.int32]:
    """How many of ``instance_ids`` equal each of ``track_ids``."""
    if track_ids.shape[0] == 0 or instance_ids.shape[0] == 0:
        return np.zeros(track_ids.shape[0], np.int32)
    top = int(max(instance_ids.max(), track_ids.max()))
    if top < _BINCOUNT_LIMIT:
        return np.bincount(instance_ids, minlength=top + 1)[track_ids].astype(np.int32)
    uniq, counts = np.unique(instance_ids, return_counts=True)
    pos = np.clip(np.searchsorted(uniq, track_ids), 0, uniq.shape[0] - 1)
    return np.where(uniq[pos] == track_ids, counts[pos], 0).astype(np.int32)


def mask_counts_and_boxes(
    instance_mask: npt.NDArray[np.uint32], track_ids: npt.NDArray[np.uint32]
) -> tuple[npt.NDArray[np.int32], npt.NDArray[np.float64]]:
    """Per track id of an ``(H, W)`` instance mask, in one pass over its pixels: how many pixels
    hold it (:func:`count_hits`) and the tight box around them (left, top, right, bottom pixel
    centres; NaN where none, and for id 0, as :func:`gtgen.visibility.modal_boxes`)."""
    ids = np.asarray(track_ids, np.uint32)
    if ids.shape[0] == 0:
        return np.zeros(0, np.int32), np.full((0, 4), np.nan)
    mask = np.ascontiguousarray(instance_mask, np.uint32)
    if mask.size == 0:
        return np.zeros(ids.shape[0], np.int32), np.full((ids.shape[0], 4), np.nan)
    uniq, back = np.unique(ids, return_inverse=True)
    counts, boxes = _counts_and_boxes(mask.reshape(mask.shape[0], -1), uniq)
    return counts[back.ravel()], boxes[back.ravel()]


@njit(cache=True, nogil=True)
def _counts_and_boxes(
    mask: npt.NDArray[np.uint32], ids: npt.NDArray[np.uint32]
) -> tuple[npt.NDArray[np.int32], npt.NDArray[np.float64]]:  # pragma: no cover - compiled
    """Per id of the sorted unique ``ids``: its pixels in ``mask`` and their box (NaN: none, or
    id 0). Runs of one id along a row are looked up once."""
    k = ids.shape[0]
    counts = np.zeros(k, np.int32)
    lo_u = np.full(k, mask.shape[1], np.int64)
    lo_v = np.full(k, mask.shape[0], np.int64)
    hi_u = np.full(k, -1, np.int64)
    hi_v = np.full(k, -1, np.int64)
    for v in range(mask.shape[0]):
        last = mask[v, 0]
        at = np.searchsorted(ids, last)
        j = at if at < k and ids[at] == last else -1
        for u in range(mask.shape[1]):
            value = mask[v, u]
            if value != last:
                last = value
                at = np.searchsorted(ids, value)
                j = at if at < k and ids[at] == value else -1
            if j < 0:
                continue
            counts[j] += 1
            if value == 0:
                continue
            lo_u[j] = min(lo_u[j], u)
            hi_u[j] = max(hi_u[j], u)
            lo_v[j] = min(lo_v[j], v)
            hi_v[j] = max(hi_v[j], v)
    boxes = np.full((k, 4), np.nan)
    for j in range(k):
        if hi_u[j] >= 0:
            boxes[j, 0], boxes[j, 1], boxes[j, 2], boxes[j, 3] = lo_u[j], lo_v[j], hi_u[j], hi_v[j]
    return counts, boxes
