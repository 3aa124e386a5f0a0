"""The scenario's sensor rig as sensor models."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cosim.scenario import Scenario
from networks.geometry import SE3
from sensors.agents import AgentBoxes
from sensors.camera import Camera
from sensors.lidar import Lidar
from sensors.radar import Radar
from sensors.view import bounding_radius_m
from sensors.weather import Weather, weather_preset


@dataclass(frozen=True, slots=True)
class Rig:
    lidars: tuple[Lidar, ...]
    cameras: tuple[Camera, ...]
    radars: tuple[Radar, ...]
    weather: Weather

    @property
    def reach_m(self) -> float:
        """The farthest any sensor sees: agents beyond it need not enter the scene."""
        ranges = [s.spec.range_m for s in self.lidars] + [s.spec.range_m for s in self.cameras]
        ranges += [s.spec.range_m for s in self.radars]
        return max(ranges)

    def agents_in_view(self, agents: AgentBoxes, map_SE3_ego: SE3) -> AgentBoxes:
        """The agents some sensor's rays may reach; the others cannot change any return."""
        radius = bounding_radius_m(agents.lwh_m)
        keep = np.zeros(len(agents), np.bool_)
        sensors: tuple[Lidar | Camera | Radar, ...] = (*self.lidars, *self.cameras, *self.radars)
        for sensor in sensors:
            keep |= sensor.reaches(agents.center_map_m, radius, map_SE3_ego)
        return agents.select(keep)

    @property
    def label_range_m(self) -> float:
        """Objects within this distance are labelled even when no ray hit them."""
        return max((li.spec.range_m for li in self.lidars), default=self.reach_m)


def build_rig(scenario: Scenario) -> Rig:
    sensors = scenario.sensors
    return Rig(
        tuple(Lidar(spec) for spec in sensors.lidars),
        tuple(Camera(spec) for spec in sensors.cameras),
        tuple(Radar(spec) for spec in sensors.radars),
        weather_preset(scenario.weather),
    )
