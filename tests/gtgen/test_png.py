import io
import struct
import zlib

import cv2
import numpy as np
import pytest
from PIL import Image

from gtgen.errors import SinkError
from gtgen.png import png_bytes


def _images() -> dict[str, np.ndarray]:
    rng = np.random.default_rng(5)
    return {
        "colour": rng.integers(0, 256, (37, 53, 3), dtype=np.uint8),
        "grey": rng.integers(0, 256, (19, 1), dtype=np.uint8),
        "depth": rng.integers(0, 2**16, (8, 29), dtype=np.uint16),
        "one pixel": np.array([[[1, 2, 3]]], np.uint8),
        "strided": rng.integers(0, 256, (20, 40, 3), dtype=np.uint8)[::2, ::3],
    }


@pytest.mark.parametrize("huffman_only", [False, True])
def test_readers_give_back_the_same_pixels(huffman_only: bool) -> None:
    for name, image in _images().items():
        data = png_bytes(image, huffman_only=huffman_only)
        back = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_UNCHANGED)
        assert back is not None, name
        if back.ndim == 2 and image.ndim == 3:
            back = back[..., None]
        assert back.dtype == image.dtype and np.array_equal(back.reshape(image.shape), image), name
        pil = np.asarray(Image.open(io.BytesIO(data)))  # another decoder: RGB, and 16-bit grey as int32
        if image.ndim == 3:
            assert np.array_equal(pil, image[..., ::-1]), name
        else:
            assert np.array_equal(pil.astype(np.int64), image.astype(np.int64)), name


def test_chunks_are_well_formed_and_the_rows_up_filtered() -> None:
    image = np.random.default_rng(1).integers(0, 256, (6, 7, 3), dtype=np.uint8)
    data = png_bytes(image)
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    at, chunks = 8, []
    while at < len(data):
        (length,) = struct.unpack(">I", data[at : at + 4])
        kind, body = data[at + 4 : at + 8], data[at + 8 : at + 8 + length]
        (crc,) = struct.unpack(">I", data[at + 8 + length : at + 12 + length])
        assert crc == zlib.crc32(kind + body), kind
        chunks.append((kind, body))
        at += 12 + length
    assert [k for k, _ in chunks] == [b"IHDR", b"IDAT", b"IEND"]
    assert struct.unpack(">IIBBBBB", chunks[0][1]) == (7, 6, 8, 2, 0, 0, 0)
    rows = np.frombuffer(zlib.decompress(chunks[1][1]), np.uint8).reshape(6, 1 + 7 * 3)
    assert (rows[:, 0] == 2).all()
    rgb = image[..., ::-1].reshape(6, -1)
    assert np.array_equal(np.cumsum(rows[:, 1:], axis=0, dtype=np.uint8), rgb)


def test_the_same_pixels_give_the_same_bytes() -> None:
    image = np.random.default_rng(2).integers(0, 2**16, (30, 40), dtype=np.uint16)
    assert png_bytes(image) == png_bytes(image.copy())


@pytest.mark.parametrize(
    "image",
    [np.zeros((4, 4), np.float32), np.zeros((4, 4, 4), np.uint8), np.zeros((0, 5), np.uint8), np.zeros(5, np.uint8)],
)
def test_what_a_png_cannot_hold_is_one_clear_error(image: np.ndarray) -> None:
    with pytest.raises(SinkError, match="PNG of"):
        png_bytes(image)
