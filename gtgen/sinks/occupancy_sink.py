"""``occupancy/``: one ``NNNNNN/labels.npz`` per frame (the Occ3D layout, frames named by index).

Each ``labels.npz`` holds ``semantics`` ``(X, Y, Z) uint8`` (Occ3D-nuScenes classes, 17 = free),
``mask_lidar`` and ``mask_camera`` ``(X, Y, Z) bool`` (Occ3D's keys), and beside them
``semantics_native`` (our classes, 255 = free), ``instance`` ``(X, Y, Z) uint32`` (track id, 0:
none), ``flow`` and ``flow_relative`` ``(X, Y, Z, 3) float32`` (m/s, ego axes), ``voxel_m``,
``range_m`` (x_min, y_min, z_min, x_max, y_max, z_max), ``occ3d_classes`` (the names of
``semantics``). ``occupancy/classes.json`` maps both class sets to their names.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path
from typing import Any

import numpy as np

from gtgen.errors import SinkError
from gtgen.npz import npz_bytes
from gtgen.occupancy import FREE_NATIVE, OCC3D_CLASSES, OCC3D_OF_CLASS, OccupancyFrame
from gtgen.sinks.folder import PartialFolder, frame_of
from networks.classes import SemanticClass


def labels_npz(occupancy: OccupancyFrame) -> bytes:
    grid = occupancy.grid
    upper = grid.upper_m
    return npz_bytes(
        semantics=occupancy.semantics, mask_lidar=occupancy.mask_lidar, mask_camera=occupancy.mask_camera,
        semantics_native=occupancy.semantics_native, instance=occupancy.instance, flow=occupancy.flow_mps,
        flow_relative=occupancy.flow_relative_mps, voxel_m=np.float64(grid.voxel_m),
        range_m=np.asarray([*grid.lower_m, *upper], np.float64), occ3d_classes=np.asarray(OCC3D_CLASSES),
    )  # fmt: skip


def classes_json() -> dict[str, Any]:
    native = {str(int(c)): {"name": c.label, "occ3d": OCC3D_OF_CLASS[c]} for c in SemanticClass}
    native[str(FREE_NATIVE)] = {"name": "free", "occ3d": "free"}
    return {"occ3d": list(OCC3D_CLASSES), "native": native}


class OccupancySink:
    def __init__(self, folder: Path, keep_frames: int = 0) -> None:
        self._folder = PartialFolder(folder, (), keep_frames)
        self._folder.partial.mkdir(parents=True, exist_ok=True)
        for path in list(self._folder.partial.iterdir()) if keep_frames else []:
            frame = frame_of(path)
            if path.is_dir() and frame is not None and frame >= keep_frames:
                shutil.rmtree(path)

    def encode(self, record: Any, images: Any) -> dict[str, bytes]:
        occupancy: OccupancyFrame | None = record.occupancy
        if occupancy is None:
            return {}
        return {f"{record.frame_index:06d}/labels.npz": labels_npz(occupancy)}

    def write(self, encoded: dict[str, bytes]) -> None:
        for relative in encoded:
            (self._folder.partial / relative).parent.mkdir(parents=True, exist_ok=True)
        self._folder.write_files(encoded)

    def close(self) -> None:
        path = self._folder.partial / "classes.json"
        try:
            path.write_text(json.dumps(classes_json(), indent=1) + "\n")
        except OSError as err:
            raise SinkError(f"{path}: cannot write: {err.strerror}") from err
        self._folder.commit()

    def abort(self) -> None:
        self._folder.discard()

    def keep(self) -> None:
        pass  # each frame's file is written whole
