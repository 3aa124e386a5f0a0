"""The README's flat/realistic figure is made by `python -m cosim.figure`."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

from cosim.figure import GAP_PX, side_by_side


def test_side_by_side_scales_both_halves_with_a_white_gap() -> None:
    left = np.zeros((720, 1280, 3), np.uint8)
    right = np.full((720, 1280, 3), 100, np.uint8)
    figure = side_by_side(left, right, 640)
    assert figure.shape == (360, 640 + GAP_PX + 640, 3)
    assert (figure[:, :640] == 0).all()
    assert (figure[:, 640 : 640 + GAP_PX] == 255).all()
    assert (figure[:, 640 + GAP_PX :] == 100).all()


@pytest.mark.slow
def test_figure_shows_the_same_frame_flat_and_realistic(tmp_path: Path) -> None:
    out = tmp_path / "figure.png"
    command = [sys.executable, "-m", "cosim.figure", "--frame", "1", "--width", "320", "--out", str(out)]
    done = subprocess.run(command, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    figure = cv2.imread(str(out))
    assert figure.shape == (180, 320 + GAP_PX + 320, 3)
    flat, realistic = figure[:, :320].astype(int), figure[:, 320 + GAP_PX :].astype(int)
    # the same view: the sky (top rows) and the road (bottom rows) sit in the same places
    assert np.abs(flat.mean(axis=(1, 2))[:20].mean() - realistic.mean(axis=(1, 2))[:20].mean()) < 80
    # but shaded differently: flat shading has few distinct colours, the realistic image many
    assert len(np.unique(flat.reshape(-1, 3), axis=0)) < len(np.unique(realistic.reshape(-1, 3), axis=0)) / 3


def test_bad_frame_is_one_line() -> None:
    done = subprocess.run([sys.executable, "-m", "cosim.figure", "--frame", "-1"], capture_output=True, text=True)
    assert done.returncode == 2
    assert len((done.stdout + done.stderr).strip().splitlines()) == 1
