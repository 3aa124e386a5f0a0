"""Counting sensor returns per object."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

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
