"""``yolo/``: 2D detection training data (images, labels, data.yaml) from the first camera.

Boxes are the tight (modal) boxes around each object's visible pixels, for objects with
at least ``min_visible_px`` visible pixels, as ``class cx cy w h`` normalised to 0..1.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import yaml

from gtgen.errors import SinkError
from gtgen.frame import FrameRecord
from gtgen.sinks.folder import PartialFolder
from gtgen.sinks.images import JPEG_QUALITY, FrameImages
from networks.classes import SemanticClass
from networks.vocabulary import Lamp, SignKind, sign_kind

YOLO_CLASSES = (SemanticClass.CAR, SemanticClass.TRUCK, SemanticClass.BUS, SemanticClass.MOTORCYCLE,
                SemanticClass.BICYCLE, SemanticClass.PEDESTRIAN)  # fmt: skip
# After the road users: traffic lights by the state they show (traffic_light_red is 6, ...),
# then signs by kind (traffic_sign_stop is 11, traffic_sign_yield 12, traffic_sign_speed_limit 13),
# then the classes added later, so that earlier datasets' ids keep their meaning (trailer 14,
# construction_vehicle 15, traffic_cone 16, barrier 17).
LIGHT_CLASSES = {lamp: len(YOLO_CLASSES) + k for k, lamp in enumerate(Lamp)}
SIGN_CLASSES = {kind: len(YOLO_CLASSES) + len(Lamp) + k for k, kind in enumerate(SignKind)}
LATER_CLASSES = (SemanticClass.TRAILER, SemanticClass.CONSTRUCTION_VEHICLE, SemanticClass.TRAFFIC_CONE,
                 SemanticClass.BARRIER)  # fmt: skip
LATER_FROM = len(YOLO_CLASSES) + len(Lamp) + len(SIGN_CLASSES)
_INDEX = np.full(256, -1, np.int64)
for _i, _c in enumerate(YOLO_CLASSES):
    _INDEX[int(_c)] = _i
for _i, _c in enumerate(LATER_CLASSES):
    _INDEX[int(_c)] = LATER_FROM + _i
YOLO_NAMES = {
    **{i: c.label for i, c in enumerate(YOLO_CLASSES)},
    **{i: f"traffic_light_{lamp.value}" for lamp, i in LIGHT_CLASSES.items()},
    **{i: f"traffic_sign_{kind.value}" for kind, i in SIGN_CLASSES.items()},
    **{LATER_FROM + i: c.label for i, c in enumerate(LATER_CLASSES)},
}


def _street_class(subtype: str, state: str) -> int:
    """The YOLO class of a signal head (by ``state``) or a sign (by ``subtype``)."""
    if state:
        return LIGHT_CLASSES[Lamp(state)]
    return SIGN_CLASSES[sign_kind(subtype)]


class YoloSink:
    def __init__(self, folder: Path, min_visible_px: int, keep_frames: int = 0) -> None:
        self._folder = PartialFolder(folder, ("images", "labels"), keep_frames)
        self._min_visible_px = min_visible_px

    def encode(self, record: FrameRecord, images: FrameImages) -> dict[str, bytes]:
        """The frame's files, by path relative to the ``yolo`` folder."""
        if not record.labels.rig_cameras:
            raise SinkError("the YOLO layout needs at least one camera in the rig")
        cam = record.labels.first_camera
        if cam is None:  # the first camera did not fire in this frame
            return {}
        name = f"{record.frame_index:06d}"
        camera = record.cameras[0]
        objects = record.labels.objects
        cls = _INDEX[objects.semantic_class]
        signals = record.signals
        street = {
            int(i): _street_class(t, st)
            for i, t, st in zip(signals.track_id.tolist(), signals.subtype, signals.state, strict=True)
        }
        for i in np.flatnonzero(cls < 0):
            cls[i] = street.get(int(objects.track_id[i]), -1)
        keep = (cam.visibility.visible_px >= self._min_visible_px) & (cls >= 0)
        box = cam.visibility.modal_px[keep]
        w, h = float(camera.spec.width_px), float(camera.spec.height_px)
        # modal boxes hold pixel centres: the box covers left - 0.5 .. right + 0.5
        cx, cy = (box[:, 0] + box[:, 2] + 1.0) / 2.0 / w, (box[:, 1] + box[:, 3] + 1.0) / 2.0 / h
        bw, bh = (box[:, 2] - box[:, 0] + 1.0) / w, (box[:, 3] - box[:, 1] + 1.0) / h
        rows = [f"{c} {x:.6f} {y:.6f} {a:.6f} {b:.6f}" for c, x, y, a, b in zip(cls[keep], cx, cy, bw, bh, strict=True)]
        return {
            f"images/{name}.jpg": images.jpeg(0, JPEG_QUALITY),
            f"labels/{name}.txt": "".join(r + "\n" for r in rows).encode(),
        }

    def write(self, encoded: dict[str, bytes]) -> None:
        self._folder.write_files(encoded)

    def close(self) -> None:
        # No "path": YOLO tools then read "images" relative to this file's folder, wherever it is moved.
        data = {"train": "images", "val": "images", "names": YOLO_NAMES}
        (self._folder.partial / "data.yaml").write_text(yaml.safe_dump(data, sort_keys=False))
        self._folder.commit()

    def abort(self) -> None:
        self._folder.discard()

    def keep(self) -> None:
        pass  # each frame's files are written whole
