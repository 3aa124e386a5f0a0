"""Street parking from the network: SUMO parking areas whose spaces lie on parking lanes.

A parking lane (OpenDRIVE lane type ``parking``) is not driven on; each one gets a
parking area on the driving lane beside it, with explicit spaces along the parking
lane's centre line, so parked vehicles stand on the parking lane, beside the traffic.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import sumolib
from shapely.geometry import LineString

from networks.markings import PARKING_END_M, PARKING_SPACE_M, parking_space_centres

SPACE_LENGTH_M = PARKING_SPACE_M  # the spaces the world's markings paint
END_CLEARANCE_M = PARKING_END_M


@dataclass(frozen=True, slots=True)
class ParkingArea:
    area_id: str
    lane_id: str  # the driving lane the area belongs to
    start_m: float
    end_m: float
    spaces: tuple[tuple[float, float, float, float], ...]  # x, y, z (map), SUMO angle (deg)


def _space_points(shape: list[tuple[float, ...]]) -> list[tuple[float, float, float, float]]:
    line = LineString([(p[0], p[1]) for p in shape])
    z0 = shape[0][2] if len(shape[0]) > 2 else 0.0
    spaces = []
    for s in parking_space_centres(line.length):  # the spaces the world's markings paint
        p, q = line.interpolate(s - 0.5), line.interpolate(s + 0.5)
        c = line.interpolate(s)
        angle = math.degrees(math.atan2(q.x - p.x, q.y - p.y)) % 360.0  # clockwise from north
        spaces.append((c.x, c.y, z0, angle))
    return spaces


def find_parking_areas(net: sumolib.net.Net, types: dict[str, str]) -> list[ParkingArea]:
    areas = []
    for edge in sorted(net.getEdges(withInternal=False), key=lambda e: e.getID()):
        lanes = edge.getLanes()
        for lane in lanes:
            if types.get(lane.getID()) != "parking" or lane.getIndex() + 1 >= len(lanes):
                continue
            driving = lanes[lane.getIndex() + 1]
            if not driving.allows("passenger"):
                continue
            spaces = _space_points(lane.getShape3D())
            if not spaces:
                continue
            end = driving.getLength() - END_CLEARANCE_M
            areas.append(
                ParkingArea(f"pa_{lane.getID()}", driving.getID(), min(END_CLEARANCE_M, end), end, tuple(spaces))
            )
    return areas


def additional_xml(areas: list[ParkingArea]) -> str:
    rows = ["<additional>"]
    for a in areas:
        rows.append(
            f'  <parkingArea id="{a.area_id}" lane="{a.lane_id}" startPos="{a.start_m:.2f}" endPos="{a.end_m:.2f}">'
        )
        rows += [
            f'    <space x="{x:.2f}" y="{y:.2f}" z="{z:.2f}" angle="{ang:.2f}" width="2.2" length="{SPACE_LENGTH_M}"/>'
            for x, y, z, ang in a.spaces
        ]
        rows.append("  </parkingArea>")
    rows.append("</additional>")
    return "\n".join(rows) + "\n"
