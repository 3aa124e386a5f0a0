"""What the traffic simulation hands the frame loop each step (map frame)."""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from gtgen.frame import ActiveHazard
from networks.vocabulary import SignalState
from sensors.agents import Agents, EgoState


@dataclass(frozen=True, slots=True)
class WorldState:
    """``agents``: every agent but the ego (instance id = track id, stable over the scene);
    ``scene_cut``: the ego is a new one, put at the start of a route when the last one ran out
    of road (what came before is another scene); ``signal_states``: each traffic light's
    state at this step, one per controlled link (SUMO's letters decoded); ``ego_lane``: the
    SUMO lane the ego drives on; ``ego_route_ahead``: the edges of its route from the one it is on;
    ``hazards``: the hazard events under way."""

    time_s: float
    agents: Agents
    ego: EgoState
    scene_cut: bool = False
    signal_states: dict[str, tuple[SignalState, ...]] = field(default_factory=dict)
    ego_lane: str = ""
    ego_route_ahead: tuple[str, ...] = ()
    hazards: tuple[ActiveHazard, ...] = ()
    ego_collided: bool = False  # SUMO saw the ego collide in the last step

    def near(self, radius_m: float) -> WorldState:
        """Only the agents whose centre lies within ``radius_m`` of the ego (in the plane)."""
        d = np.linalg.norm(self.agents.center_map_m[:, :2] - self.ego.center_map_m[:2], axis=1)
        return replace(self, agents=self.agents.select(d <= radius_m))
