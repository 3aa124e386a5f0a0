"""What a cast returns per ray (no Open3D here: the writer process reads these types)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt


@dataclass(frozen=True, slots=True)
class RayHits:
    """Per ray: ``range_m: (N,) float32`` (inf where nothing was hit),
    ``semantic_class: (N,) uint8``, ``instance_id: (N,) uint32`` (0: static world),
    ``normal: (N, 3) float32`` unit surface normals in the rays' frame, ``part: (N,) uint8``
    what the surface is made of (:class:`sensors.parts.Part`; 0: the static world, by class)."""

    range_m: npt.NDArray[np.float32]
    semantic_class: npt.NDArray[np.uint8]
    instance_id: npt.NDArray[np.uint32]
    normal: npt.NDArray[np.float32]
    part: npt.NDArray[np.uint8]

    @property
    def hit(self) -> npt.NDArray[np.bool_]:
        return np.isfinite(self.range_m)


@dataclass(frozen=True, slots=True)
class PairHits:
    """What the rays of ``(ray, agent)`` pairs hit on their agent alone (:func:`cast_agents_moving`):
    per pair ``range_m: (M,) float32`` (inf: missed), ``normal: (M, 3) float32`` unit map-frame
    normals and ``part: (M,) uint8``."""

    range_m: npt.NDArray[np.float32]
    normal: npt.NDArray[np.float32]
    part: npt.NDArray[np.uint8]
