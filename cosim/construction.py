"""Construction zones as data: where the cones, barriers and the work vehicle of a closed lane
stand (pure functions; :mod:`cosim.sumo.traffic` closes the lane in SUMO and adds the objects to
every world state).

Along the closed lane, from ``start_m``: a taper of cones leading diagonally from the lane's
far edge to the edge it shares with the open lane, a barrier across the lane where the taper
ends, cones along the shared edge every ``cone_spacing_m`` for ``length_m``, a second barrier
across the lane at the end, and a construction vehicle standing in the closed stretch (shifted
away from the open lane, so no two objects' boxes overlap: every LiDAR return falls in one
box). Boxes stand on the lane's surface (its shape's z) and follow its heading.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from networks.classes import SemanticClass
from networks.geometry import arc_lengths, point_and_heading

CONE_LWH_M = (0.4, 0.4, 0.75)  # EN 13422's 750 mm cone on its 400 mm base
BARRIER_LWH_M = (2.0, 0.5, 1.0)  # a water-filled plastic barrier element
WORK_VEHICLE_LWH_M = (7.0, 2.5, 3.2)
TAPER_M = 16.0  # from the lane's far edge to the shared edge (urban tapers: 1:5 to 1:10 of the lane's width x speed)
CLEAR_M = 2.0  # between a barrier and the nearest cone, along the lane
CONE_INSET_M = 0.25  # cone centres inside the closed lane's edges: clear of curbs and of the open lane's traffic
GAP_M = 0.2  # between the work vehicle's box and the cones' (a 7 m box on an 80 m radius bows 8 cm)


@dataclass(frozen=True, slots=True)
class ZoneLayout:
    """The zone's objects in the map frame: ``semantic_class: (N,) uint8``, ``center_map_m: (N, 3)
    float64`` box centres, ``lwh_m: (N, 3) float64``, ``yaw_map_rad: (N,) float64``."""

    semantic_class: npt.NDArray[np.uint8]
    center_map_m: npt.NDArray[np.float64]
    lwh_m: npt.NDArray[np.float64]
    yaw_map_rad: npt.NDArray[np.float64]

    def __len__(self) -> int:
        return int(self.semantic_class.shape[0])


def zone_layout(
    lane_shape_m: npt.ArrayLike, lane_width_m: float, open_side: int, start_m: float, length_m: float,
    cone_spacing_m: float, vehicle: bool,
) -> ZoneLayout:  # fmt: skip
    """The objects closing a lane: ``lane_shape_m: (K, 3)`` its centre line in the map frame
    (SUMO's lane shape), ``open_side`` +1 when the open lane is on its left, -1 on its right.
    The zone is clipped to the lane's length."""
    shape = np.asarray(lane_shape_m, np.float64)
    lane_length = float(arc_lengths(shape)[-1])
    half = lane_width_m / 2.0
    rows: list[tuple[SemanticClass, float, float, tuple[float, float, float], float]] = []  # class, s, d, lwh, yaw
    end = min(start_m + TAPER_M + length_m, lane_length - 1.0)
    edge_d = open_side * (half - CONE_INSET_M)  # cones by the shared edge: lateral offset from the centre (left +)
    for s in np.arange(start_m, min(start_m + TAPER_M, end) + 1e-9, cone_spacing_m):  # the taper
        t = (s - start_m) / TAPER_M
        rows.append((SemanticClass.TRAFFIC_CONE, float(s), float(-edge_d + 2 * t * edge_d), CONE_LWH_M, 0.0))
    first_barrier = start_m + TAPER_M + CLEAR_M
    barrier_d = -open_side * 0.1  # across the lane, clear of the shared edge's cones
    if first_barrier < end:
        rows.append((SemanticClass.BARRIER, first_barrier, barrier_d, BARRIER_LWH_M, np.pi / 2))
    for s in np.arange(first_barrier + CLEAR_M, end - CLEAR_M + 1e-9, cone_spacing_m):  # along the shared edge
        rows.append((SemanticClass.TRAFFIC_CONE, float(s), edge_d, CONE_LWH_M, 0.0))
    if end - first_barrier > 2 * CLEAR_M:
        rows.append((SemanticClass.BARRIER, end, barrier_d, BARRIER_LWH_M, np.pi / 2))
    work_l, work_w = WORK_VEHICLE_LWH_M[:2]
    cone_inner = half - CONE_INSET_M - CONE_LWH_M[1] / 2  # the shared edge's cones' inner side
    d = cone_inner - GAP_M - work_w / 2  # the vehicle's centre: its side GAP_M from the cones
    if vehicle and end - first_barrier >= work_l + 4 * CLEAR_M and d - work_w / 2 >= -half:
        d *= open_side
        rows.append((SemanticClass.CONSTRUCTION_VEHICLE, (first_barrier + end) / 2, d, WORK_VEHICLE_LWH_M, 0.0))
    return _placed(shape, rows)


def _placed(
    shape: npt.NDArray[np.float64], rows: list[tuple[SemanticClass, float, float, tuple[float, float, float], float]]
) -> ZoneLayout:
    n = len(rows)
    cls, center, lwh, yaw = np.zeros(n, np.uint8), np.zeros((n, 3)), np.zeros((n, 3)), np.zeros(n)
    for i, (c, s, d, size, turn) in enumerate(rows):
        point, heading = point_and_heading(shape, s)
        left = np.array([-heading[1], heading[0]])
        center[i, :2] = point[:2] + d * left
        center[i, 2] = point[2] + size[2] / 2.0
        cls[i], lwh[i], yaw[i] = int(c), size, np.arctan2(heading[1], heading[0]) + turn
    return ZoneLayout(cls, center, lwh, yaw)
