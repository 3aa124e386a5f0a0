"""The camera images of one frame, each shaded and encoded once however many sinks use it.

MCAP, KITTI and YOLO all write the first camera's image; one :class:`FrameImages` per
frame is handed to every sink, so an image is shaded (:func:`sensors.shading.shade_frame`)
once and an encoding asked for twice is encoded once.
PNGs are written by :func:`gtgen.png.png_bytes` (the UP filter on every row, DEFLATE through
zlib-ng); the colour image's with Huffman coding only: its sensor noise leaves little for
string matching to find (about 12 ms of CPU for 1280x720, 4 % (by day) to 20 % (at night)
larger than with matching), the same pixels.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from typing import Any

import cv2
import numpy as np
import numpy.typing as npt

from gtgen.errors import SinkError
from gtgen.frame import FrameRecord
from gtgen.png import png_bytes
from sensors.camera import CameraOutput, depth_to_uint16
from sensors.shading import shade_frame

JPEG_QUALITY = 90  # every sink that writes the camera image as JPEG writes this one encoding


def encode(ext: str, image: npt.NDArray[Any], params: list[int]) -> bytes:
    ok, buf = cv2.imencode(ext, image, params)
    if not ok:
        raise SinkError(f"could not encode a {ext} image")
    return buf.tobytes()


def shaded(record: FrameRecord) -> FrameRecord:
    """``record`` with every camera's image shaded (:func:`sensors.shading.shade_frame`: the
    same pixels wherever it is shaded)."""
    sensors = tuple(
        replace(o, image=shade_frame(o.frame)) if isinstance(o, CameraOutput) and o.image is None else o
        for o in record.sensors
    )
    return replace(record, sensors=sensors)


class FrameImages:
    """Lazily encoded images of ``cameras`` (the frame's camera outputs, rig order)."""

    def __init__(self, cameras: tuple[CameraOutput, ...]) -> None:
        self._cameras = cameras
        self._done: dict[tuple[object, ...], bytes] = {}
        self._shaded: dict[int, npt.NDArray[np.uint8]] = {}

    def image(self, camera: int) -> npt.NDArray[np.uint8]:
        """The shaded ``(H, W, 3) uint8`` BGR image of camera ``camera``."""
        image = self._shaded.get(camera)
        if image is None:
            output = self._cameras[camera]
            image = output.image if output.image is not None else shade_frame(output.frame)
            self._shaded[camera] = image
        return image

    def _once(self, key: tuple[object, ...], make: Callable[[], bytes]) -> bytes:
        data = self._done.get(key)
        if data is None:
            data = make()
            self._done[key] = data
        return data

    def jpeg(self, camera: int, quality: int) -> bytes:
        """The shaded image as a JPEG of ``quality`` (0..100)."""
        image = self.image(camera)
        return self._once(("jpeg", camera, quality), lambda: encode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, quality]))

    def png(self, camera: int) -> bytes:
        """The shaded image as a lossless 8-bit colour PNG."""
        image = self.image(camera)
        return self._once(("png", camera), lambda: png_bytes(image, huffman_only=True))

    def depth_png(self, camera: int, units_per_m: float) -> bytes:
        """z-depth as a 16-bit PNG in ``1 / units_per_m`` metres (0: nothing, or out of range)."""
        depth = self._cameras[camera].frame.depth_m
        return self._once(("depth", camera, units_per_m), lambda: png_bytes(depth_to_uint16(depth, units_per_m)))

    def instance_png(self, camera: int) -> bytes:
        """Instance ids as a 16-bit PNG (0: static world or nothing)."""
        ids = self._cameras[camera].frame.instance_id
        return self._once(("instance", camera), lambda: png_bytes(_uint16_ids(ids)))

    def class_png(self, camera: int) -> bytes:
        """Semantic classes as an 8-bit PNG (0: nothing)."""
        classes = self._cameras[camera].frame.semantic_class
        return self._once(("class", camera), lambda: png_bytes(classes))


def _uint16_ids(ids: npt.NDArray[np.uint32]) -> npt.NDArray[np.uint16]:
    if ids.size and int(ids.max()) > 0xFFFF:
        raise SinkError("instance ids above 65535 do not fit the 16-bit instance mask")
    return ids.astype(np.uint16)
