"""Encoded camera images: lossless PNGs of the frame's arrays, each encoding made once."""

import cv2
import numpy as np
import pytest

import gtgen.sinks.images as images_module
from gtgen.sinks.images import FrameImages, shaded
from sensors.camera import depth_to_uint16
from sensors.shading import shade_frame


def decode(data: bytes) -> np.ndarray:
    return cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_UNCHANGED)


def test_pngs_decode_to_the_frame_arrays(records):
    frame = records[0].cameras[0].frame
    images = FrameImages(records[0].cameras)
    np.testing.assert_array_equal(decode(images.png(0)), shade_frame(frame))
    np.testing.assert_array_equal(decode(images.depth_png(0, 256.0)), depth_to_uint16(frame.depth_m, 256.0))
    np.testing.assert_array_equal(decode(images.instance_png(0)), frame.instance_id.astype(np.uint16))
    np.testing.assert_array_equal(decode(images.class_png(0)), frame.semantic_class)
    assert decode(images.jpeg(0, 90)).shape == (90, 160, 3)


def test_an_encoding_asked_for_twice_is_made_once(records):
    images = FrameImages(records[0].cameras)
    assert images.jpeg(0, 90) is images.jpeg(0, 90)
    assert images.png(0) is images.png(0)
    assert images.image(0) is images.image(0)  # shaded once
    assert images.jpeg(0, 92) is not images.jpeg(0, 90)


def test_an_image_shaded_before_the_writer_is_the_one_it_would_shade_and_is_not_shaded_again(records, monkeypatch):
    record = records[0]
    ahead = shaded(record)
    assert record.cameras[0].image is None and ahead.cameras[0].image is not None
    expected = FrameImages(record.cameras).png(0)

    def no_shading(frame):
        raise AssertionError("shaded again")

    monkeypatch.setattr(images_module, "shade_frame", no_shading)
    assert FrameImages(ahead.cameras).png(0) == expected
    with pytest.raises(AssertionError, match="shaded again"):
        FrameImages(record.cameras).png(0)
