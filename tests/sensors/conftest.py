"""Hand-built scenes with analytic answers, handed to tests as the ``synth`` fixture (the suite
runs in importlib mode: test modules import helpers only relatively, ``from .conftest import``)."""

from __future__ import annotations

from collections.abc import Sequence
from types import SimpleNamespace

import numpy as np
import pytest

from networks.classes import SemanticClass
from networks.geometry import SE3
from networks.mesh import ClassedMesh, merge
from sensors.agents import Agents, EgoState
from sensors.scene import FrameScene

EGO = EgoState.at(SE3.identity())  # the ego's footprint at the map origin, facing +x, standing still


def quad(corners: Sequence[Sequence[float]], cls: SemanticClass) -> ClassedMesh:
    """Two triangles over four corners given in order around the quad."""
    return ClassedMesh(np.asarray(corners, dtype=np.float64), np.array([[0, 1, 2], [0, 2, 3]]), np.full(2, cls))


def ground(half_m: float = 500.0, cls: SemanticClass = SemanticClass.ROAD, z_m: float = 0.0) -> ClassedMesh:
    h = half_m
    return quad([(-h, -h, z_m), (h, -h, z_m), (h, h, z_m), (-h, h, z_m)], cls)


def wall_at_x(x_m: float, half_m: float = 200.0, cls: SemanticClass = SemanticClass.BUILDING) -> ClassedMesh:
    """A wall facing -x across the whole view, from z = -half to +half."""
    h = half_m
    return quad([(x_m, -h, -h), (x_m, h, -h), (x_m, h, h), (x_m, -h, h)], cls)


def agents(
    rows: Sequence[tuple[int, SemanticClass, float, float, float, float, float, float, float]],
    velocity_map_mps: Sequence[Sequence[float]] | None = None,
    yaw_rate_rad_s: Sequence[float] | None = None,
) -> Agents:
    """Rows of (id, class, x, y, z_centre, l, w, h, yaw); level, not parked, standing still
    unless ``velocity_map_mps`` gives each one's velocity (and ``yaw_rate_rad_s`` its rate of turn)."""
    if not rows:
        return Agents.empty()
    a = np.array([r[2:] for r in rows], dtype=np.float64)
    n = len(rows)
    velocity = np.zeros((n, 3)) if velocity_map_mps is None else np.asarray(velocity_map_mps, np.float64)
    turning = np.zeros(n) if yaw_rate_rad_s is None else np.asarray(yaw_rate_rad_s, np.float64)
    return Agents(np.array([r[0] for r in rows]), np.array([int(r[1]) for r in rows]), a[:, 0:3], a[:, 3:6], a[:, 6],
                  np.zeros(n), velocity, np.zeros(n, bool), yaw_rate_rad_s=turning)  # fmt: skip


def scene(static: Sequence[ClassedMesh], boxes: Agents | None = None) -> FrameScene:
    return FrameScene(merge(list(static)), Agents.empty() if boxes is None else boxes)


def ego(velocity_map_mps: Sequence[float] = (0.0, 0.0, 0.0), yaw_rate_rad_s: float = 0.0) -> EgoState:
    """The ego at the map origin, facing +x, driving at ``velocity_map_mps`` and turning at
    ``yaw_rate_rad_s``."""
    return EgoState(EGO.center_map_m, EGO.lwh_m, 0.0, 0.0, np.asarray(velocity_map_mps, np.float64), yaw_rate_rad_s)


@pytest.fixture
def synth() -> SimpleNamespace:
    return SimpleNamespace(quad=quad, ground=ground, wall_at_x=wall_at_x, agents=agents, scene=scene, ego=ego, EGO=EGO)


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(7)
