"""Spinning multi-beam LiDAR: ray pattern, cast, per-point class and instance.

All rays of a sweep are cast at the frame's instant (no motion distortion).
Intensity = reflectivity(class) * |cos(incidence)| * exp(-range / 200 m), in 0..1; an
optional :class:`~sensors.weather.Weather` (rain, fog) shortens the range, weakens and drops
returns and adds near spurious ones; day and night change nothing.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from typing import TYPE_CHECKING, ClassVar

import numpy as np
import numpy.typing as npt

from networks.geometry import SE3
from networks.records import check_arrays
from sensors.agents import EgoState
from sensors.errors import SensorConfigError
from sensors.parts import lidar_reflectivity
from sensors.rays import sensor_rays
from sensors.view import spheres_in_view
from sensors.weather import (
    Weather,
    add_spurious_returns,
    lidar_dropout,
    lidar_intensity_factor,
    lidar_max_range_m,
    lidar_range_noise_m,
)

if TYPE_CHECKING:  # Open3D loads only where rays are cast, not in the writer process
    from sensors.engine import Scene


@dataclass(frozen=True, slots=True)
class LidarSpec:
    name: str = "lidar"
    beams: int = 64
    vertical_min_deg: float = -24.9
    vertical_max_deg: float = 2.0
    azimuth_steps: int = 1024
    range_m: float = 120.0
    rate_hz: float = 20.0
    mount_xyz_m: tuple[float, float, float] = (0.0, 0.0, 1.95)
    mount_rpy_deg: tuple[float, float, float] = (0.0, 0.0, 0.0)
    range_noise_m: float = 0.0
    dropout: float = 0.0
    elevations_deg: tuple[float, ...] = ()  # each beam's elevation, lowest first (instead of an even spread)

    def __post_init__(self) -> None:
        if self.elevations_deg:
            e = self.elevations_deg
            if len(e) != self.beams or any(b <= a for a, b in itertools.pairwise(e)) or not -90 <= e[0] <= e[-1] <= 90:
                raise SensorConfigError(f"lidar {self.name}: elevations_deg must hold `beams` ({self.beams}) angles, "
                                        "rising, within -90..90")  # fmt: skip
        if not 1 <= self.beams <= 512:
            raise SensorConfigError(f"lidar {self.name}: beams must be 1..512, got {self.beams}")
        if not 8 <= self.azimuth_steps <= 16384:
            raise SensorConfigError(f"lidar {self.name}: azimuth_steps must be 8..16384, got {self.azimuth_steps}")
        if not -90.0 <= self.vertical_min_deg < self.vertical_max_deg <= 90.0:
            raise SensorConfigError(f"lidar {self.name}: need -90 <= vertical_min_deg < vertical_max_deg <= 90")
        if self.range_m <= 0 or self.rate_hz <= 0:
            raise SensorConfigError(f"lidar {self.name}: range_m and rate_hz must be > 0")
        if self.range_noise_m < 0 or not 0.0 <= self.dropout < 1.0:
            raise SensorConfigError(f"lidar {self.name}: need range_noise_m >= 0 and 0 <= dropout < 1")

    @property
    def ego_SE3_sensor(self) -> SE3:
        r, p, y = np.radians(self.mount_rpy_deg)
        return SE3.from_xyz_rpy(self.mount_xyz_m, r, p, y)

    def directions(self) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.uint16]]:
        """Unit ray directions ``(beams * azimuth_steps, 3)`` in the lidar frame and the ring
        of each (ring 0 is the lowest beam); azimuth starts at +x and turns counter-clockwise."""
        spread = np.linspace(self.vertical_min_deg, self.vertical_max_deg, self.beams)
        elevation = np.radians(np.asarray(self.elevations_deg, np.float64) if self.elevations_deg else spread)
        azimuth = np.arange(self.azimuth_steps) * (2.0 * np.pi / self.azimuth_steps)
        el, az = np.meshgrid(elevation, azimuth, indexing="ij")
        dirs = np.stack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)], axis=-1).reshape(-1, 3)
        ring = np.repeat(np.arange(self.beams, dtype=np.uint16), self.azimuth_steps)
        return dirs, ring


@dataclass(frozen=True, slots=True)
class LidarScan:
    """Returns of one sweep, in the lidar frame: ``xyz_lidar_m: (N, 3) float32``,
    ``intensity: (N,) float32`` in 0..1, ``ring: (N,) uint16``, ``semantic_class: (N,) uint8``,
    ``instance_id: (N,) uint32`` (0 for the static world)."""

    xyz_lidar_m: npt.NDArray[np.float32]
    intensity: npt.NDArray[np.float32]
    ring: npt.NDArray[np.uint16]
    semantic_class: npt.NDArray[np.uint8]
    instance_id: npt.NDArray[np.uint32]

    def __post_init__(self) -> None:
        check_arrays(
            self, xyz_lidar_m=(np.float32, ("N", 3)), intensity=(np.float32, ("N",)), ring=(np.uint16, ("N",)),
            semantic_class=(np.uint8, ("N",)), instance_id=(np.uint32, ("N",)),
        )  # fmt: skip

    def __len__(self) -> int:
        return int(self.xyz_lidar_m.shape[0])


@dataclass(frozen=True, slots=True)
class LidarOutput:
    spec: LidarSpec
    scan: LidarScan


class Lidar:
    kind: ClassVar[str] = "lidar"

    def __init__(self, spec: LidarSpec) -> None:
        self.spec = spec
        self._dirs_lidar, self._ring = spec.directions()
        self._dirs32 = self._dirs_lidar.astype(np.float32)

    @property
    def num_rays(self) -> int:
        return int(self._dirs_lidar.shape[0])

    def reaches(
        self, center_map_m: npt.NDArray[np.float64], radius_m: npt.NDArray[np.float64], map_SE3_ego: SE3
    ) -> npt.NDArray[np.bool_]:
        """Which spheres this LiDAR's rays may meet within its range (see :mod:`sensors.view`)."""
        lidar_SE3_map = map_SE3_ego.compose(self.spec.ego_SE3_sensor).inverse()
        return spheres_in_view(lidar_SE3_map, center_map_m, radius_m, self.spec.range_m)

    def rays(self, map_SE3_ego: SE3) -> npt.NDArray[np.float32]:
        return sensor_rays(map_SE3_ego.compose(self.spec.ego_SE3_sensor), self._dirs32)

    def sense(self, scene: Scene, ego: EgoState, weather: Weather, rng: np.random.Generator) -> LidarOutput:
        """One sweep; the ``weather`` (day changes nothing) shortens the range, drops and
        weakens returns and adds near spurious ones (class NONE, instance 0)."""
        w = weather
        map_SE3_lidar = ego.map_SE3_ego().compose(self.spec.ego_SE3_sensor)
        rays = sensor_rays(map_SE3_lidar, self._dirs32)
        cast = scene.cast_from(map_SE3_lidar.translation, map_SE3_lidar.rotation, self._dirs32)
        hits, spurious = add_spurious_returns(cast, rays, w, rng)
        keep = hits.range_m <= lidar_max_range_m(w, self.spec.range_m)
        dropout = lidar_dropout(w, self.spec.dropout) if w.lidar_dropout > 0 else self.spec.dropout
        if dropout > 0:
            keep &= rng.random(keep.shape[0]) >= dropout
        idx = np.flatnonzero(keep)
        rng_m = hits.range_m[idx]
        noise_m = lidar_range_noise_m(w, self.spec.range_noise_m)
        if noise_m > 0:
            rng_m = (rng_m + rng.normal(0.0, noise_m, rng_m.shape[0])).astype(np.float32)
        xyz = self._dirs32[idx] * rng_m[:, None]
        cos_inc = np.abs(np.einsum("ij,ij->i", rays[idx, 3:6], hits.normal[idx]))
        cls = hits.semantic_class[idx]
        intensity = lidar_reflectivity(cls, hits.part[idx]) * cos_inc * np.exp(rng_m * np.float32(-1.0 / 200.0))
        if w.lidar_spurious_rate > 0 or w.lidar_intensity_scale != 1.0 or w.lidar_extinction_per_m > 0:
            intensity = intensity * lidar_intensity_factor(w, rng_m)
            intensity = np.where(spurious[idx], w.lidar_spurious_intensity, intensity)
        scan = LidarScan(xyz.astype(np.float32, copy=False), intensity.astype(np.float32, copy=False),
                         self._ring[idx], cls, hits.instance_id[idx])  # fmt: skip
        return LidarOutput(self.spec, scan)
