"""The one way records check their array fields: shape and dtype, named in the error.

A record's ``__post_init__`` calls :func:`check_arrays` with each field's dtype and shape.
A dimension is a number, or a letter shared by the fields that must agree on it
(``("N", 3)``). Values of another dtype are converted when they stay what they are: integers
to integers (when every value fits), booleans to numbers, integers and floats to floats. Any
other dtype (a float where an integer is expected), and any shape that differs, raises
``ValueError`` naming the record and the field: nothing is reshaped.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt

Dim = int | str
FieldSpec = tuple[npt.DTypeLike, tuple[Dim, ...]]


def _converted(owner: str, name: str, value: Any, dtype: np.dtype[Any]) -> npt.NDArray[Any]:
    array = np.asarray(value)
    if array.dtype == dtype:
        return array
    src = array.dtype
    if src.kind in "biu" and dtype.kind in "iu":
        info = np.iinfo(dtype)
        if array.size == 0 or (int(array.min()) >= info.min and int(array.max()) <= info.max):
            return array.astype(dtype)
    elif np.can_cast(src, dtype, "same_kind"):
        return array.astype(dtype)
    lost = " with values out of range" if src.kind in "iu" and dtype.kind in "iu" else ""
    raise ValueError(f"{owner}.{name}: expected dtype {dtype}, got {src}{lost}")


def _shape_text(shape: tuple[Dim, ...]) -> str:
    return "(" + ", ".join(str(d) for d in shape) + ("," if len(shape) == 1 else "") + ")"


def _fits(got: tuple[int, ...], want: tuple[Dim, ...], sizes: dict[str, int]) -> bool:
    """Whether shape ``got`` is ``want``, binding letter dimensions not bound yet."""
    if len(got) != len(want):
        return False
    for size, dim in zip(got, want, strict=True):
        expected = sizes.setdefault(dim, size) if isinstance(dim, str) else dim
        if size != expected:
            return False
    return True


def check_arrays(record: object, **fields: FieldSpec) -> dict[str, int]:
    """Check (and convert, see the module) each named field of a frozen ``record`` in place;
    returns the size bound to each letter dimension."""
    owner = type(record).__name__
    sizes: dict[str, int] = {}
    for name, (dtype, shape) in fields.items():
        array = _converted(owner, name, getattr(record, name), np.dtype(dtype))
        if not _fits(array.shape, shape, sizes):
            expected = _shape_text(tuple(f"{d}={sizes[d]}" if isinstance(d, str) and d in sizes else d for d in shape))
            raise ValueError(f"{owner}.{name}: expected shape {expected}, got {array.shape}")
        object.__setattr__(record, name, array)
    return sizes
