"""Vehicle sizes drawn per vehicle from the cited datasets' distributions (cosim/demand.py)."""

import numpy as np
import pytest

from cosim.demand import KINDS, sample_size


@pytest.mark.parametrize("kind", sorted(KINDS))
def test_sizes_follow_the_kinds_distribution_inside_its_ranges(kind):
    spec = KINDS[kind]
    rng = np.random.default_rng(0)
    sizes = np.array([sample_size(spec, rng) for _ in range(4000)])
    lo = np.array([spec.length_m[0], spec.width_m[0], spec.height_m[0]])
    hi = np.array([spec.length_m[1], spec.width_m[1], spec.height_m[1]])
    assert np.all(sizes >= lo) and np.all(sizes <= hi)
    assert spec.mean_lwh_m is not None
    # truncation to the ranges moves the mean by less than a fifth of a spread
    np.testing.assert_allclose(sizes.mean(axis=0), spec.mean_lwh_m, atol=0.2 * max(spec.sd_lwh_m) + 0.01)
    assert len({tuple(s) for s in sizes.tolist()}) > 3000  # not a handful of variants


def test_cars_spread_as_nuscenes_cars_do():
    """nuScenes v1.0-trainval cars: 4.62 x 1.95 x 1.73 m, sd 0.46 / 0.19 / 0.24."""
    rng = np.random.default_rng(1)
    sizes = np.array([sample_size(KINDS["car"], rng) for _ in range(4000)])
    np.testing.assert_allclose(sizes.mean(axis=0), (4.62, 1.95, 1.73), atol=0.05)
    np.testing.assert_allclose(sizes.std(axis=0), (0.46, 0.19, 0.24), rtol=0.15)


def test_a_length_cap_holds():
    rng = np.random.default_rng(2)
    assert max(sample_size(KINDS["car"], rng, 5.4)[0] for _ in range(500)) <= 5.4
