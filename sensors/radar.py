"""Automotive radar by raycasting: sparse returns with range, radial velocity and strength.

A dense azimuth x elevation grid of rays is cast; returns whose RCS-like value
(reflectivity x |cos incidence|) is below ``min_rcs_db`` are dropped as clutter (grazing
road), then at most one return per range-azimuth cell is kept (the strongest) and,
if more remain than ``points_per_frame``, a weighted sample without replacement (weight:
linear reflectivity x incidence, so objects beat road clutter at any range) is drawn from
``rng``. Radial velocity is the hit surface's velocity relative to the radar, projected on
the ray: negative when approaching. Surfaces move with their agent's velocity (static
world: 0); the radar moves with the ego's velocity (yaw rate ignored).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, ClassVar

import numpy as np
import numpy.typing as npt

from networks.geometry import SE3
from networks.records import check_arrays
from networks.vocabulary import SensorKind
from sensors.agents import EgoState
from sensors.errors import SensorConfigError
from sensors.parts import radar_reflectivity
from sensors.rays import sensor_rays
from sensors.view import spheres_in_view
from sensors.weather import Weather

if TYPE_CHECKING:  # Open3D loads only where rays are cast, not in the writer process
    from sensors.engine import Scene


@dataclass(frozen=True, slots=True)
class RadarSpec:
    """A forward radar. ``azimuth_steps`` x ``elevation_steps`` rays are cast before thinning
    to ``points_per_frame``; ``cell_range_m`` x ``cell_azimuth_deg`` is the resolution cell."""

    name: str = SensorKind.RADAR.value  # named after its kind unless the rig names it
    hfov_deg: float = 90.0
    vfov_deg: float = 18.0
    range_m: float = 150.0
    points_per_frame: int = 450
    mount_xyz_m: tuple[float, float, float] = (2.0, 0.0, 0.65)
    mount_rpy_deg: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rate_hz: float = 20.0
    azimuth_steps: int = 360
    elevation_steps: int = 24
    cell_range_m: float = 0.4
    cell_azimuth_deg: float = 1.0
    min_rcs_db: float = -20.0
    range_noise_m: float = 0.0
    velocity_noise_mps: float = 0.0

    def __post_init__(self) -> None:
        if not (0.0 < self.hfov_deg <= 180.0 and 0.0 < self.vfov_deg <= 90.0):
            raise SensorConfigError(f"radar {self.name}: need 0 < hfov_deg <= 180 and 0 < vfov_deg <= 90")
        if self.range_m <= 0 or self.rate_hz <= 0 or self.cell_range_m <= 0 or self.cell_azimuth_deg <= 0:
            raise SensorConfigError(f"radar {self.name}: range_m, rate_hz and cell sizes must be > 0")
        if not (1 <= self.points_per_frame <= self.azimuth_steps * self.elevation_steps):
            raise SensorConfigError(f"radar {self.name}: points_per_frame must be 1..azimuth_steps*elevation_steps")
        if not (2 <= self.azimuth_steps <= 8192 and 1 <= self.elevation_steps <= 512):
            raise SensorConfigError(f"radar {self.name}: azimuth_steps must be 2..8192, elevation_steps 1..512")
        if self.range_noise_m < 0 or self.velocity_noise_mps < 0:
            raise SensorConfigError(f"radar {self.name}: noise must be >= 0")

    @property
    def ego_SE3_sensor(self) -> SE3:
        r, p, y = np.radians(self.mount_rpy_deg)
        return SE3.from_xyz_rpy(self.mount_xyz_m, r, p, y)

    def directions(self) -> npt.NDArray[np.float64]:
        """``(azimuth_steps * elevation_steps, 3)`` unit rays in the radar frame, cell centres."""
        az = _centres(math.radians(self.hfov_deg), self.azimuth_steps)
        el = _centres(math.radians(self.vfov_deg), self.elevation_steps)
        e, a = np.meshgrid(el, az, indexing="ij")
        return np.stack([np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)], axis=-1).reshape(-1, 3)


def _centres(fov_rad: float, steps: int) -> npt.NDArray[np.float64]:
    return np.asarray((np.arange(steps) + 0.5) * (fov_rad / steps) - fov_rad / 2.0, dtype=np.float64)


@dataclass(frozen=True, slots=True)
class RadarScan:
    """Returns of one frame in the radar frame (x forward, y left, z up), all ``(N,)`` unless
    said: ``xyz_radar_m: (N, 3) float32``, ``range_m``, ``radial_velocity_mps`` (negative:
    approaching), ``azimuth_rad`` (atan2(y, x), positive left), ``elevation_rad`` (positive
    up), ``strength_db`` (float32 each), ``instance_id: uint32`` (0: static world),
    ``semantic_class: uint8``."""

    xyz_radar_m: npt.NDArray[np.float32]
    range_m: npt.NDArray[np.float32]
    radial_velocity_mps: npt.NDArray[np.float32]
    azimuth_rad: npt.NDArray[np.float32]
    elevation_rad: npt.NDArray[np.float32]
    strength_db: npt.NDArray[np.float32]
    instance_id: npt.NDArray[np.uint32]
    semantic_class: npt.NDArray[np.uint8]

    def __post_init__(self) -> None:
        per_point = (np.float32, ("N",))
        check_arrays(
            self, xyz_radar_m=(np.float32, ("N", 3)), range_m=per_point, radial_velocity_mps=per_point,
            azimuth_rad=per_point, elevation_rad=per_point, strength_db=per_point,
            instance_id=(np.uint32, ("N",)), semantic_class=(np.uint8, ("N",)),
        )  # fmt: skip

    def __len__(self) -> int:
        return int(self.range_m.shape[0])


@dataclass(frozen=True, slots=True)
class RadarOutput:
    spec: RadarSpec
    scan: RadarScan


def strength_db(
    reflectivity: npt.NDArray[np.floating], cos_incidence: npt.NDArray[np.floating], range_m: npt.NDArray[np.floating]
) -> npt.NDArray[np.float64]:
    """RCS-like strength: ``10 log10(reflectivity * |cos(incidence)|) - 40 log10(range / 1 m)``
    (the radar equation's 1/R^4), floored at -200 dB."""
    rcs = np.maximum(np.asarray(reflectivity, np.float64) * np.abs(cos_incidence), 1e-20)
    return np.asarray(np.maximum(10.0 * np.log10(rcs) - 40.0 * np.log10(np.maximum(range_m, 1.0)), -200.0))


def thin_to_budget(
    range_m: npt.NDArray[np.floating],
    azimuth_rad: npt.NDArray[np.floating],
    strength: npt.NDArray[np.floating],
    weight: npt.NDArray[np.floating],
    spec: RadarSpec,
    rng: np.random.Generator,
) -> npt.NDArray[np.int64]:
    """Indices of the returns kept: the strongest per range-azimuth cell, then a weighted
    sample without replacement down to ``spec.points_per_frame``, sorted. Strengths (to 0.01
    dB) and weights (to 1e-4) are rounded first, so that the float noise of one ray engine or
    another does not decide which of two equal returns is kept."""
    cell_r = np.floor(np.asarray(range_m) / spec.cell_range_m).astype(np.int64)
    cell_a = np.floor(np.asarray(azimuth_rad) / math.radians(spec.cell_azimuth_deg)).astype(np.int64)
    order = np.lexsort((-np.round(np.asarray(strength, np.float64), 2), cell_a, cell_r))
    cells = np.stack([cell_r[order], cell_a[order]], axis=1)
    first = np.ones(order.shape[0], np.bool_)
    first[1:] = np.any(cells[1:] != cells[:-1], axis=1)
    kept = np.sort(order[first])
    if kept.shape[0] <= spec.points_per_frame:
        return kept
    w = np.maximum(np.round(np.asarray(weight, np.float64)[kept], 4), 1e-4)
    chosen = rng.choice(kept.shape[0], size=spec.points_per_frame, replace=False, p=w / w.sum())
    return np.sort(kept[chosen])


class Radar:
    kind: ClassVar[SensorKind] = SensorKind.RADAR

    def __init__(self, spec: RadarSpec) -> None:
        self.spec = spec
        self._dirs_radar = spec.directions()
        self._dirs32 = self._dirs_radar.astype(np.float32)

    @property
    def num_rays(self) -> int:
        return int(self._dirs_radar.shape[0])

    def reaches(
        self, center_map_m: npt.NDArray[np.float64], radius_m: npt.NDArray[np.float64], map_SE3_ego: SE3
    ) -> npt.NDArray[np.bool_]:
        """Which spheres this radar's rays may meet within its range (see :mod:`sensors.view`)."""
        radar_SE3_map = map_SE3_ego.compose(self.spec.ego_SE3_sensor).inverse()
        spec = self.spec
        return spheres_in_view(
            radar_SE3_map, center_map_m, radius_m, spec.range_m, spec.hfov_deg, spec.vfov_deg, elevation_fov=True
        )

    def rays(self, map_SE3_ego: SE3) -> npt.NDArray[np.float32]:
        return sensor_rays(map_SE3_ego.compose(self.spec.ego_SE3_sensor), self._dirs32)

    def sense(self, scene: Scene, ego: EgoState, weather: Weather, rng: np.random.Generator) -> RadarOutput:
        """One frame of returns (the weather does not change them); surfaces move with their
        agent's velocity (:attr:`Scene.agents`), the radar with the ego's."""
        map_SE3_radar = ego.map_SE3_ego().compose(self.spec.ego_SE3_sensor)
        rays = sensor_rays(map_SE3_radar, self._dirs32)
        hits = scene.cast_from(map_SE3_radar.translation, map_SE3_radar.rotation, self._dirs32)
        cls_all = hits.semantic_class
        cos_inc = np.abs(np.einsum("ij,ij->i", rays[:, 3:6], hits.normal))
        reflect = radar_reflectivity(cls_all, hits.part)
        rcs = reflect * cos_inc
        power = strength_db(reflect, cos_inc, hits.range_m)
        in_range = hits.range_m <= self.spec.range_m
        cand = np.flatnonzero(in_range & (rcs >= np.float32(10.0 ** (self.spec.min_rcs_db / 10.0))))
        dirs = self._dirs_radar[cand]
        az = np.arctan2(dirs[:, 1], dirs[:, 0])
        keep = cand[thin_to_budget(hits.range_m[cand], az, power[cand], rcs[cand], self.spec, rng)]
        rel_v = scene.agents.velocities_of(hits.instance_id[keep]) - ego.velocity_map_mps
        radial = np.einsum("ij,ij->i", rel_v, rays[keep, 3:6].astype(np.float64))
        scan = self._scan(keep, hits.range_m[keep], radial, power[keep], hits.instance_id[keep], cls_all[keep], rng)
        return RadarOutput(self.spec, scan)

    def _scan(
        self,
        keep: npt.NDArray[np.int64],
        range_m: npt.NDArray[np.float32],
        radial_mps: npt.NDArray[np.float64],
        power_db: npt.NDArray[np.float64],
        instance_id: npt.NDArray[np.uint32],
        semantic_class: npt.NDArray[np.uint8],
        rng: np.random.Generator,
    ) -> RadarScan:
        r = range_m.astype(np.float64)
        if self.spec.range_noise_m > 0:
            r = r + rng.normal(0.0, self.spec.range_noise_m, r.shape[0])
        if self.spec.velocity_noise_mps > 0:
            radial_mps = radial_mps + rng.normal(0.0, self.spec.velocity_noise_mps, r.shape[0])
        dirs = self._dirs_radar[keep]
        f32 = np.float32
        return RadarScan(
            (dirs * r[:, None]).astype(f32),
            r.astype(f32),
            radial_mps.astype(f32),
            np.arctan2(dirs[:, 1], dirs[:, 0]).astype(f32),
            np.arcsin(np.clip(dirs[:, 2], -1.0, 1.0)).astype(f32),
            power_db.astype(f32),
            instance_id,
            semantic_class,
        )
