"""Scenario sensor configuration -> sensor models."""

from __future__ import annotations

from cosim.scenario import LidarConfig, Scenario
from sensors.lidar import Lidar, LidarSpec


def lidar_spec(config: LidarConfig, rate_hz: float) -> LidarSpec:
    return LidarSpec(
        name=config.name,
        beams=config.beams,
        vertical_min_deg=config.vertical_min_deg,
        vertical_max_deg=config.vertical_max_deg,
        azimuth_steps=config.azimuth_steps,
        range_m=config.range_m,
        rate_hz=rate_hz,
        mount_xyz_m=config.mount_xyz_m,
        mount_rpy_deg=config.mount_rpy_deg,
        range_noise_m=config.range_noise_m,
        dropout=config.dropout,
    )


def build_lidars(scenario: Scenario) -> list[Lidar]:
    return [Lidar(lidar_spec(c, 1.0 / scenario.step_s)) for c in scenario.sensors.lidars]
