"""Spinning multi-beam LiDAR: ray pattern, cast, per-point time, class and instance.

``sweep: instant`` casts every ray at the frame's instant (no motion distortion, every point's
``t`` 0); ``sweep: timed`` fires each ray at its own time in the sweep and casts it with the ego
and the agents where they are then (:mod:`sensors.sweep`), and ``deskew: true`` adds each
point moved to the sweep's reference time by the ego's motion.
Intensity (``intensity: physical``) = reflectivity(part or class) * |cos(incidence)| *
exp(-range / 200 m), in 0..1 (painted parts by their colour; retro-reflective plates, signs and
road paint without the cosine; glass returns nothing, the ray goes on); ``intensity: kitti``
reads it as KITTI's HDL-64E does (:data:`INTENSITY_RESPONSES`); with ``range_10pct_m`` a return is
kept with a chance from its received power (:meth:`Lidar.detection_probability`); an
optional :class:`~sensors.weather.Weather` (rain, fog) shortens the range, weakens and drops
returns and adds near spurious ones; day and night change nothing.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ClassVar, Literal

import numpy as np
import numpy.typing as npt
from numba import njit

from networks.classes import SemanticClass
from networks.geometry import SE3
from networks.records import check_arrays
from networks.vocabulary import SensorKind
from sensors.agents import EgoState, turned_about_z
from sensors.beam import SLICES, BeamEchoes, beam_echoes, edge_shots, spot_directions
from sensors.errors import SensorConfigError
from sensors.hits import RayHits
from sensors.materials import REFLECTIVITY_BY_CLASS, RETRO_BY_CLASS
from sensors.parts import (
    COLOURED_BY_PAINT,
    PAINT_REFLECTIVITY_FLOOR,
    PAINT_REFLECTIVITY_PER_ALBEDO,
    PALETTE_SALT,
    PALETTES,
    REFLECTIVITY_BY_PART,
    RETRO_PARTS,
    Part,
)
from sensors.rays import sensor_rays
from sensors.shade_kernels import palette_row
from sensors.sweep import deskewed, near_pairs, nearest, ray_times_s, reference_s, sensor_origins
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
    name: str = SensorKind.LIDAR.value  # named after its kind unless the rig names it
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
    sweep: Literal["instant", "timed"] = "instant"  # rays at the frame's instant, or each at its time
    firing: Literal["even", "hdl64e", "hdl32e"] = "even"  # the beams' firing pattern in a column
    reference: Literal["start", "middle", "end"] = "middle"  # the sweep's time of the frame's state and boxes
    deskew: bool = False  # also give each point moved to the reference time by the ego's motion
    # Returns lost by received power (Lidar.detection_probability): the range at which a 10 %
    # target returns half the time (0: every hit within range returns).
    range_10pct_m: float = 0.0
    intensity: Literal["physical", "kitti"] = "physical"  # the intensity's scale (INTENSITY_RESPONSES)
    # Each beam's spot widens by this much (horizontal, vertical; 0: a thin ray): spots straddling
    # depth edges give mixed returns (sensors.beam).
    beam_divergence_mrad: tuple[float, float] = (0.0, 0.0)
    returns: Literal["strongest", "dual"] = "strongest"  # dual: the strongest and the last echo of each shot

    def __post_init__(self) -> None:
        if self.elevations_deg:
            e = self.elevations_deg
            if len(e) != self.beams or any(b <= a for a, b in itertools.pairwise(e)) or not -90 <= e[0] <= e[-1] <= 90:
                raise SensorConfigError(
                    f"lidar {self.name}: elevations_deg must hold `beams` ({self.beams}) angles, rising, within -90..90"
                )
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
        if not 0.0 <= self.range_10pct_m <= self.range_m:
            raise SensorConfigError(f"lidar {self.name}: range_10pct_m must be in 0..range_m, got {self.range_10pct_m}")
        if (self.firing, self.beams) not in {("hdl64e", 64), ("hdl32e", 32)} and self.firing != "even":
            raise SensorConfigError(
                f"lidar {self.name}: firing {self.firing} needs "
                f"{64 if self.firing == 'hdl64e' else 32} beams, got {self.beams}"
            )
        self._check_beam()

    def _check_beam(self) -> None:
        h, v = self.beam_divergence_mrad
        column_mrad = 2000.0 * np.pi / self.azimuth_steps
        ring_mrad = 1000.0 * float(np.diff(self.elevations_rad()).min()) if self.beams > 1 else np.inf
        if not (0.0 <= h < column_mrad and 0.0 <= v < min(ring_mrad, column_mrad)):
            raise SensorConfigError(
                f"lidar {self.name}: beam_divergence_mrad must be >= 0 and narrower than the "
                f"grid's spacing ({column_mrad:.2f} mrad across, {ring_mrad:.2f} mrad up), "
                f"got {list(self.beam_divergence_mrad)}"
            )
        if self.returns == "dual" and self.firing == "hdl64e":
            raise SensorConfigError(
                f"lidar {self.name}: returns dual: the HDL-64E S2 (firing hdl64e) reports one return per shot"
            )
        if self.returns == "dual" and not h > 0 and not v > 0:
            raise SensorConfigError(
                f"lidar {self.name}: returns dual needs beam_divergence_mrad (second echoes "
                "come from beams straddling edges)"
            )

    @property
    def ego_SE3_sensor(self) -> SE3:
        r, p, y = np.radians(self.mount_rpy_deg)
        return SE3.from_xyz_rpy(self.mount_xyz_m, r, p, y)

    @property
    def period_s(self) -> float:
        return 1.0 / self.rate_hz

    def elevations_rad(self) -> npt.NDArray[np.float64]:
        """``(beams,)`` each ring's elevation, lowest first."""
        spread = np.linspace(self.vertical_min_deg, self.vertical_max_deg, self.beams)
        return np.radians(np.asarray(self.elevations_deg, np.float64) if self.elevations_deg else spread)

    def directions(self) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.uint16]]:
        """Unit ray directions ``(beams * azimuth_steps, 3)`` in the lidar frame and the ring
        of each (ring 0 is the lowest beam); azimuth starts at +x and turns counter-clockwise."""
        elevation = self.elevations_rad()
        azimuth = np.arange(self.azimuth_steps) * (2.0 * np.pi / self.azimuth_steps)
        el, az = np.meshgrid(elevation, azimuth, indexing="ij")
        dirs = np.stack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)], axis=-1).reshape(-1, 3)
        ring = np.repeat(np.arange(self.beams, dtype=np.uint16), self.azimuth_steps)
        return dirs, ring


@dataclass(frozen=True, slots=True)
class LidarScan:
    """Returns of one sweep: ``xyz_lidar_m: (N, 3) float32`` in the lidar frame at each point's
    time, ``intensity: (N,) float32`` in 0..1, ``ring: (N,) uint16``, ``semantic_class: (N,)
    uint8``, ``instance_id: (N,) uint32`` (0 for the static world), ``t_s: (N,) float32`` seconds
    from the sweep's start (0 for an instant sweep), and ``xyz_deskewed_lidar_m: (N, 3) float32``
    the points in the lidar frame at the sweep's reference time (``(0, 3)``: not asked for)."""

    xyz_lidar_m: npt.NDArray[np.float32]
    intensity: npt.NDArray[np.float32]
    ring: npt.NDArray[np.uint16]
    semantic_class: npt.NDArray[np.uint8]
    instance_id: npt.NDArray[np.uint32]
    t_s: npt.NDArray[np.float32]
    xyz_deskewed_lidar_m: npt.NDArray[np.float32]

    def __post_init__(self) -> None:
        check_arrays(
            self, xyz_lidar_m=(np.float32, ("N", 3)), intensity=(np.float32, ("N",)), ring=(np.uint16, ("N",)),
            semantic_class=(np.uint8, ("N",)), instance_id=(np.uint32, ("N",)), t_s=(np.float32, ("N",)),
            xyz_deskewed_lidar_m=(np.float32, ("D", 3)),
        )  # fmt: skip
        if self.xyz_deskewed_lidar_m.shape[0] not in (0, len(self)):
            raise ValueError("LidarScan.xyz_deskewed_lidar_m: expected N or 0 rows")

    def __len__(self) -> int:
        return int(self.xyz_lidar_m.shape[0])


@dataclass(frozen=True, slots=True)
class LidarOutput:
    spec: LidarSpec
    scan: LidarScan


class Lidar:
    kind: ClassVar[SensorKind] = SensorKind.LIDAR

    def __init__(self, spec: LidarSpec) -> None:
        self.spec = spec
        self._dirs_lidar, self._ring = spec.directions()
        self._dirs32 = self._dirs_lidar.astype(np.float32)
        self._elevation_rad = spec.elevations_rad()
        self._t_s = ray_times_s(self._dirs_lidar, self._ring, spec.ego_SE3_sensor, spec.period_s, spec.azimuth_steps,
                                spec.firing, spec.beams)  # fmt: skip
        self._t_ref_s = reference_s(spec.reference, spec.period_s)
        self._t32 = self._t_s.astype(np.float32)
        response = INTENSITY_RESPONSES[spec.intensity]
        self._laser_gain = np.exp(
            response.laser_spread * np.random.default_rng(LASER_GAIN_SEED).standard_normal(spec.beams)
        )
        self._laser_floor = np.zeros(spec.beams)
        for beam, floor in response.laser_floors:
            if beam < spec.beams:
                self._laser_floor[beam] = floor

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
        swept = self._cast(scene, ego)
        rays = swept.rays
        hits, spurious = add_spurious_returns(swept.hits, rays, w, rng)
        share = None  # each echo's share of its shot's power (a beam at an edge), where beams are wide
        ray_of = np.arange(rays.shape[0])  # the shot of each echo
        if any(d > 0 for d in self.spec.beam_divergence_mrad):
            echoes = self._beam_echoes(scene, ego, swept, hits, spurious)
            hits, ray_of, share = echoes.hits, echoes.ray, echoes.share
            rays, spurious = rays[ray_of], spurious[ray_of]
        keep = hits.range_m <= lidar_max_range_m(w, self.spec.range_m)
        dropout = lidar_dropout(w, self.spec.dropout) if w.lidar_dropout > 0 else self.spec.dropout
        if dropout > 0:
            keep &= rng.random(keep.shape[0]) >= dropout
        if self.spec.range_10pct_m > 0:
            keep = self._detected(hits, rays, keep & ~spurious, rng, share) | (keep & spurious)
        idx = np.flatnonzero(keep)
        shot = ray_of[idx]
        rng_m = hits.range_m[idx]
        noise_m = lidar_range_noise_m(w, self.spec.range_noise_m)
        if noise_m > 0:
            rng_m = (rng_m + rng.normal(0.0, noise_m, rng_m.shape[0])).astype(np.float32)
        xyz = self._dirs32[shot] * rng_m[:, None]
        cos_inc = np.abs(np.einsum("ij,ij->i", rays[idx, 3:6], hits.normal[idx]))
        cls = hits.semantic_class[idx]
        reflectance, retro = reflectance_of(cls, hits.part[idx], hits.instance_id[idx])
        if share is not None:
            reflectance = (reflectance * share[idx]).astype(np.float32)
        intensity: npt.NDArray[np.floating] = self._read_intensity(
            reflectance, retro, cos_inc, rng_m, hits.part[idx], self._ring[shot], rng, cls
        )
        if w.lidar_spurious_rate > 0 or w.lidar_intensity_scale != 1.0 or w.lidar_extinction_per_m > 0:
            intensity = intensity * lidar_intensity_factor(w, rng_m)
            intensity = np.where(spurious[idx], w.lidar_spurious_intensity, intensity)
        xyz = xyz.astype(np.float32, copy=False)
        timed = self.spec.sweep == "timed"
        t_s = self._t32[shot] if timed else np.zeros(idx.shape[0], np.float32)
        still = np.zeros((0, 3), np.float32)
        if self.spec.deskew:
            still = deskewed(xyz, t_s, self._t_ref_s, ego, map_SE3_lidar) if timed else xyz.copy()
        scan = LidarScan(
            xyz, intensity.astype(np.float32, copy=False), self._ring[shot], cls, hits.instance_id[idx], t_s, still
        )
        return LidarOutput(self.spec, scan)

    def _beam_echoes(
        self, scene: Scene, ego: EgoState, cast: CastSweep, hits: RayHits, left_out: npt.NDArray[np.bool_]
    ) -> BeamEchoes:
        """The echoes of wide beams (:mod:`sensors.beam`): the shots next to edges looked at
        across their spots, with rays cast at their shots' times."""
        spec = self.spec
        spots = []
        for axis, shots in enumerate(edge_shots(hits, spec.beams, spec.azimuth_steps, left_out)):
            width = spec.beam_divergence_mrad[axis] / 1000.0
            if width <= 0 or shots.size == 0:
                spots.append((shots[:0], _rows(hits, shots[:0])))
                continue
            dirs = spot_directions(self._dirs_lidar[shots], axis, width)
            spots.append((shots, self._cast_beside(scene, ego, cast, np.repeat(shots, SLICES), dirs)))
        return beam_echoes(hits, spots, self._spot_power, spec.returns == "dual")

    @staticmethod
    def _spot_power(hits: RayHits) -> npt.NDArray[np.float64]:
        """``(N,)`` received power of a whole spot on each hit: reflectance (times RETRO_GAIN on
        retro-reflectors) / range^2; 0 where nothing was met."""
        reflectance, retro = reflectance_of(hits.semantic_class, hits.part, hits.instance_id)
        r = np.where(hits.hit, hits.range_m, 1.0).astype(np.float64)
        return np.asarray(
            np.where(hits.hit, reflectance * np.where(retro, RETRO_GAIN, 1.0) / np.maximum(r, 0.1) ** 2, 0.0)
        )

    def _cast_beside(
        self, scene: Scene, ego: EgoState, cast: CastSweep, shot: npt.NDArray[np.intp],
        dirs_lidar: npt.NDArray[np.float64],
    ) -> RayHits:  # fmt: skip
        """Rays along ``dirs_lidar`` (LiDAR frame) from the sensor where it is at each ``shot``'s
        time, against the world as it is then (an agent paired with the shot, for timed sweeps)."""
        dirs = dirs_lidar @ cast.map_SE3_lidar.rotation.T
        if cast.turn is not None:
            dirs = turned_about_z(dirs, cast.turn[shot])
        rays = np.concatenate([cast.rays[shot, :3].astype(np.float64), dirs], axis=1).astype(np.float32)
        if cast.pairs is None:
            return through_glass(scene, rays, scene.cast(rays))
        ray_i, agent_i = cast.pairs
        order = np.argsort(ray_i, kind="stable")
        lo = np.searchsorted(ray_i[order], shot, side="left")
        hi = np.searchsorted(ray_i[order], shot, side="right")
        count = hi - lo
        within = np.arange(int(count.sum())) - np.repeat(np.cumsum(count) - count, count)
        agent = agent_i[order][np.repeat(lo, count) + within]
        sub = np.repeat(np.arange(shot.shape[0]), count)
        by_agent = np.argsort(agent, kind="stable")
        sub, agent = sub[by_agent], agent[by_agent]
        dt_s = self._t_s[shot] - self._t_ref_s
        return nearest(
            scene.cast_static(rays), scene.agents, sub, agent, scene.cast_agents_moving(rays, dt_s, sub, agent)
        )

    def detection_probability(
        self, hits: RayHits, rays: npt.NDArray[np.float32], share: npt.NDArray[np.float64] | None = None
    ) -> npt.NDArray[np.float64]:
        """``(N,)`` chance that each hit's echo rises above the sensor's noise floor: received
        power ``reflectance / range^2`` against that of a 10 % target at ``range_10pct_m``, which
        returns half the time; a logistic in log power (it falls from 0.9 to 0.1 as the power
        drops 3 times). The incidence angle does not enter: in real KITTI scans the road, hit
        2-3 deg from grazing, returns on 96-100 % of the rays out to 35-40 m and on half of them at
        about 48 m, as the HDL-64E S2 data sheet's 50 m for 10 % pavement says for a target faced
        (README, "LiDAR against real KITTI scans"). Retro-reflective surfaces
        (plates, signs, road paint) return RETRO_GAIN times brighter; ``share``: each echo's share of
        its beam's power (a beam straddling an edge)."""
        reflectance, retro = reflectance_of(hits.semantic_class, hits.part, hits.instance_id)
        if share is not None:
            reflectance = (reflectance * share).astype(np.float32)
        return _logistic(self._power_ratio(reflectance, retro, hits.range_m))

    def _power_ratio(
        self, reflectance: npt.NDArray[np.float32], retro: npt.NDArray[np.bool_], range_m: npt.NDArray[np.float32]
    ) -> npt.NDArray[np.float64]:
        """``(N,)`` received power against the noise floor's (that of a 10 % target at ``range_10pct_m``)."""
        power = reflectance * np.where(retro, RETRO_GAIN, 1.0) / np.maximum(range_m.astype(np.float64), 0.1) ** 2
        return np.asarray(power * (self.spec.range_10pct_m**2 / 0.1))

    def _read_intensity(
        self, reflectance: npt.NDArray[np.float32], retro: npt.NDArray[np.bool_], cos_inc: npt.NDArray[np.float32],
        range_m: npt.NDArray[np.float32], part: npt.NDArray[np.uint8], ring: npt.NDArray[np.uint16],
        rng: np.random.Generator, semantic_class: npt.NDArray[np.uint8] | None = None,
    ) -> npt.NDArray[np.float32]:  # fmt: skip
        """Intensity as the spec's :class:`IntensityResponse` reads it (``semantic_class``: for
        the asphalt's grain, where the response has it)."""
        r = INTENSITY_RESPONSES[self.spec.intensity]
        cos64 = cos_inc.astype(np.float64)
        if r.asphalt_stone > 0 and semantic_class is not None:  # each footprint's share of stone and binder
            asphalt = np.flatnonzero(np.isin(semantic_class, ASPHALT) & (part == Part.SURFACE))
            stone = rng.beta(r.stone_share_beta[0], r.stone_share_beta[1], asphalt.shape[0])
            reflectance = reflectance.copy()
            reflectance[asphalt] = r.asphalt_binder + (r.asphalt_stone - r.asphalt_binder) * stone
        facing = np.where(retro, r.retro, cos64**r.incidence_exponent)
        if r.sheeting_echo != 1.0:  # prismatic sheeting (plates, cone bands) against glass-bead road paint
            facing = np.where(np.isin(part, SHEETING_PARTS), facing * r.sheeting_echo, facing)
        echo_share = None  # each echo against a matte surface's of the same reflectivity, where paint glints
        if r.glint_chance > 0:  # clear-coated paint: a glint straight back, or nothing the sensor reads
            glossy = np.flatnonzero(np.isin(part, GLOSSY_PARTS))
            glint = rng.random(glossy.shape[0]) < r.glint_chance * cos64[glossy] ** r.glint_falloff
            facing[glossy] = glint
            echo_share = np.ones(facing.shape[0])
            echo_share[glossy] = np.where(glint, r.glint_echo, 0.0)
        echo_read = reflectance * facing * np.exp(range_m * (-1.0 / 200.0))
        value = r.scale * (echo_read if r.exponent == 1.0 else echo_read**r.exponent)
        if r.fade_above_floor > 0 and self.spec.range_10pct_m > 0:
            echo = reflectance if echo_share is None else (reflectance * echo_share).astype(np.float32)
            above = np.log(np.maximum(self._power_ratio(echo, retro, range_m), 1e-30) / r.fade_above_floor)
            value = value * np.clip(above / r.fade_width, 0.0, 1.0)
        if r.laser_spread > 0:
            value = value * self._laser_gain[ring]
        if r.point_spread > 0:
            value = value * np.exp(r.point_spread * rng.standard_normal(value.shape[0]))
        if r.laser_floors:
            floor = self._laser_floor[ring]
            steeper = np.maximum(value - floor, 0.0) * (r.floor_reference / (r.floor_reference - floor))
            value = np.where(floor > 0, steeper, value)
        value = np.minimum(value, r.top)
        if r.step > 0:
            value = np.round(value / r.step) * r.step
        return np.asarray(value, np.float32)

    def _detected(
        self, hits: RayHits, rays: npt.NDArray[np.float32], candidates: npt.NDArray[np.bool_], rng: np.random.Generator,
        share: npt.NDArray[np.float64] | None = None,
    ) -> npt.NDArray[np.bool_]:  # fmt: skip
        """Which ``candidates`` return: each with its :meth:`detection_probability` (one draw each)."""
        at = np.flatnonzero(candidates)
        chance = self.detection_probability(_rows(hits, at), rays[at], None if share is None else share[at])
        out = np.zeros_like(candidates)
        out[at] = rng.random(at.shape[0]) < chance
        return out

    def cast(self, scene: Scene, ego: EgoState) -> tuple[npt.NDArray[np.float32], RayHits]:
        """Every ray of the sweep (map frame; each from where the sensor is at its time) and what
        it hits first, looking through glass."""
        swept = self._cast(scene, ego)
        return swept.rays, swept.hits

    def _cast(self, scene: Scene, ego: EgoState) -> CastSweep:
        map_SE3_lidar = ego.map_SE3_ego().compose(self.spec.ego_SE3_sensor)
        rays = sensor_rays(map_SE3_lidar, self._dirs32)
        if self.spec.sweep == "timed":
            return self._cast_timed(scene, ego, map_SE3_lidar, rays)
        hits = scene.cast_from(map_SE3_lidar.translation, map_SE3_lidar.rotation, self._dirs32)
        return CastSweep(rays, through_glass(scene, rays, hits), map_SE3_lidar, None, None)

    def _cast_timed(self, scene: Scene, ego: EgoState, map_SE3_lidar: SE3, rays: npt.NDArray[np.float32]) -> CastSweep:
        """Each ray from where the sensor is at its time and turned as the ego has turned then,
        against the static world and against each agent near its line of sight where that agent
        is then (rays move in place)."""
        dt_s = self._t_s - self._t_ref_s
        turn = None
        if not ego.turning():
            rays[:, :3] += (dt_s[:, None] * ego.velocity_map_mps[None, :]).astype(np.float32)
        else:
            origins, turn = sensor_origins(ego, map_SE3_lidar.translation, dt_s)
            rays[:, :3] = origins.astype(np.float32)
            rays[:, 3:6] = turned_about_z(rays[:, 3:6].astype(np.float64), turn).astype(np.float32)
        static = scene.cast_static(rays)
        agents = scene.agents
        dt_range = (-self._t_ref_s, self.spec.period_s - self._t_ref_s)
        ray_i, agent_i = near_pairs(agents, ego, map_SE3_lidar, dt_range, self.spec.azimuth_steps, self._elevation_rad)
        hits = nearest(static, agents, ray_i, agent_i, scene.cast_agents_moving(rays, dt_s, ray_i, agent_i))
        return CastSweep(rays, hits, map_SE3_lidar, (ray_i, agent_i), turn)


@dataclass(frozen=True, slots=True)
class CastSweep:
    """A sweep's cast: its rays (map frame, each where it was fired), their hits, the LiDAR's
    pose at the reference time, and for a timed sweep the ``(ray, agent)`` pairs cast and how far
    the ego had turned at each ray's time (None: not at all)."""

    rays: npt.NDArray[np.float32]
    hits: RayHits
    map_SE3_lidar: SE3
    pairs: tuple[npt.NDArray[np.intp], npt.NDArray[np.intp]] | None
    turn: npt.NDArray[np.float64] | None


RETRO_GAIN = 10.0  # a retro-reflector's echo against a white diffuse surface of the same reflectivity
DETECTION_WIDTH = 0.25  # the logistic's scale in log received power (0.9 -> 0.1 over a factor of 3)


def _logistic(power_ratio: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
    with np.errstate(divide="ignore"):
        log_ratio = np.log(np.maximum(power_ratio, 1e-30))
    return np.asarray(1.0 / (1.0 + np.exp(-log_ratio / DETECTION_WIDTH)))


@dataclass(frozen=True, slots=True)
class IntensityResponse:
    """How a LiDAR reads an echo as intensity: ``scale * echo ** exponent``, the echo being
    ``reflectivity * facing * exp(-range / 200 m)``, where ``facing`` is ``|cos|^incidence_exponent``
    on matte surfaces and ``retro`` on retro-reflective ones (an ``exponent`` under 1 compresses:
    bright surfaces read little more than dark ones). Clear-coated paint (:data:`GLOSSY_PARTS`),
    where ``glint_chance`` > 0: each point either glints (with the chance ``glint_chance *
    |cos|^glint_falloff``: the clear coat or a metallic flake under it faces the beam and sends it
    straight back; ``facing`` 1, an echo ``glint_echo`` times a matte surface's) or sends the beam
    away (``facing`` 0, no echo the sensor reads); 0: read as matte. Faded to 0 as the received
    power falls from ``fade_above_floor * e^fade_width`` to ``fade_above_floor`` times the noise
    floor's (weak echoes are returned with intensity 0); each laser's own gain (log-normal,
    ``laser_spread``, fixed per sensor) and each point's (``point_spread``) on the reading; a
    laser listed in ``laser_floors`` as ``(beam, floor)`` reads ``(value - floor)`` scaled to agree
    with the others at ``floor_reference`` (steeper: dark surfaces read near 0, bright ones as on
    the other lasers); at most ``top``, in steps of ``step``. Where ``asphalt_stone`` > 0, each
    road point's reflectivity is that of its footprint's mix of aggregate stone
    (``asphalt_stone``) and bitumen binder (``asphalt_binder``), the stone's share drawn from a
    beta distribution (``stone_share_beta``); retro-reflective sheeting (:data:`SHEETING_PARTS`:
    prismatic number plates, cone and barrier bands) answers ``sheeting_echo`` times as the
    glass beads of road paint do."""

    scale: float = 1.0
    exponent: float = 1.0
    incidence_exponent: float = 1.0
    retro: float = 1.0
    glint_chance: float = 0.0
    glint_falloff: float = 0.0
    glint_echo: float = 1.0
    fade_above_floor: float = 0.0
    fade_width: float = 1.0
    laser_spread: float = 0.0
    point_spread: float = 0.0
    laser_floors: tuple[tuple[int, float], ...] = ()
    floor_reference: float = 1.0
    asphalt_binder: float = 0.0
    asphalt_stone: float = 0.0
    stone_share_beta: tuple[float, float] = (1.0, 1.0)
    sheeting_echo: float = 1.0
    top: float = 1.0
    step: float = 0.0


# ``kitti``: fitted to seven real KITTI object-benchmark scans (training frames 000000-000003, 000008,
# 002155, 007347; points in cam2's view, cars by their 3D labels, road and lane paint on the
# ground plane by cam2's pixels), README "LiDAR against real KITTI scans". Road 0.08/0.26/0.34
# (p10/p50/p90), within 0.01 of constant over 5-20 m whatever the angle (incidence_exponent 0) and
# 0.00 from about 28 m on (the fade); lane paint 0.32/0.42/0.57: surfaces about 5 times apart in
# reflectivity (asphalt 0.12, paint 0.6) read 1.6 times apart, and the brightest tenth of all
# points in view reads 0.42 and more (0.64 at p99), so the reading is compressed: 0.49 *
# echo^0.3 puts asphalt at 0.26 and paint, read by its reflectivity (retro 1), at 0.42, and a
# building's or kerb's 0.3-0.5 at 0.34-0.40. Cars 0.00/0.00/0.45, 55 % of their points at 0; by
# incidence (normals from 12 neighbours) 35 % at 0 met squarely, 45 % at |cos| 0.8-0.95, 58 % at
# 0.5-0.8 and 68 % under 0.5: a clear coat met squarely does not answer on every point, and
# answers less often off the normal: glint chance 0.6 |cos|^2, each glint's echo 10 times a matte
# surface's (RETRO_GAIN: a mirror sends the beam straight back). Each laser reads the same road
# by its own steady factor (0.04 to 0.32 between lasers): laser_spread 0.2; road and paint read
# up to 1.31 and 1.33 times their medians at p90 (a log spread of 0.22 in all), which leaves
# each point 0.1 (point_spread); in 0.01 steps up to 0.99 as KITTI stores them.
# The road read in 0.1 bins (range-matched, 5-40 m) is 11/18/38/30/2 %: a quarter of its points
# read under 0.2, most of them from four lasers, at -13.1, -12.6, -10.2 and -9.8 deg (beams 22,
# 23, 28, 29 here), which in every scan read the road at 0.52-0.88 of the others' and on dark
# asphalt often near 0 (up to 80 % of their points under 0.1), while on lane paint they read as
# the others do: each has its own intensity floor (laser_floors, fitted to the road's reading on
# each of them, 0.52, 0.65, 0.77 and 0.88 times the others', with the paint's 0.42 in common),
# as the HDL-64E's per-laser minimum and maximum intensity calibration gives. Within one
# laser's ring the asphalt reads down to 0.6 times its median at p10 and 0.4 at p5: each
# footprint, 2-3 cm wide, holds its own mix of aggregate stone and bitumen binder (reflectivity
# 0.27 and 0.02, the stone's share from Beta(0.4, 0.3); the reading only, returns still go by
# the class's 0.12). Number plates read 0.9-0.99 (the cars' 3 % at
# 0.9-1.0): prismatic sheeting returns far more than road paint's beads (sheeting_echo 10).
INTENSITY_RESPONSES: dict[str, IntensityResponse] = {
    "physical": IntensityResponse(),
    "kitti": IntensityResponse(scale=0.49, exponent=0.3, incidence_exponent=0.0, retro=1.0, glint_chance=0.6,
                               glint_falloff=2.0, glint_echo=RETRO_GAIN, fade_above_floor=5.0, fade_width=1.0,
                               laser_spread=0.2, point_spread=0.1,
                               laser_floors=((22, 0.115), (23, 0.069), (28, 0.152), (29, 0.184)), floor_reference=0.42,
                               asphalt_binder=0.02, asphalt_stone=0.27, stone_share_beta=(0.4, 0.3),
                               sheeting_echo=RETRO_GAIN, top=0.99, step=0.01),
}  # fmt: skip
GLOSSY_PARTS = np.array([Part.PAINT, Part.CAB, Part.LIVERY, Part.SAFETY_YELLOW], np.uint8)
SHEETING_PARTS = np.array([Part.PLATE, Part.RETRO_WHITE, Part.RETRO_YELLOW], np.uint8)
ASPHALT = np.array([SemanticClass.ROAD, SemanticClass.PARKING], np.uint8)  # the classes whose surface is asphalt
LASER_GAIN_SEED = 64
GLASS_LAYERS = 4  # panes a ray passes through at most (a car's windscreen and rear window, and back)
PAST_GLASS_M = 1e-4


def through_glass(scene: Scene, rays: npt.NDArray[np.float32], hits: RayHits) -> RayHits:
    """``hits`` with every ray that met glass continued to the first surface behind it (glass
    returns nothing at the LiDAR's wavelength here: its own return is weak and mostly lost)."""
    glass = np.flatnonzero(hits.part == Part.GLASS)
    if glass.size == 0:
        return hits
    range_m, cls, inst = hits.range_m.copy(), hits.semantic_class.copy(), hits.instance_id.copy()
    normal, part = hits.normal.copy(), hits.part.copy()
    for _ in range(GLASS_LAYERS):
        past = range_m[glass] + PAST_GLASS_M
        again = rays[glass].copy()
        again[:, :3] += again[:, 3:6] * past[:, None]
        more = scene.cast(again)
        range_m[glass] = past + more.range_m
        cls[glass], inst[glass], part[glass] = more.semantic_class, more.instance_id, more.part
        normal[glass] = more.normal
        glass = glass[more.part == Part.GLASS]
        if glass.size == 0:
            break
    return RayHits(range_m, cls, inst, normal, part)


def _rows(hits: RayHits, at: npt.NDArray[np.intp]) -> RayHits:
    return RayHits(hits.range_m[at], hits.semantic_class[at], hits.instance_id[at], hits.normal[at], hits.part[at])


def _reflectance_tables() -> tuple[Any, ...]:
    """The tables of :func:`_reflectance`: the parts' and classes' reflectivity and
    retro-reflection (:mod:`sensors.parts`, :mod:`sensors.materials`), per part whether its colour
    is its instance's paint and whether it is retro-reflective; the paints' palettes one after
    another (each part's first row, size and salt)."""
    painted = np.zeros(256, np.bool_)
    painted[[int(p) for p in COLOURED_BY_PAINT]] = True
    retro = np.zeros(256, np.bool_)
    retro[[int(p) for p in RETRO_PARTS]] = True
    first, size, salt = np.zeros(256, np.int64), np.zeros(256, np.int64), np.zeros(256, np.uint64)
    at = 0
    for p in COLOURED_BY_PAINT:
        first[int(p)], size[int(p)], salt[int(p)] = at, PALETTES[p].shape[0], PALETTE_SALT[p]
        at += PALETTES[p].shape[0]
    palettes = np.concatenate([PALETTES[p] for p in COLOURED_BY_PAINT]).astype(np.float32)
    return (np.asarray(REFLECTIVITY_BY_PART, np.float32), np.asarray(REFLECTIVITY_BY_CLASS, np.float32),
            np.asarray(RETRO_BY_CLASS, np.bool_), painted, retro, first, size, salt, palettes)  # fmt: skip


_REFLECTANCE_TABLES = _reflectance_tables()


def reflectance_of(
    semantic_class: npt.NDArray[np.uint8], part: npt.NDArray[np.uint8], instance_id: npt.NDArray[np.uint32]
) -> tuple[npt.NDArray[np.float32], npt.NDArray[np.bool_]]:
    """``(N,)`` LiDAR reflectivity of surfaces (painted parts by their instance's colour, other
    parts by the table, the static world by class) and whether each is retro-reflective
    (number plates; signs and road paint), in one compiled pass."""
    by_part, by_class, retro_by_class, painted, retro, first, size, salt, palettes = _REFLECTANCE_TABLES
    return _reflectance(
        np.ascontiguousarray(semantic_class, np.uint8), np.ascontiguousarray(part, np.uint8),
        np.ascontiguousarray(instance_id, np.uint32), by_part, by_class, retro_by_class, painted, retro, first, size,
        salt, palettes, np.float32(PAINT_REFLECTIVITY_FLOOR), np.float32(PAINT_REFLECTIVITY_PER_ALBEDO),
    )  # fmt: skip


@njit(cache=True, nogil=True)
def _reflectance(
    cls: npt.NDArray[np.uint8], part: npt.NDArray[np.uint8], instance: npt.NDArray[np.uint32],
    by_part: npt.NDArray[np.float32], by_class: npt.NDArray[np.float32], retro_by_class: npt.NDArray[np.bool_],
    painted: npt.NDArray[np.bool_], retro_part: npt.NDArray[np.bool_], first: npt.NDArray[np.int64],
    size: npt.NDArray[np.int64], salt: npt.NDArray[np.uint64], palettes: npt.NDArray[np.float32],
    floor: np.float32, per_albedo: np.float32,
) -> tuple[npt.NDArray[np.float32], npt.NDArray[np.bool_]]:  # fmt: skip  # pragma: no cover - compiled
    """Per hit its reflectivity (by part on agents, by class on the static world; a painted part
    ``floor + per_albedo`` times the mean of its :func:`~sensors.shade_kernels.palette_row` colour,
    in float32) and whether it is retro-reflective."""
    n = part.shape[0]
    out = np.empty(n, np.float32)
    retro = np.empty(n, np.bool_)
    for i in range(n):
        p = part[i]
        if p > 0:
            out[i] = by_part[p]
            retro[i] = retro_part[p]
        else:
            out[i] = by_class[cls[i]]
            retro[i] = retro_by_class[cls[i]]
        if painted[p]:
            row = palette_row(instance[i], p, first, size, salt)
            mean = (palettes[row, 0] + palettes[row, 1] + palettes[row, 2]) / np.float32(3.0)
            out[i] = floor + per_albedo * mean
    return out, retro
