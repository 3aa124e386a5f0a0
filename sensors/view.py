"""Which agents a sensor's rays can reach: a conservative test of bounding spheres against
the sensor's range and field of view. An agent that fails it cannot be hit by any ray of
the sensor within its range, so leaving it out of the frame's scene changes no return."""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from networks.geometry import SE3

F64 = npt.NDArray[np.float64]
MARGIN_M = 0.5  # on top of each sphere's radius, far more than float32 rounding of the rays


def spheres_in_view(
    sensor_SE3_map: SE3,
    center_map_m: F64,
    radius_m: F64,
    range_m: float,
    hfov_deg: float = 360.0,
    vfov_deg: float = 180.0,
    elevation_fov: bool = False,
) -> npt.NDArray[np.bool_]:
    """Whether each sphere may meet the sensor's view. The sensor frame looks along +x, y left,
    z up; the view is within ``range_m`` of the origin, within ``hfov_deg / 2`` of azimuth and
    either within ``vfov_deg / 2`` of elevation (``elevation_fov``: rays on an azimuth and
    elevation grid) or between the two tilted planes of a pinhole image's top and bottom edge."""
    c = sensor_SE3_map.transform_from(center_map_m)
    r = radius_m + MARGIN_M
    keep = np.linalg.norm(c, axis=1) - r <= range_m
    if hfov_deg < 180.0:  # signed distance to the nearer side plane of the azimuth wedge
        h = math.radians(hfov_deg / 2.0)
        keep &= np.abs(c[:, 1]) * math.cos(h) - c[:, 0] * math.sin(h) <= r
    if vfov_deg < 180.0:  # the same in the plane of the forward (or horizontal) axis and z
        v = math.radians(vfov_deg / 2.0)
        forward = np.hypot(c[:, 0], c[:, 1]) if elevation_fov else c[:, 0]
        keep &= np.abs(c[:, 2]) * math.cos(v) - forward * math.sin(v) <= r
    return np.asarray(keep)


def bounding_radius_m(lwh_m: F64) -> F64:
    """Radius of the sphere around a box's centre that holds the box (and its mesh)."""
    return np.asarray(np.linalg.norm(lwh_m, axis=1) / 2.0)
