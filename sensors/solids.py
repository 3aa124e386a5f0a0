"""Where straight lines run inside the static world's solids (buildings, trees, poles, piers).

The world builds these as prisms: vertical walls around a footprint and a top (no floor), so a
horizontal line crosses their walls an even number of times and lies inside a solid between
crossings 1 and 2, 3 and 4, ... (ray parity, as Open3D's ``compute_occupancy`` counts it, along
lines that never meet a floor or a top). The rest of the world (roads, sidewalks, terrain) is
surface, not volume.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from networks.classes import SemanticClass
from networks.mesh import ClassedMesh
from sensors.o3d import RaycastingScene, o3c

SOLID_CLASSES = (SemanticClass.BUILDING, SemanticClass.VEGETATION, SemanticClass.POLE)


@dataclass(frozen=True, slots=True)
class Spans:
    """Where lines run inside solids: ``line: (S,) int64`` the line of each span, ``t0, t1: (S,)
    float64`` its ends (parameters along the line), ``semantic_class: (S,) uint8`` the solid's."""

    line: npt.NDArray[np.int64]
    t0: npt.NDArray[np.float64]
    t1: npt.NDArray[np.float64]
    semantic_class: npt.NDArray[np.uint8]


class Solids:
    """The solids of a static mesh (its triangles of :data:`SOLID_CLASSES`) in a scene of their own."""

    def __init__(self, static: ClassedMesh) -> None:
        keep = np.isin(static.triangle_class, np.asarray(SOLID_CLASSES, np.uint8))
        self._class = static.triangle_class[keep]
        self._scene = RaycastingScene()
        if keep.any():
            self._scene.add_triangles(o3c.Tensor.from_numpy(np.ascontiguousarray(static.vertices_m, np.float32)),
                                      o3c.Tensor.from_numpy(static.triangles[keep].astype(np.uint32)))  # fmt: skip

    def spans(self, start_m: npt.NDArray[np.float64], end_m: npt.NDArray[np.float64]) -> Spans:
        """The spans inside solids of the lines ``start -> end`` (``(N, 3)`` each, map frame; ``t``
        in 0..1 from start to end). A line should start and end outside every solid."""
        rays = np.concatenate([start_m, end_m - start_m], axis=1).astype(np.float32)
        found = self._scene.list_intersections(o3c.Tensor.from_numpy(rays))
        splits = found["ray_splits"].numpy().astype(np.int64)
        t = found["t_hit"].numpy().astype(np.float64)
        prim = found["primitive_ids"].numpy().astype(np.int64)
        line = np.repeat(np.arange(rays.shape[0], dtype=np.int64), np.diff(splits))
        inside = (t >= 0) & (t <= 1)
        line, t, prim = line[inside], t[inside], prim[inside]
        order = np.lexsort((t, line))
        line, t, prim = line[order], t[order], prim[order]
        rank = np.arange(line.shape[0]) - np.searchsorted(line, line)  # crossing number within its line
        enter = np.flatnonzero(rank % 2 == 0)
        paired = enter[(enter + 1 < line.shape[0])]
        paired = paired[line[np.minimum(paired + 1, line.shape[0] - 1)] == line[paired]]
        return Spans(line[paired], t[paired], t[paired + 1], self._class[prim[paired]])
