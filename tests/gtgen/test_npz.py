import io
import zipfile

import numpy as np
import pytest

from gtgen.errors import SinkError
from gtgen.npz import npz_bytes


def _arrays() -> dict[str, np.ndarray]:
    rng = np.random.default_rng(3)
    grid = np.zeros((40, 30, 8, 3), np.float32)
    grid[rng.integers(0, 40, 50), rng.integers(0, 30, 50), rng.integers(0, 8, 50)] = rng.normal(size=(50, 3))
    return {
        "flow": grid,
        "semantics": rng.integers(0, 18, (40, 30, 8)).astype(np.uint8),
        "mask": rng.random((40, 30, 8)) < 0.3,
        "instance": rng.integers(0, 2**32, (5, 7), dtype=np.uint32),
        "names": np.asarray(["free", "car", "driveable_surface"]),
        "voxel_m": np.float64(0.4),
        "empty": np.zeros((0, 3), np.float32),
        "fortran": np.asfortranarray(np.arange(12.0).reshape(3, 4)),
        "strided": np.arange(20, dtype=np.int16)[::3],
    }


def test_numpy_reads_every_array_back_as_written() -> None:
    arrays = _arrays()
    with np.load(io.BytesIO(npz_bytes(**arrays))) as z:
        assert sorted(z.files) == sorted(arrays)
        for name, value in arrays.items():
            assert z[name].dtype == value.dtype and z[name].shape == value.shape, name
            assert np.array_equal(z[name], value), name


def test_members_are_the_npy_files_numpy_writes_and_the_archive_checks_out() -> None:
    arrays = _arrays()
    archive = zipfile.ZipFile(io.BytesIO(npz_bytes(**arrays)))
    assert archive.testzip() is None  # every member's CRC and size
    assert [i.compress_type for i in archive.infolist()] == [zipfile.ZIP_DEFLATED] * len(arrays)
    for name, value in arrays.items():
        npy = io.BytesIO()
        np.lib.format.write_array(npy, np.ascontiguousarray(value) if value.ndim else value)
        assert archive.read(f"{name}.npy") == npy.getvalue(), name


def test_same_arrays_same_bytes_and_compressed_like_numpy() -> None:
    arrays = _arrays()
    first = npz_bytes(**arrays)
    assert npz_bytes(**{k: v.copy() for k, v in arrays.items()}) == first
    reference = io.BytesIO()
    np.savez_compressed(reference, **arrays)
    assert len(first) < 1.2 * len(reference.getvalue())


def test_an_array_of_python_objects_is_refused() -> None:
    with pytest.raises(SinkError, match="objects"):
        npz_bytes(bad=np.asarray([{"a": 1}], dtype=object))
