"""Records check their array fields one way: shapes exact, dtypes converted only within kind."""

from dataclasses import dataclass

import numpy as np
import pytest

from networks.records import check_arrays


@dataclass(frozen=True, slots=True)
class Points:
    ids: np.ndarray
    xyz_m: np.ndarray

    def __post_init__(self) -> None:
        check_arrays(self, ids=(np.uint32, ("N",)), xyz_m=(np.float32, ("N", 3)))


def test_fields_of_the_right_shape_are_converted_within_their_kind():
    p = Points(np.array([1, 2]), np.zeros((2, 3), np.float64))
    assert p.ids.dtype == np.uint32 and p.xyz_m.dtype == np.float32


def test_a_flat_array_is_not_reshaped_and_the_error_names_the_field_and_the_sizes():
    with pytest.raises(ValueError, match=r"^Points\.xyz_m: expected shape \(N=2, 3\), got \(6,\)$"):
        Points(np.array([1, 2]), np.zeros(6))


def test_floats_where_integers_are_expected_and_values_that_do_not_fit_are_refused():
    with pytest.raises(ValueError, match=r"^Points\.ids: expected dtype uint32, got float64$"):
        Points(np.array([1.0, 2.0]), np.zeros((2, 3)))
    with pytest.raises(ValueError, match=r"^Points\.ids: expected dtype uint32, got int64 with values out of range$"):
        Points(np.array([1, -2]), np.zeros((2, 3)))
