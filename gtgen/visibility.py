"""Camera visibility from the rays: visible pixels against the unoccluded silhouette.

For each labelled object, the pixels of its instance mask are its visible pixels. Its
unoccluded silhouette is found by casting the camera's rays over the object's clipped 2D
box against the object alone (its own mesh in the frame's scene, with everything else taken
away), so the rays that pass through it count whatever lies in front of it. Boxes larger than ``MAX_SAMPLES`` pixels
are sampled on a regular pixel grid (stride s); visible and silhouette pixels are then
counted on the same grid.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

import numpy as np
import numpy.typing as npt

from gtgen.counting import count_hits
from networks.geometry import SE3
from sensors.pinhole import Pinhole

MAX_SAMPLES = 4096
F64 = npt.NDArray[np.float64]


class SilhouetteCaster(Protocol):
    """The frame's scene as the labels use it (:class:`sensors.engine.Scene`)."""

    def hits_alone(self, rays: npt.NDArray[np.float32], instance_id: npt.NDArray[np.uint32]) -> npt.NDArray[np.bool_]:
        """Whether ray ``i`` meets agent ``instance_id[i]`` with everything else taken away."""
        ...


@dataclass(frozen=True, slots=True)
class CameraVisibility:
    """Per object: ``visible_px: (N,) int64`` pixels of the instance mask;
    ``fraction: (N,) float64`` visible over unoccluded silhouette (0 when not in the image);
    ``modal_px: (N, 4) float64`` tight left, top, right, bottom around the visible pixels
    (NaN when none); ``occluded: (N,) int8`` 0..3; ``visibility_bin: (N,) int8`` 1..4 (nuScenes)."""

    visible_px: npt.NDArray[np.int64]
    fraction: F64
    modal_px: F64
    occluded: npt.NDArray[np.int8]
    visibility_bin: npt.NDArray[np.int8]


def occlusion_level(fraction: F64) -> npt.NDArray[np.int8]:
    """0 fully visible (>= 0.8), 1 partly (>= 0.4), 2 largely occluded (> 0), 3 not visible."""
    return np.select([fraction >= 0.8, fraction >= 0.4, fraction > 0.0], [0, 1, 2], 3).astype(np.int8)


def visibility_bin(fraction: F64) -> npt.NDArray[np.int8]:
    """nuScenes bins: 1 = 0-40 %, 2 = 40-60 %, 3 = 60-80 %, 4 = 80-100 %."""
    return (1 + np.searchsorted([0.4, 0.6, 0.8], fraction, side="right")).astype(np.int8)


def modal_boxes(instance_mask: npt.NDArray[np.uint32], track_ids: npt.NDArray[np.uint32]) -> F64:
    """Tight boxes (left, top, right, bottom; pixel centres) around each id's mask pixels."""
    out = np.full((track_ids.shape[0], 4), np.nan)
    flat = instance_mask.ravel()
    idx = np.flatnonzero(flat)
    if idx.size == 0 or track_ids.size == 0:
        return out
    ids = flat[idx]
    order = np.argsort(ids, kind="stable")
    ids, idx = ids[order], idx[order]
    starts = np.flatnonzero(np.r_[True, ids[1:] != ids[:-1]])
    width = instance_mask.shape[1]
    u, v = idx % width, idx // width
    boxes = np.stack([np.minimum.reduceat(u, starts), np.minimum.reduceat(v, starts),
                      np.maximum.reduceat(u, starts), np.maximum.reduceat(v, starts)], axis=1)  # fmt: skip
    uniq = ids[starts]
    pos = np.clip(np.searchsorted(uniq, track_ids), 0, uniq.shape[0] - 1)
    found = uniq[pos] == track_ids
    out[found] = boxes[pos[found]]
    return out


def _grid(box: F64, stride: int) -> tuple[npt.NDArray[np.int64], npt.NDArray[np.int64]]:
    us = np.arange(math.ceil(box[0]), math.floor(box[2]) + 1, stride)
    vs = np.arange(math.ceil(box[1]), math.floor(box[3]) + 1, stride)
    v, u = np.meshgrid(vs, us, indexing="ij")
    return u.ravel(), v.ravel()


def _stride(box: F64) -> int:
    area = max(box[2] - box[0] + 1, 1) * max(box[3] - box[1] + 1, 1)
    return max(1, math.ceil(math.sqrt(area / MAX_SAMPLES)))


def camera_visibility(
    pinhole: Pinhole,
    map_SE3_cam: SE3,
    track_ids: npt.NDArray[np.uint32],
    clipped_px: F64,
    instance_mask: npt.NDArray[np.uint32],
    scene: SilhouetteCaster,
    visible_px: npt.NDArray[np.integer] | None = None,
    modal_px: F64 | None = None,
) -> CameraVisibility:
    """``track_ids`` and ``clipped_px`` are row-aligned (one row per labelled object);
    ``visible_px`` and ``modal_px``: each object's pixels in ``instance_mask`` and their box
    (:func:`modal_boxes`), if the caller has them already."""
    n = track_ids.shape[0]
    grids = []
    for i in range(n):
        box = clipped_px[i]
        if not np.all(np.isfinite(box)):
            grids.append((np.zeros(0, np.int64), np.zeros(0, np.int64)))
            continue
        u, v = _grid(np.clip(box, 0, [pinhole.width_px - 1, pinhole.height_px - 1] * 2), _stride(box))
        grids.append((u, v))
    owner = np.concatenate([np.full(g[0].shape[0], i) for i, g in enumerate(grids)] or [np.zeros(0, int)])
    u_all = np.concatenate([g[0] for g in grids] or [np.zeros(0, np.int64)])
    v_all = np.concatenate([g[1] for g in grids] or [np.zeros(0, np.int64)])
    silhouette = _silhouette_hits(pinhole, map_SE3_cam, scene, track_ids[owner], u_all, v_all)
    visible = instance_mask[v_all, u_all] == track_ids[owner] if owner.size else np.zeros(0, bool)
    sil_count = np.bincount(owner, weights=silhouette, minlength=n)
    vis_count = np.bincount(owner, weights=visible & silhouette, minlength=n)
    with np.errstate(invalid="ignore", divide="ignore"):
        fraction = np.where(sil_count > 0, vis_count / sil_count, 0.0)
    counted = count_hits(instance_mask.ravel(), track_ids) if visible_px is None else visible_px
    mask_px = counted.astype(np.int64)
    fraction = np.where(mask_px > 0, fraction, 0.0)
    modal = modal_boxes(instance_mask, track_ids) if modal_px is None else modal_px
    return CameraVisibility(mask_px, fraction, modal, occlusion_level(fraction), visibility_bin(fraction))


def _silhouette_hits(
    pinhole: Pinhole, map_SE3_cam: SE3, scene: SilhouetteCaster, instance_id: npt.NDArray[np.uint32],
    u: npt.NDArray[np.int64], v: npt.NDArray[np.int64],
) -> npt.NDArray[np.bool_]:  # fmt: skip
    """Whether the ray of pixel (u, v) passes through agent ``instance_id`` (others ignored)."""
    if u.size == 0:
        return np.zeros(0, bool)
    d = pinhole.pixel_directions(u, v)
    rays = np.concatenate([np.broadcast_to(map_SE3_cam.translation, d.shape), map_SE3_cam.rotate(d)], axis=1)
    return scene.hits_alone(rays.astype(np.float32), instance_id)
