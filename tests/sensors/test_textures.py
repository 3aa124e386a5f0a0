import numpy as np

from sensors import textures


def _hash_in_int64(ix: np.ndarray, iy: np.ndarray, seed: int) -> np.ndarray:
    """The texture hash as written with 64-bit integers masked to 32 bits."""
    h = (ix * 374761393 + iy * 668265263 + seed * 2147483647) & 0xFFFFFFFF
    h = ((h ^ (h >> 13)) * 1274126177) & 0xFFFFFFFF
    h ^= h >> 16
    return (h & 0xFFFFFF).astype(np.float32) / np.float32(16777216.0)


def test_hash_in_32_bit_arithmetic_equals_the_64_bit_formula_for_negative_and_far_lattice_points() -> None:
    rng = np.random.default_rng(5)
    ix = rng.integers(-3_000_000, 3_000_000, 20_000)
    iy = rng.integers(-3_000_000, 3_000_000, 20_000)
    for seed in (0, 7, 91, 1000):
        assert np.array_equal(textures.hash01(ix, iy, seed), _hash_in_int64(ix, iy, seed))


def test_value_noise_takes_each_lattice_points_hash_there_and_blends_between() -> None:
    rng = np.random.default_rng(6)
    ix = rng.integers(-5000, 5000, 2000)
    iy = rng.integers(-5000, 5000, 2000)
    at_points = textures.value_noise(ix.astype(np.float32), iy.astype(np.float32), 3)
    assert np.array_equal(at_points, _hash_in_int64(ix, iy, 3))
    x = ix.astype(np.float32) + np.float32(0.5)
    y = iy.astype(np.float32) + np.float32(0.5)
    mid = textures.value_noise(x, y, 3)  # the four corners' mean at a cell's centre
    corners = [_hash_in_int64(ix + dx, iy + dy, 3) for dx in (0, 1) for dy in (0, 1)]
    assert np.allclose(mid, np.mean(corners, axis=0), atol=1e-6)
