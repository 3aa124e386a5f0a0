"""Train, validation and test splits of a run, by one rule for every export that needs them.

A run's units in time order (KITTI's frames, nuScenes's scenes) are split into three blocks:
the last ``SHARE`` of them (at least one) is ``test``, the ``SHARE`` before it (at least one)
``val``, the rest ``train``. Blocks, not every n-th unit, so that neighbouring frames (nearly
the same data) do not land on both sides of a split. Two units give one ``train`` and one
``val``; one unit is ``train``.
"""

from __future__ import annotations

from typing import Literal

Split = Literal["train", "val", "test"]
SPLITS: tuple[Split, ...] = ("train", "val", "test")
SHARE = 0.15  # of the units in each of val and test (nuScenes: 150 of 1,000 scenes each)


def split_units(count: int) -> list[Split]:
    """The split of each of ``count`` units in time order."""
    if count <= 2:
        first: list[Split] = ["train", "val"]
        return first[:count]
    held_out = max(1, round(SHARE * count))
    held_out = min(held_out, (count - 1) // 2)
    train: list[Split] = ["train"] * (count - 2 * held_out)
    val: list[Split] = ["val"] * held_out
    test: list[Split] = ["test"] * held_out
    return train + val + test
