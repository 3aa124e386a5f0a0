"""The scenario's sensor rig as sensor models, and one frame of all of them."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cosim.scenario import Scenario
from gtgen.timing import NO_CLOCK, StageClock
from networks.geometry import SE3
from networks.vocabulary import SensorKind
from sensors.agents import Agents, EgoState
from sensors.camera import Camera
from sensors.engine import Engine, Scene, open_engine
from sensors.lidar import Lidar
from sensors.radar import Radar
from sensors.sensor import Sensor, SensorOutput, fires
from sensors.view import bounding_radius_m
from sensors.weather import Weather, weather_preset


@dataclass(frozen=True, slots=True)
class Rig:
    """``sensors`` in the order they sense each frame (LiDARs, cameras, radars: the order in
    which they draw from the frame loop's random generator). Each fires at its own rate on the
    simulation clock of frames ``step_s`` apart (0: every sensor every frame)."""

    sensors: tuple[Sensor, ...]
    weather: Weather
    engine: Engine
    notice: str = ""  # lines for the user: the engine asked for is not the one used, a sensor above the frame rate
    step_s: float = 0.0

    def due(self, frame_index: int) -> tuple[Sensor, ...]:
        """The sensors that fire in this frame, in rig order."""
        return tuple(s for s in self.sensors if fires(s.spec.rate_hz, self.step_s, frame_index))

    @property
    def camera_names(self) -> tuple[str, ...]:
        return tuple(s.spec.name for s in self.of_kind(SensorKind.CAMERA))

    def of_kind(self, kind: SensorKind) -> tuple[Sensor, ...]:
        return tuple(s for s in self.sensors if s.kind == kind)

    @property
    def reach_m(self) -> float:
        """The farthest any sensor sees: agents beyond it need not enter the scene."""
        return max(s.spec.range_m for s in self.sensors)

    @property
    def label_range_m(self) -> float:
        """Objects within this distance are labelled even when no ray hit them."""
        return max((s.spec.range_m for s in self.of_kind(SensorKind.LIDAR)), default=self.reach_m)

    def agents_in_view(self, agents: Agents, map_SE3_ego: SE3, sensors: tuple[Sensor, ...] | None = None) -> Agents:
        """The agents the rays of ``sensors`` (default: all) may reach; the others cannot
        change any return."""
        radius = bounding_radius_m(agents.lwh_m)
        keep = np.zeros(len(agents), np.bool_)
        for sensor in self.sensors if sensors is None else sensors:
            keep |= sensor.reaches(agents.center_map_m, radius, map_SE3_ego)
        return agents.select(keep)

    def sense(
        self, scene: Scene, ego: EgoState, rng: np.random.Generator, clock: StageClock = NO_CLOCK,
        sensors: tuple[Sensor, ...] | None = None,
    ) -> tuple[SensorOutput, ...]:  # fmt: skip
        """The output of every sensor in ``sensors`` (default: all), in rig order (each timed as
        its kind)."""
        outputs = []
        for sensor in self.sensors if sensors is None else sensors:
            with clock.stage(sensor.kind):
                outputs.append(sensor.sense(scene, ego, self.weather, rng))
        return tuple(outputs)


def build_rig(scenario: Scenario) -> Rig:
    spec = scenario.sensors
    sensors: list[Sensor] = [Lidar(s) for s in spec.lidars]
    sensors += [Camera(s) for s in spec.cameras]
    sensors += [Radar(s) for s in spec.radars]
    engine, notice = open_engine(scenario.engine)
    notices = [notice] if notice else []
    notices += rate_notices(sensors, scenario.step_s)
    return Rig(tuple(sensors), weather_preset(scenario.weather), engine, "\n".join(notices), scenario.step_s)


def rate_notices(sensors: list[Sensor], step_s: float) -> list[str]:
    """A line for each sensor faster than the frames: it fires every frame."""
    frame_hz = 1.0 / step_s
    fast = [s.spec for s in sensors if s.spec.rate_hz > frame_hz * (1 + 1e-9)]
    return [f"notice: sensors: {spec.name} is set to {spec.rate_hz:g} Hz, above the frame rate ({frame_hz:g} Hz, "
            f"step_s {step_s:g}): it fires every frame" for spec in fast]  # fmt: skip
