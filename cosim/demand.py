"""Traffic demand as data: vehicle kinds with size ranges, variants, target counts."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from networks.classes import SemanticClass


@dataclass(frozen=True, slots=True)
class KindSpec:
    """Ranges a vehicle kind's types are sampled from (metres, m/s, m/s^2)."""

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


KINDS: dict[str, KindSpec] = {
    spec.kind: spec
    for spec in (
        KindSpec("car", "passenger", SemanticClass.CAR,
                 (3.9, 5.0), (1.70, 1.95), (1.40, 1.75), (38, 55), (2.3, 3.2), 4.5, "passenger"),
        KindSpec("truck", "truck", SemanticClass.TRUCK,
                 (6.5, 12.0), (2.35, 2.55), (2.9, 3.8), (24, 28), (1.0, 1.5), 4.0, "truck"),
        KindSpec("bus", "bus", SemanticClass.BUS,
                 (10.5, 13.5), (2.50, 2.55), (3.0, 3.3), (22, 27), (1.0, 1.3), 4.0, "bus"),
        KindSpec("motorcycle", "motorcycle", SemanticClass.MOTORCYCLE,
                 (1.9, 2.3), (0.7, 0.9), (1.4, 1.6), (35, 50), (3.0, 4.5), 6.0, "motorcycle"),
        KindSpec("bicycle", "bicycle", SemanticClass.BICYCLE,
                 (1.6, 1.9), (0.55, 0.7), (1.6, 1.85), (4.5, 7.0), (1.0, 1.5), 3.0, "bicycle"),
    )
}  # fmt: skip

PEDESTRIAN = KindSpec("pedestrian", "pedestrian", SemanticClass.PEDESTRIAN,
                      (0.3, 0.5), (0.5, 0.7), (1.55, 1.95), (1.0, 1.6), (1.0, 1.5), 2.0, "pedestrian")  # fmt: skip
"""A walker's box holds its stride: 0.6-0.8 m long (nuScenes' pedestrians: 0.73 m on average)."""

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


def sample_variants(spec: KindSpec, rng: np.random.Generator, count: int = VARIANTS_PER_KIND) -> list[TypeVariant]:
    """``count`` types of a kind, sized uniformly within its ranges (the renderer draws each
    with the body type that fits its size best: :func:`sensors.bodies.body_of`)."""
    out = []
    for i in range(count):
        size = rng.uniform([spec.length_m[0], spec.width_m[0], spec.height_m[0]],
                           [spec.length_m[1], spec.width_m[1], spec.height_m[1]])  # fmt: skip
        out.append(
            TypeVariant(
                f"{spec.kind}_{i}",
                spec,
                round(float(size[0]), 2),
                round(float(size[1]), 2),
                round(float(size[2]), 2),
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
