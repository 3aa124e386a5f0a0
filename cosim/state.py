"""What the traffic simulation hands the frame loop each step (map frame)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from networks.geometry import SE3
from sensors.agents import AgentBoxes


@dataclass(frozen=True, slots=True)
class WorldState:
    """``agents`` are every agent but the ego (instance id = track id, stable over the scene);
    ``velocity_map_mps: (N, 3) float64``; ``parked: (N,) bool``; ``ego`` is the ego's box."""

    time_s: float
    agents: AgentBoxes
    velocity_map_mps: npt.NDArray[np.float64]
    parked: npt.NDArray[np.bool_]
    ego: AgentBoxes
    ego_velocity_map_mps: npt.NDArray[np.float64]

    def map_SE3_ego(self) -> SE3:
        """Ego frame: origin at the footprint centre on the ground, x forward, z up."""
        rotation = self.ego.rotations()[0]
        footprint = self.ego.center_map_m[0] - rotation[:, 2] * self.ego.lwh_m[0, 2] / 2.0
        return SE3(rotation, footprint)

    def near(self, radius_m: float) -> WorldState:
        """Only the agents whose centre lies within ``radius_m`` of the ego (in the plane)."""
        d = np.linalg.norm(self.agents.center_map_m[:, :2] - self.ego.center_map_m[0, :2], axis=1)
        keep = d <= radius_m
        return WorldState(
            self.time_s, self.agents.select(keep), self.velocity_map_mps[keep], self.parked[keep], self.ego,
            self.ego_velocity_map_mps,
        )  # fmt: skip
