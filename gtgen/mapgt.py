"""Map ground truth of a frame: the HD map's elements around the ego in its frame, the lane the
ego drives on and its route ahead, and bird's-eye rasters (map layers and object footprints).

Written under ``map/`` in the run folder (:class:`MapSink`):

- ``map/map.json``: the whole map in the map frame (elements, lane graph, junctions);
- ``map/vectors/NNNNNN.json``: ``frame``, ``timestamp``, ``map_SE3_ego`` (4x4, row-major),
  ``ego_lane``, ``route_ahead`` (SUMO edge ids), ``range_m`` (half extents x, y),
  ``resolution_m``, ``elements`` (``id``, ``type``, ``points`` as ego-frame x, y in metres,
  and ``pattern``, ``colour``, ``lane`` where they apply);
- ``map/raster/NNNNNN.npz``: ``layers`` ``(L, H, W) uint8`` (0/1) named by ``names``; row 0 is
  the far end ahead (+x), column 0 the far left (+y).
"""

from __future__ import annotations

import json
import shutil
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import numpy.typing as npt

from gtgen.errors import SinkError
from gtgen.npz import npz_bytes
from gtgen.objects import ObjectBoxes
from networks.classes import SemanticClass
from networks.geometry import SE3
from networks.hdmap import RASTER_LAYERS, HdMap, element_json, raster_px


@dataclass(frozen=True, slots=True)
class MapFrame:
    """One frame's map ground truth: ``vectors`` (JSON-ready, see the module) and ``raster``
    ``(L, H, W) uint8`` in the order of :data:`networks.hdmap.RASTER_LAYERS`."""

    vectors: dict[str, Any]
    raster: npt.NDArray[np.uint8]


@dataclass(frozen=True, slots=True)
class MapRange:
    half_x_m: float = 30.0  # ahead and behind (60 m x 30 m, as in the vector-mapping literature)
    half_y_m: float = 15.0  # left and right
    resolution_m: float = 0.5


def map_frame(
    hdmap: HdMap, frame_index: int, timestamp_ns: int, map_SE3_ego: SE3, objects: ObjectBoxes, ego_lane: str,
    route_ahead: tuple[str, ...], rng: MapRange,
) -> MapFrame:  # fmt: skip
    """The map ground truth of one frame (object footprints from the labelled ``objects``)."""
    view = hdmap.view(map_SE3_ego, rng.half_x_m, rng.half_y_m)
    raster = hdmap.raster(map_SE3_ego, rng.half_x_m, rng.half_y_m, rng.resolution_m, view)
    _footprints(raster, objects, rng)
    matrix = np.eye(4)
    matrix[:3, :3], matrix[:3, 3] = map_SE3_ego.rotation, map_SE3_ego.translation
    vectors = {
        "frame": frame_index, "timestamp": round(timestamp_ns / 1e9, 3), "map_SE3_ego": np.round(matrix, 6).tolist(),
        "ego_lane": ego_lane, "route_ahead": list(route_ahead), "range_m": [rng.half_x_m, rng.half_y_m],
        "resolution_m": rng.resolution_m, "elements": [element_json(e, p) for e, p in view],
    }  # fmt: skip
    return MapFrame(vectors, raster)


def _footprints(raster: npt.NDArray[np.uint8], objects: ObjectBoxes, rng: MapRange) -> None:
    for i, xy in enumerate(objects.footprints_xy()):
        cls = SemanticClass(int(objects.semantic_class[i]))
        if not cls.is_agent:
            continue
        pts = raster_px(xy, rng.half_x_m, rng.half_y_m, rng.resolution_m)
        cv2.fillPoly(raster[RASTER_LAYERS.index(cls.label)], [pts], 1, cv2.LINE_8, 3)


class MapSink:
    """``map/``: the static map once, and per frame its vectors (JSON) and rasters (NPZ)."""

    def __init__(self, folder: Path, static_json: Path, keep_frames: int = 0) -> None:
        from gtgen.sinks.folder import PartialFolder

        self._folder = PartialFolder(folder, ("vectors", "raster"), keep_frames)
        self._static = static_json

    def encode(self, record: Any, images: Any) -> dict[str, bytes]:
        frame: MapFrame | None = record.map
        if frame is None:
            return {}
        name = f"{record.frame_index:06d}"
        return {
            f"vectors/{name}.json": json.dumps(frame.vectors, separators=(",", ":")).encode(),
            f"raster/{name}.npz": npz_bytes(layers=frame.raster, names=np.asarray(RASTER_LAYERS)),
        }

    def write(self, encoded: dict[str, bytes]) -> None:
        self._folder.write_files(encoded)

    def close(self) -> None:
        try:
            shutil.copyfile(self._static, self._folder.partial / "map.json")
        except OSError as err:
            raise SinkError(f"{self._folder.partial / 'map.json'}: cannot write: {err.strerror}") from err
        self._folder.commit()

    def abort(self) -> None:
        self._folder.discard()

    def keep(self) -> None:
        pass  # each frame's files are written whole


def load_map_frame(run_dir: Path, frame_index: int) -> tuple[dict[str, Any], dict[str, npt.NDArray[np.uint8]]]:
    """A frame's map vectors (the JSON) and raster layers by name, read back from ``run_dir/map``."""
    name = f"{frame_index:06d}"
    vectors = json.loads((run_dir / "map" / "vectors" / f"{name}.json").read_text())
    with np.load(run_dir / "map" / "raster" / f"{name}.npz") as data:
        layers = {str(n): data["layers"][k] for k, n in enumerate(data["names"])}
    return vectors, layers
