"""Trucks with trailers: one SUMO vehicle drawn and labelled as two objects, the truck and its
trailer, the trailer following the truck's hitch with its own yaw (pure functions).

SUMO moves a truck with a trailer as one rigid vehicle of the combination's length. Here the
truck's box is its first ``TRUCK_SHARE`` of that length, from the front bumper; the trailer is
a centre-axle trailer whose rigid drawbar hangs on a hitch ``HITCH_BEHIND_M`` behind the
truck's box, its box starting ``DRAWBAR_M`` behind the hitch. Its yaw follows the hitch
kinematics of a trailer without side slip: the trailer's axle (the middle of its box) is pulled
along the line to the hitch, so each step it moves to the point ``axle_to_hitch`` from the new
hitch position on the line through its last position (the tractrix of the hitch's path:
trailers cut corners, as real ones do). A trailer first read at a step starts in line with its
truck. The articulation angle is limited to ``MAX_ARTICULATION_RAD``, which keeps the two boxes
apart (every LiDAR return then lies in exactly one box). The drawbar itself is not drawn.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from networks.geometry import wrap_angle

TRUCK_SHARE = 0.48
HITCH_BEHIND_M = 0.3
DRAWBAR_M = 1.3
MAX_ARTICULATION_RAD = np.radians(45.0)  # the boxes stay 0.3 m apart or more up to it


@dataclass(frozen=True, slots=True)
class Combination:
    """Lengths of a truck with a trailer of SUMO length ``length_m``."""

    truck_m: float
    trailer_m: float

    @classmethod
    def of(cls, length_m: float) -> Combination:
        truck = round(TRUCK_SHARE * length_m, 3)
        return cls(truck, round(length_m - truck - HITCH_BEHIND_M - DRAWBAR_M, 3))

    @property
    def axle_to_hitch_m(self) -> float:
        return DRAWBAR_M + self.trailer_m / 2.0


def hitch_point(
    front_xy_m: npt.NDArray[np.float64], yaw_rad: float, combination: Combination
) -> npt.NDArray[np.float64]:
    """``(2,)`` the hitch in the map plane: behind the truck's box on its axis."""
    back = combination.truck_m + HITCH_BEHIND_M
    return np.asarray(front_xy_m, np.float64)[:2] - back * np.array([np.cos(yaw_rad), np.sin(yaw_rad)])


def pulled_axle(
    axle_xy_m: npt.NDArray[np.float64] | None,
    hitch_xy_m: npt.NDArray[np.float64],
    truck_yaw_rad: float,
    combination: Combination,
) -> npt.NDArray[np.float64]:
    """``(2,)`` the trailer's axle after the hitch moved to ``hitch_xy_m`` (``None``: the
    trailer starts in line with the truck), the articulation limited."""
    reach = combination.axle_to_hitch_m
    if axle_xy_m is None:
        yaw = truck_yaw_rad
    else:
        to_axle = np.asarray(axle_xy_m, np.float64) - hitch_xy_m
        yaw = float(np.arctan2(-to_axle[1], -to_axle[0])) if np.linalg.norm(to_axle) > 1e-9 else truck_yaw_rad
        bend = float(wrap_angle(yaw - truck_yaw_rad))
        yaw = truck_yaw_rad + float(np.clip(bend, -MAX_ARTICULATION_RAD, MAX_ARTICULATION_RAD))
    return hitch_xy_m - reach * np.array([np.cos(yaw), np.sin(yaw)])


def trailer_box_center(
    hitch_xy_m: npt.NDArray[np.float64], axle_xy_m: npt.NDArray[np.float64], combination: Combination
) -> tuple[npt.NDArray[np.float64], float]:
    """The trailer box's centre in the plane ``(2,)`` and its yaw (the axle lies under it)."""
    along = hitch_xy_m - axle_xy_m
    return np.asarray(axle_xy_m, np.float64), float(np.arctan2(along[1], along[0]))
