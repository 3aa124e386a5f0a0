"""Traffic demand as data: vehicle kinds with their size distributions, variants, target counts.

Every vehicle's length, width and height are drawn for it alone (:func:`sample_size`) from a
log-normal distribution per kind with the mean and spread of a real dataset's boxes,
truncated to the kind's range:

- car: nuScenes v1.0-trainval's ``vehicle.car`` boxes, 4.62 x 1.95 x 1.73 m, sd 0.46 / 0.19 /
  0.24 (over the annotations of its 34,149 keyframes; mmdetection3d's nuScenes anchor sizes, from the
  same boxes: 4.61 x 1.95 x 1.72, ``configs/_base_/models/pointpillars_hv_fpn_nus.py``);
- truck: nuScenes ``vehicle.truck``, 6.9 +- 2.2 m long (same measure) and 2.73 m high on
  average (mmdetection3d's anchors; height spread assumed: 0.5 m); 2.38 +- 0.1 m wide (assumed:
  nuScenes' 2.46 counts the mirrors, and the body stays within the 2.55 m EU law allows);
- bus: nuScenes ``vehicle.bus``, 11.19 m long and 3.47 m high on average (mmdetection3d's
  anchors; spreads assumed: 1.0, 0.2 m); 2.45-2.55 m wide, the most EU law allows (Directive
  96/53/EC; nuScenes' 2.94 counts the mirrors), as for trucks;
- motorcycle: nuScenes ``vehicle.motorcycle``, 2.10 x 0.76 m (mmdetection3d's anchors; its
  1.44 m mean height counts parked ones: ridden ones here are 1.4-1.6 m; spreads assumed);
- bicycle with its rider: KITTI's ``Cyclist`` boxes, 1.76 x 0.60 x 1.74 m (the mean sizes
  Frustum PointNets takes from KITTI's training labels, ``g_type_mean_size`` in its
  ``models/model_util.py``; spreads assumed: 0.1, 0.05, 0.07 m).

Dimensions are drawn with a correlation of 0.5 (an assumed figure: longer vehicles are
mostly wider and taller too)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from networks.classes import SemanticClass


@dataclass(frozen=True, slots=True)
class KindSpec:
    """Ranges a vehicle kind's sizes and types are sampled from (metres, m/s, m/s^2); sizes
    from a log-normal distribution (mean ``mean_lwh_m``, sd ``sd_lwh_m``) truncated to the ranges."""

    kind: str
    sumo_vclass: str
    semantic_class: SemanticClass
    length_m: tuple[float, float]
    width_m: tuple[float, float]
    height_m: tuple[float, float]
    max_speed_mps: tuple[float, float]
    accel_mps2: tuple[float, float]
    decel_mps2: float
    shape_class: str
    mean_lwh_m: tuple[float, float, float] | None = None
    sd_lwh_m: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        if self.mean_lwh_m is not None:
            for (lo, hi), mean in zip((self.length_m, self.width_m, self.height_m), self.mean_lwh_m, strict=True):
                if not lo <= mean <= hi:
                    raise ValueError(f"{self.kind}: mean size {mean} m outside its range {lo}-{hi} m")


KINDS: dict[str, KindSpec] = {
    spec.kind: spec
    for spec in (
        KindSpec("car", "passenger", SemanticClass.CAR,
                 (3.4, 5.9), (1.5, 2.4), (1.2, 2.35), (38, 55), (2.3, 3.2), 4.5, "passenger",
                 (4.62, 1.95, 1.73), (0.46, 0.19, 0.24)),
        KindSpec("truck", "truck", SemanticClass.TRUCK,
                 (4.0, 16.5), (2.0, 2.55), (2.0, 4.0), (24, 28), (1.0, 1.5), 4.0, "truck",
                 (6.9, 2.38, 2.73), (2.2, 0.1, 0.5)),
        # A truck with a centre-axle trailer, moved by SUMO as one vehicle and labelled as a
        # truck and a trailer (cosim/trailers.py); 18.75 m is the EU's limit for such a road
        # train; the sizes of the whole combination are assumed (17.0 m +- 0.8, as wide as the
        # law allows, 3.6 m high +- 0.2: the box bodies of road trains).
        KindSpec("truck_trailer", "truck", SemanticClass.TRUCK,
                 (15.5, 18.5), (2.45, 2.55), (3.3, 3.9), (22, 25), (0.8, 1.2), 4.0, "truck/trailer",
                 (17.0, 2.5, 3.6), (0.8, 0.03, 0.2)),
        KindSpec("bus", "bus", SemanticClass.BUS,
                 (9.0, 13.5), (2.45, 2.55), (3.0, 3.9), (22, 27), (1.0, 1.3), 4.0, "bus",
                 (11.19, 2.52, 3.47), (1.0, 0.03, 0.2)),
        KindSpec("motorcycle", "motorcycle", SemanticClass.MOTORCYCLE,
                 (1.8, 2.4), (0.65, 0.9), (1.4, 1.6), (35, 50), (3.0, 4.5), 6.0, "motorcycle",
                 (2.10, 0.76, 1.5), (0.15, 0.06, 0.06)),
        KindSpec("bicycle", "bicycle", SemanticClass.BICYCLE,
                 (1.55, 1.95), (0.5, 0.7), (1.6, 1.9), (4.5, 7.0), (1.0, 1.5), 3.0, "bicycle",
                 (1.76, 0.60, 1.74), (0.1, 0.05, 0.07)),
    )
}  # fmt: skip

PEDESTRIAN = KindSpec("pedestrian", "pedestrian", SemanticClass.PEDESTRIAN,
                      (0.3, 0.5), (0.5, 0.7), (1.55, 1.95), (1.0, 1.6), (1.0, 1.5), 2.0, "pedestrian")  # fmt: skip
"""Walkers' types: SUMO's length is the room a walker takes on the footpath (0.3-0.5 m); the
labelled box is lengthened about the same centre to hold the walker's stride as the traffic is
read (:func:`sensors.bodies.walker_length_m`: 0.57 x the height, 1.0 m for a walker 1.75 m
tall). Widths 0.5-0.7 m: real datasets' walker boxes are 0.6 (KITTI) to 0.84 m (Waymo) wide."""
CHILD = KindSpec("child", "pedestrian", SemanticClass.PEDESTRIAN,
                 (0.3, 0.45), (0.4, 0.5), (1.0, 1.45), (0.9, 1.4), (1.0, 1.5), 2.0, "pedestrian")  # fmt: skip
"""A child of about 4 to 10 years (1.0-1.45 m tall), labelled a pedestrian; it walks with a group
or alone (:mod:`cosim.sumo.people`)."""

VARIANTS_PER_KIND = 4


@dataclass(frozen=True, slots=True)
class TypeVariant:
    type_id: str
    spec: KindSpec
    length_m: float
    width_m: float
    height_m: float
    max_speed_mps: float
    accel_mps2: float


SIZE_CORRELATION = 0.5
"""Correlation between a vehicle's length, width and height (assumed)."""


def sample_size(spec: KindSpec, rng: np.random.Generator, max_length_m: float = np.inf) -> tuple[float, float, float]:
    """One vehicle's length, width and height (m, to the centimetre): log-normal with the kind's
    means and spreads (sizes are positive and skewed to the long side: long trucks, short
    pickups), correlation :data:`SIZE_CORRELATION` between the three; drawn again where outside
    the kind's ranges (and ``max_length_m``). Uniform within the ranges for kinds without a mean."""
    lo = np.array([spec.length_m[0], spec.width_m[0], spec.height_m[0]])
    hi = np.array([spec.length_m[1], spec.width_m[1], spec.height_m[1]])
    hi[0] = max(min(hi[0], max_length_m), lo[0])
    if spec.mean_lwh_m is None:
        return _centimetres(rng.uniform(lo, hi))
    mean, sd = np.asarray(spec.mean_lwh_m), np.asarray(spec.sd_lwh_m)
    sigma = np.sqrt(np.log1p((sd / mean) ** 2))  # the log-normal with this mean and sd
    mu = np.log(mean) - sigma**2 / 2
    size = mean
    for _ in range(20):
        shared, own = rng.standard_normal(), rng.standard_normal(3)
        size = np.exp(mu + sigma * (np.sqrt(SIZE_CORRELATION) * shared + np.sqrt(1 - SIZE_CORRELATION) * own))
        if np.all((size >= lo) & (size <= hi)):
            break
    return _centimetres(np.clip(size, lo, hi))


def _centimetres(size: npt.NDArray[np.float64]) -> tuple[float, float, float]:
    return (round(float(size[0]), 2), round(float(size[1]), 2), round(float(size[2]), 2))


def sample_variants(spec: KindSpec, rng: np.random.Generator, count: int = VARIANTS_PER_KIND) -> list[TypeVariant]:
    """``count`` types of a kind: speeds and accelerations, and a size drawn as a vehicle's is
    (:func:`sample_size`; the traffic then gives each vehicle a size of its own)."""
    out = []
    for i in range(count):
        size = sample_size(spec, rng)
        out.append(
            TypeVariant(
                f"{spec.kind}_{i}",
                spec,
                *size,
                round(float(rng.uniform(*spec.max_speed_mps)), 2),
                round(float(rng.uniform(*spec.accel_mps2)), 2),
            )
        )
    return out


def target_vehicle_count(vehicles_per_lane_km: float, lane_km: float, fixed: int | None) -> int:
    """Vehicles to keep in the network: a fixed count, else density times lane length."""
    if fixed is not None:
        return fixed
    return round(vehicles_per_lane_km * lane_km)


def split_by_mix(total: int, mix: dict[str, float]) -> dict[str, int]:
    """Integer counts per kind summing to ``total`` (largest remainder)."""
    kinds = sorted(k for k, v in mix.items() if v > 0)
    shares = np.array([mix[k] for k in kinds], dtype=np.float64)
    exact = shares / shares.sum() * total
    counts = np.floor(exact).astype(int)
    for i in np.argsort(-(exact - counts), kind="stable")[: total - counts.sum()]:
        counts[i] += 1
    return {k: int(c) for k, c in zip(kinds, counts, strict=True)}


def busiest(
    candidates_xy: npt.ArrayLike, agents_xy: npt.ArrayLike, radius_m: float, share: float
) -> npt.NDArray[np.intp]:
    """Indices (ascending) of the ``share`` of candidates (at least one) with the most
    agents within ``radius_m``: ``candidates_xy: (K, 2)``, ``agents_xy: (N, 2)``, map frame."""
    cand = np.asarray(candidates_xy, dtype=np.float64).reshape(-1, 2)
    agents = np.asarray(agents_xy, dtype=np.float64).reshape(-1, 2)
    near = np.linalg.norm(cand[:, None, :] - agents[None, :, :], axis=2) <= radius_m
    keep = max(1, int(np.ceil(share * len(cand))))
    return np.sort(np.argsort(-near.sum(axis=1), kind="stable")[:keep])
