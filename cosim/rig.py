"""The scenario's sensor rig as sensor models."""

from __future__ import annotations

from dataclasses import dataclass

from cosim.scenario import Scenario
from sensors.camera import Camera
from sensors.lidar import Lidar
from sensors.radar import Radar
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
