"""Weather and light presets and the pure functions the sensors use to apply them.

Light (day, night) changes only the camera. Rain and fog also shorten the LiDAR's
reach, weaken its returns (two-way extinction), drop returns and add near spurious
returns off droplets. Radar is treated as unaffected by any of them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from networks.errors import quoted
from sensors.errors import SensorConfigError
from sensors.hits import RayHits

BGR = tuple[float, float, float]


SUN_MIN_Z = 0.454
"""The lowest sun (sin 27 degrees): agents' shadows then stay within the camera's culling margin."""


@dataclass(frozen=True, slots=True)
class Weather:
    """Numbers of one weather and light condition.

    LiDAR: ``lidar_range_scale`` multiplies the spec's range; intensity is multiplied by
    ``lidar_intensity_scale * exp(-2 * lidar_extinction_per_m * range)``; a return is
    dropped with probability ``lidar_dropout``; a ray gets a spurious return at
    ``lidar_spurious_min_m .. lidar_spurious_max_m`` with probability ``lidar_spurious_rate``
    (class NONE, instance 0, intensity ``lidar_spurious_intensity``).
    Camera: ``sun_dir_map`` (unit, towards the sun) lights with ``sun_gain``, everything
    gets ``ambient``; a light at the camera (headlights) adds ``headlight_gain`` fading
    over ``headlight_range_m``; ``haze_m`` is the distance of 63 % haze towards
    ``haze_bgr``; misses show a gradient from ``sky_horizon_bgr`` to ``sky_zenith_bgr``;
    ``exposure`` scales the image and ``noise_sigma`` (0..255 scale) adds Gaussian noise.
    ``wet_ground``: the mirror strength of paved ground under a film of water at normal
    incidence (0: dry; water 0.02), growing towards grazing angles by Schlick's term: a wet
    road mirrors the sky in the distance and stays dark close by.
    At night ``lamp_key_gain`` stands for the street lamps overhead: one warm light from
    ``sun_dir_map`` with its shadows (the realistic camera's shadow rays), so that roofs and
    bonnets catch the light, sides fall darker and every road user casts a shadow.
    """

    name: str
    lidar_range_scale: float = 1.0
    lidar_intensity_scale: float = 1.0
    lidar_extinction_per_m: float = 0.0
    lidar_dropout: float = 0.0
    lidar_range_noise_m: float = 0.0
    lidar_spurious_rate: float = 0.0
    lidar_spurious_min_m: float = 0.5
    lidar_spurious_max_m: float = 8.0
    lidar_spurious_intensity: float = 0.02
    sun_dir_map: tuple[float, float, float] = (-0.45, 0.35, 0.82)
    sun_gain: float = 0.75
    lamp_key_gain: float = 0.0
    ambient: float = 0.35
    headlight_gain: float = 0.0
    headlight_range_m: float = 25.0
    haze_m: float = 2500.0
    haze_bgr: BGR = (235.0, 215.0, 200.0)
    sky_horizon_bgr: BGR = (240.0, 220.0, 200.0)
    sky_zenith_bgr: BGR = (200.0, 130.0, 70.0)
    exposure: float = 1.0
    noise_sigma: float = 0.0
    saturation: float = 1.3
    wet_ground: float = 0.0

    def __post_init__(self) -> None:
        if not 0.0 < self.lidar_range_scale <= 1.0 or not 0.0 < self.lidar_intensity_scale <= 1.0:
            raise SensorConfigError(f"weather {self.name}: lidar range and intensity scales must be in (0, 1]")
        if not 0.0 <= self.lidar_dropout < 1.0 or not 0.0 <= self.lidar_spurious_rate < 1.0:
            raise SensorConfigError(f"weather {self.name}: lidar dropout and spurious rate must be in [0, 1)")
        if not 0.0 < self.lidar_spurious_min_m < self.lidar_spurious_max_m:
            raise SensorConfigError(f"weather {self.name}: need 0 < lidar_spurious_min_m < lidar_spurious_max_m")
        if min(self.lidar_extinction_per_m, self.lidar_range_noise_m, self.noise_sigma, self.ambient) < 0:
            raise SensorConfigError(f"weather {self.name}: extinction, noise and ambient must be >= 0")
        if not 0.0 <= self.wet_ground <= 1.0:
            raise SensorConfigError(f"weather {self.name}: wet_ground must be in [0, 1], got {self.wet_ground}")
        if self.lamp_key_gain < 0:
            raise SensorConfigError(f"weather {self.name}: lamp_key_gain must be >= 0")
        if not 0.0 <= self.saturation <= 3.0:
            raise SensorConfigError(f"weather {self.name}: saturation must be in [0, 3], got {self.saturation}")
        if self.haze_m <= 0 or self.headlight_range_m <= 0 or self.exposure <= 0:
            raise SensorConfigError(f"weather {self.name}: haze_m, headlight_range_m and exposure must be > 0")
        sun = np.asarray(self.sun_dir_map, dtype=np.float64)
        if sun.shape != (3,) or not np.isclose(np.linalg.norm(sun), 1.0, atol=0.05):
            raise SensorConfigError(f"weather {self.name}: sun_dir_map must be a unit 3-vector")
        if self.sun_gain > 0 and sun[2] < SUN_MIN_Z:
            raise SensorConfigError(
                f"weather {self.name}: the sun must stand at least 27 degrees high "
                f"(sun_dir_map z >= {SUN_MIN_Z:.3f}), got z = {sun[2]:.3f}"
            )


PRESETS: dict[str, Weather] = {
    # day: haze_m 2500 m puts the 5 % contrast visibility near 7.5 km, a clear day's in a town
    # (clean air 20 km and more): a car 40 m away keeps 98 % of its own light
    "day": Weather("day"),
    # night: a town's sky glows with its own light scattered back by the air and the clouds'
    # undersides (overcast city skies several times brighter than clear ones: Kyba et al. 2011,
    # PLoS ONE 6(3) e17307), a warm brownish grey brightest at the horizon, not a dark blue
    "night": Weather(
        "night", sun_gain=0.0, lamp_key_gain=0.5, sun_dir_map=(-0.3, 0.24, 0.92325),
        ambient=0.05, headlight_gain=0.6, headlight_range_m=18.0, haze_m=400.0,
        haze_bgr=(28.0, 33.0, 40.0), sky_horizon_bgr=(38.0, 44.0, 52.0), sky_zenith_bgr=(14.0, 14.0, 17.0),
        exposure=1.0, noise_sigma=6.0, saturation=1.0,
    ),
    # rain: haze_m 300 m puts the 5 % contrast visibility near 900 m, moderate rain's (WMO: 1-5 km
    # light to moderate, under 1 km heavy); wet roads mirror the sky (water's 2 % at normal
    # incidence); the camera's own spray and wet glass are not modelled
    "rain": Weather(
        "rain", lidar_range_scale=0.7, lidar_intensity_scale=0.8, lidar_extinction_per_m=0.004, lidar_dropout=0.08,
        lidar_range_noise_m=0.02, lidar_spurious_rate=0.004, lidar_spurious_max_m=6.0,
        sun_gain=0.2, ambient=0.4, headlight_gain=0.3, haze_m=300.0, haze_bgr=(150.0, 145.0, 140.0),
        sky_horizon_bgr=(160.0, 155.0, 150.0), sky_zenith_bgr=(120.0, 115.0, 110.0), exposure=0.8, noise_sigma=4.0,
        wet_ground=0.02,
    ),
    "fog": Weather(
        "fog", lidar_range_scale=0.35, lidar_intensity_scale=0.6, lidar_extinction_per_m=0.015, lidar_dropout=0.15,
        lidar_range_noise_m=0.03, lidar_spurious_rate=0.015, lidar_spurious_max_m=10.0,
        sun_gain=0.15, ambient=0.55, headlight_gain=0.2, haze_m=45.0, haze_bgr=(200.0, 200.0, 198.0),
        sky_horizon_bgr=(205.0, 205.0, 203.0), sky_zenith_bgr=(190.0, 190.0, 188.0), exposure=0.95, noise_sigma=2.0,
    ),
}  # fmt: skip
DAY = PRESETS["day"]


def weather_preset(name: str) -> Weather:
    """The preset called ``name`` (day, night, rain, fog)."""
    try:
        return PRESETS[name]
    except KeyError as err:
        msg = f"unknown weather {quoted(name)}; expected one of {', '.join(PRESETS)}"
        raise SensorConfigError(msg) from err


def lidar_max_range_m(weather: Weather, spec_range_m: float) -> float:
    return spec_range_m * weather.lidar_range_scale


def lidar_dropout(weather: Weather, spec_dropout: float) -> float:
    """Probability that a return is lost, from the sensor's own dropout and the weather's."""
    return 1.0 - (1.0 - spec_dropout) * (1.0 - weather.lidar_dropout)


def lidar_range_noise_m(weather: Weather, spec_noise_m: float) -> float:
    return float(np.hypot(spec_noise_m, weather.lidar_range_noise_m))


def add_spurious_returns(
    hits: RayHits, rays: npt.NDArray[np.float32], weather: Weather, rng: np.random.Generator
) -> tuple[RayHits, npt.NDArray[np.bool_]]:
    """Replace the return of a random ``lidar_spurious_rate`` of rays by a near droplet return
    (class NONE, instance 0, normal facing the ray) and say which ones. Draws nothing from
    ``rng`` when the rate is 0."""
    n = hits.range_m.shape[0]
    if weather.lidar_spurious_rate <= 0:
        return hits, np.zeros(n, np.bool_)
    spurious: npt.NDArray[np.bool_] = np.asarray(rng.random(n) < weather.lidar_spurious_rate)
    near = np.asarray(rng.uniform(weather.lidar_spurious_min_m, weather.lidar_spurious_max_m, n), np.float32)
    spurious &= near < hits.range_m
    range_m = np.where(spurious, near, hits.range_m)
    cls = np.where(spurious, np.uint8(0), hits.semantic_class)
    inst = np.where(spurious, np.uint32(0), hits.instance_id)
    normal = np.where(spurious[:, None], -rays[:, 3:6], hits.normal).astype(np.float32)
    part = np.where(spurious, np.uint8(0), hits.part)
    return RayHits(range_m.astype(np.float32), cls, inst, normal, part), spurious


def lidar_intensity_factor(weather: Weather, range_m: npt.NDArray[np.floating]) -> npt.NDArray[np.float64]:
    """Multiplier of LiDAR intensity: scale times two-way extinction over ``range_m``."""
    r = np.asarray(range_m, dtype=np.float64)
    return weather.lidar_intensity_scale * np.exp(-2.0 * weather.lidar_extinction_per_m * r)


def haze_fraction(weather: Weather, distance_m: npt.NDArray[np.float32], range_m: float) -> npt.NDArray[np.float32]:
    """``(N,)`` blend towards the haze colour: ``1 - exp(-d / haze_m)``, forced to 1 as ``d``
    nears the camera's range so the far cut-off fades into the sky."""
    d = np.asarray(distance_m, dtype=np.float32)
    fog = 1.0 - np.exp(-d / np.float32(weather.haze_m))
    edge = np.clip((d - np.float32(0.8 * range_m)) / np.float32(0.2 * range_m), 0.0, 1.0)
    return np.asarray(np.maximum(fog, edge * edge * (3.0 - 2.0 * edge)), dtype=np.float32)


def sky_bgr(weather: Weather, dir_z_map: npt.NDArray[np.float32]) -> npt.NDArray[np.float32]:
    """``(N, 3)`` sky colour for rays of map-frame elevation component ``dir_z_map``."""
    t = np.sqrt(np.clip(np.asarray(dir_z_map, dtype=np.float32), 0.0, 1.0))
    horizon = np.asarray(weather.sky_horizon_bgr, np.float32)
    zenith = np.asarray(weather.sky_zenith_bgr, np.float32)
    return np.asarray(horizon + t[:, None] * (zenith - horizon))


def image_noise(weather: Weather, rng: np.random.Generator, pixels: int) -> npt.NDArray[np.float32] | None:
    """``(pixels,) float32`` Gaussian sensor noise drawn from ``rng`` (None, and nothing drawn,
    when sigma is 0); the same for every colour channel of a pixel."""
    if weather.noise_sigma <= 0:
        return None
    return np.float32(weather.noise_sigma) * rng.standard_normal(pixels, dtype=np.float32)
