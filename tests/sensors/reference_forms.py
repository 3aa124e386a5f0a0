"""The step-by-step forms the product's one-pass code is tested against: the camera's last steps
(greys, black level, levels, noise, bytes; :func:`sensors.photo.finished_bytes` does them in one
pass) and the LiDAR's reflectance by numpy (:func:`sensors.lidar.reflectance_of` in one compiled
pass). Test modules import it relatively (``from .reference_forms import ...``)."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
from numba import njit

from sensors.materials import REFLECTIVITY_BY_CLASS, RETRO_BY_CLASS
from sensors.parts import (
    COLOURED_BY_PAINT,
    PAINT_REFLECTIVITY_FLOOR,
    PAINT_REFLECTIVITY_PER_ALBEDO,
    REFLECTIVITY_BY_PART,
    RETRO_PARTS,
    part_albedo,
)
from sensors.photo import BLACK_STEP, BLACK_TOE, _black_of, _pcg64_words
from sensors.shade_kernels import _byte, _levelled, _standard_normal

F32 = npt.NDArray[np.float32]


@njit(nogil=True)
def grey_of(image: F32) -> F32:  # pragma: no cover - compiled
    """``(N,)`` the mean of each row of ``(N, 3)`` (numpy's ``mean(axis=1)``: the sum in order, over 3)."""
    out = np.empty(image.shape[0], np.float32)
    for i in range(image.shape[0]):
        out[i] = (image[i, 0] + image[i, 1] + image[i, 2]) / np.float32(3.0)
    return out


@njit(nogil=True)
def scaled_grey(image: F32, k: np.float32) -> F32:  # pragma: no cover - compiled
    """``image (N, 3)`` times ``k`` in place, and :func:`grey_of` the result, in one pass."""
    out = np.empty(image.shape[0], np.float32)
    for i in range(image.shape[0]):
        a, b, c = image[i, 0] * k, image[i, 1] * k, image[i, 2] * k
        image[i, 0], image[i, 1], image[i, 2] = a, b, c
        out[i] = (a + b + c) / np.float32(3.0)
    return out


@njit(nogil=True)
def levels(
    image: F32, grey: F32, black: np.float32, scale: np.float32, saturation: np.float32, toe: np.float32
) -> None:  # pragma: no cover - compiled
    """In place: ``image`` ``(N, 3)``'s grey less ``black`` times ``scale`` plus ``toe`` (when
    ``black > 0``; greys below ``black`` scaled onto 0..``toe``), its colours ``saturation``
    times further from that grey than from their own ``grey``: the stretch lifts brightness, not
    colour."""
    for i in range(image.shape[0]):
        g = grey[i]
        levelled = _levelled(g, black, scale, toe)
        for c in range(3):
            image[i, c] = (image[i, c] - g) * saturation + levelled


@njit(nogil=True)
def levelled_bytes(
    image: F32, grey: F32, black: np.float32, scale: np.float32, saturation: np.float32, toe: np.float32,
    noise: F32, sigma: np.float32,
) -> npt.NDArray[np.uint8]:  # fmt: skip  # pragma: no cover - compiled
    """:func:`levels` then :func:`to_bytes` in one pass: ``(N, 3) uint8`` (``image`` left as it is)."""
    out = np.empty(image.shape, np.uint8)
    for i in range(image.shape[0]):
        g = grey[i]
        levelled = _levelled(g, black, scale, toe)
        nz = noise[i, 0] * sigma
        for c in range(3):
            out[i, c] = _byte((image[i, c] - g) * saturation + levelled, nz)
    return out


@njit(nogil=True)
def to_bytes(image: F32, noise: F32, sigma: np.float32) -> npt.NDArray[np.uint8]:  # pragma: no cover - compiled
    """``(N, 3) uint8``: ``image`` plus ``noise * sigma`` (one draw per pixel, ``(N, 1)``),
    rounded and clipped to 0..255."""
    out = np.empty(image.shape, np.uint8)
    for i in range(image.shape[0]):
        nz = noise[i, 0] * sigma
        for c in range(3):
            out[i, c] = _byte(image[i, c], nz)
    return out


@njit(nogil=True)
def standard_normals_of_state(state: npt.NDArray[np.uint64], n: int) -> F32:  # pragma: no cover - compiled
    """``(n,)`` float32 draws of numpy's ``Generator.standard_normal(n, dtype=np.float32)`` on a
    PCG64 bit generator in ``state`` (:func:`sensors.shade_kernels._pcg64_next32`'s six words;
    left as it is), by :func:`sensors.shade_kernels._standard_normal`."""
    st = state.copy()
    out = np.empty(n, np.float32)
    for i in range(n):
        out[i] = _standard_normal(st)
    return out


def standard_normals(seed: int, n: int) -> F32:
    """``(n,)`` float32 draws equal to ``np.random.default_rng(seed).standard_normal(n,
    dtype=np.float32)``, by :func:`standard_normals_of_state`."""
    return standard_normals_of_state(_pcg64_words(seed), n)


def black_level(image: F32, grey: F32 | None = None) -> tuple[F32, np.float32, np.float32]:
    """:func:`auto_levels`' measure of ``(N, 3)`` ``image``: each pixel's grey (given, or the mean
    of its three values), the frame's black level and the stretch of the greys above it."""
    grey = grey_of(image) if grey is None else grey
    return (grey, *_black_of(grey[::BLACK_STEP]))


def auto_levels(image: F32, saturation: float) -> F32:
    """``(N, 3)`` display values 0..255 with the frame's black level set and colours
    ``saturation`` times further from their grey (:func:`black_level`, :func:`levels`), in
    place: :func:`sensors.photo.finished_bytes` without the scaling, the noise and the bytes."""
    grey, black, scale = black_level(image)
    levels(image, grey, black, scale, np.float32(saturation), np.float32(BLACK_TOE))
    return image


def lidar_reflectivity(semantic_class: npt.NDArray[np.uint8], part: npt.NDArray[np.uint8]) -> F32:
    """``(N,)`` LiDAR reflectivity of surfaces: by part on agents (glass and tyres weak, plates
    strong), by class on the static world."""
    return np.where(part > 0, REFLECTIVITY_BY_PART[part], REFLECTIVITY_BY_CLASS[semantic_class]).astype(np.float32)


def lidar_reflectance(
    semantic_class: npt.NDArray[np.uint8], part: npt.NDArray[np.uint8], instance_id: npt.NDArray[np.uint32]
) -> tuple[F32, npt.NDArray[np.bool_]]:
    """``(N,)`` LiDAR reflectivity of surfaces (painted parts by their instance's colour, other
    parts by the table, the static world by class) and whether each is retro-reflective
    (number plates; signs and road paint)."""
    out = lidar_reflectivity(semantic_class, part)
    painted = np.flatnonzero(np.isin(part, COLOURED_BY_PAINT))
    if painted.size:
        albedo = part_albedo(part[painted], instance_id[painted]).mean(axis=1)
        out[painted] = PAINT_REFLECTIVITY_FLOOR + PAINT_REFLECTIVITY_PER_ALBEDO * albedo
    retro = np.where(part > 0, np.isin(part, RETRO_PARTS), RETRO_BY_CLASS[semantic_class])
    return out, retro
