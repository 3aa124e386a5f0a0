"""The ray engine a frame's rays are cast with: one interface, two implementations.

An engine makes a frame's :class:`Scene` from the static world near the ego and the agents;
the scene casts rays (map frame) and tells per ray the distance, class, instance and surface
normal. ``open3d`` (:mod:`sensors.scene`) is the reference, always installed; ``mitsuba``
(:mod:`sensors.mitsuba_engine`) traces coherent packets with Dr.Jit's LLVM backend, several
times faster, when it can start (it needs libLLVM 15 or newer). ``auto`` takes the fast
engine when it starts, else Open3D with one line saying why. Nothing above this interface
imports either library.
"""

from __future__ import annotations

from typing import Any, Protocol

import numpy as np
import numpy.typing as npt

from networks.errors import quoted
from networks.mesh import ClassedMesh
from sensors.agents import AgentMeshes, Agents
from sensors.errors import SensorConfigError
from sensors.hits import PairHits, RayHits

ENGINES = ("auto", "open3d", "mitsuba")


class Scene(Protocol):
    """One frame's scene: the static world and the agents (their meshes made by the engine)."""

    @property
    def agents(self) -> Agents: ...

    @property
    def agent_meshes(self) -> AgentMeshes: ...

    def cast(self, rays: npt.NDArray[np.float32]) -> RayHits:
        """Rays ``(N, 6) float32`` (origin, unit direction) in the map frame."""
        ...

    def cast_from(
        self,
        origin_map_m: npt.NDArray[np.float64],
        map_R_sensor: npt.NDArray[np.float64],
        dirs_sensor: npt.NDArray[np.float32],
    ) -> RayHits:
        """Rays from one origin along unit directions ``(N, 3) float32`` given in a sensor's
        frame turned by ``map_R_sensor`` (a sensor passes the same directions array every
        frame: an engine may keep it)."""
        ...

    def cast_static(self, rays: npt.NDArray[np.float32]) -> RayHits:
        """Rays cast into the static world alone (instance 0, part 0 everywhere)."""
        ...

    def cast_agents_moving(
        self, rays: npt.NDArray[np.float32], dt_s: npt.NDArray[np.float64], ray_index: npt.NDArray[np.intp],
        agent_index: npt.NDArray[np.intp],
    ) -> PairHits:  # fmt: skip
        """Ray ``ray_index[k]`` at ``dt_s[ray_index[k]]`` seconds from the scene's time against agent
        ``agent_index[k]`` (a row of :attr:`agents`) alone, moved by its velocity and rate of turn
        over that time; glass lets the ray through (see :func:`sensors.scene.cast_agents_moving`)."""
        ...

    def occluded(self, rays: npt.NDArray[np.float32]) -> npt.NDArray[np.bool_]:
        """``(N,) bool`` whether each ray meets anything at all (shadow rays: cheaper than
        :meth:`cast`, no nearest hit sought); the same as ``isfinite(cast(rays).range_m)``."""
        ...

    def cast_raw(self, rays: npt.NDArray[np.float32]) -> Any:
        """The engine's own cast of ``rays``, nothing added (what the benchmark compares to)."""
        ...

    def hits_alone(self, rays: npt.NDArray[np.float32], instance_id: npt.NDArray[np.uint32]) -> npt.NDArray[np.bool_]:
        """Whether ray ``i`` meets agent ``instance_id[i]`` with everything else taken away."""
        ...


class Engine(Protocol):
    @property
    def name(self) -> str: ...

    def scene(self, static: ClassedMesh, agents: Agents) -> Scene:
        """The frame's scene; ``static`` is usually the same mesh as the last frame's."""
        ...

    def checkpoint(self) -> dict[str, Any]:
        """What the engine keeps from the frames made so far and its next frames depend on (plain
        JSON data; empty when nothing)."""
        ...

    def restore(self, state: dict[str, Any]) -> None:
        """Continue as the engine whose :meth:`checkpoint` gave ``state`` would."""
        ...


def open_engine(name: str) -> tuple[Engine, str]:
    """The engine called ``name`` (one of :data:`ENGINES`) and a notice for the user ('' if none).
    ``auto`` falls back to Open3D when the fast engine cannot start; ``mitsuba`` raises then."""
    if name not in ENGINES:
        raise SensorConfigError(f"engine: expected one of {', '.join(ENGINES)}, got {quoted(name)}")
    if name == "open3d":
        from sensors.scene import Open3DEngine

        return Open3DEngine(), ""
    try:
        from sensors.mitsuba_engine import MitsubaEngine

        return MitsubaEngine(), ""
    except (ImportError, RuntimeError, OSError) as err:
        reason = " ".join(str(err).split())[:160] or "it is not installed"
        if name == "mitsuba":
            raise SensorConfigError(f"engine mitsuba cannot start here: {reason}") from err
    from sensors.scene import Open3DEngine

    return Open3DEngine(), f"note: the fast ray engine (Mitsuba) cannot start here ({reason}); casting with Open3D"
