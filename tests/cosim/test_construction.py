"""Construction zones and trucks with trailers as pure geometry (no SUMO): the zone's objects
stand apart inside the closed lane, and a trailer follows its truck's hitch with its own yaw."""

import numpy as np
import pytest
from shapely.geometry import LineString, Polygon

from cosim.construction import zone_layout
from cosim.trailers import MAX_ARTICULATION_RAD, Combination, hitch_point, pulled_axle, trailer_box_center
from networks.classes import SemanticClass


def footprint(center: np.ndarray, lwh: np.ndarray, yaw: float) -> Polygon:
    c, s = np.cos(yaw), np.sin(yaw)
    half = np.array([[1, 1], [1, -1], [-1, -1], [-1, 1]]) * lwh[:2] / 2
    return Polygon(center[:2] + half @ np.array([[c, s], [-s, c]]))


def curved_lane(radius_m: float = 80.0, length_m: float = 140.0) -> np.ndarray:
    a = np.linspace(0.0, length_m / radius_m, 60)
    return np.column_stack([radius_m * np.sin(a), radius_m * (1 - np.cos(a)), 0.5 + 0.01 * a])


@pytest.mark.parametrize("open_side", [1, -1])
def test_a_zone_closes_its_lane_with_objects_that_stand_apart_inside_it(open_side):
    lane = curved_lane()
    layout = zone_layout(lane, 3.3, open_side, 8.0, 60.0, 4.0, vehicle=True)
    counts = {c: int(np.sum(layout.semantic_class == int(c))) for c in SemanticClass}
    assert counts[SemanticClass.BARRIER] == 2 and counts[SemanticClass.CONSTRUCTION_VEHICLE] == 1
    assert counts[SemanticClass.TRAFFIC_CONE] >= 18
    boxes = [footprint(c, s, y) for c, s, y in zip(layout.center_map_m, layout.lwh_m, layout.yaw_map_rad, strict=True)]
    for i in range(len(boxes)):
        for j in range(i + 1, len(boxes)):
            assert boxes[i].distance(boxes[j]) > 0.05, (i, j)
    # every object inside the closed lane (3.3 m wide), standing on its surface
    lane_area = LineString(lane[:, :2]).buffer(3.3 / 2, cap_style="flat")
    for box in boxes:
        assert lane_area.contains(box)
    ground = np.interp(layout.center_map_m[:, 0], lane[:, 0], lane[:, 2])
    np.testing.assert_allclose(layout.center_map_m[:, 2] - layout.lwh_m[:, 2] / 2, ground, atol=1e-3)


def test_the_taper_leads_from_the_far_edge_to_the_open_lane():
    lane = np.array([[0.0, 0.0, 0.0], [200.0, 0.0, 0.0]])
    layout = zone_layout(lane, 3.2, 1, 10.0, 50.0, 4.0, vehicle=False)
    cones = layout.center_map_m[layout.semantic_class == int(SemanticClass.TRAFFIC_CONE)]
    taper = cones[cones[:, 0] <= 26.0]
    assert taper[0, 1] < -1.0 and taper[-1, 1] > 1.0  # open lane on the left (+y)
    assert np.all(np.diff(taper[:, 1]) > 0)
    assert not np.any(layout.semantic_class == int(SemanticClass.CONSTRUCTION_VEHICLE))


def drive_circle(radius_m: float, combination: Combination, steps: int = 4000, step_m: float = 0.05):
    """A truck whose front bumper goes round a circle; yields truck yaw, hitch, axle per step."""
    axle = None
    for k in range(steps):
        a = k * step_m / radius_m
        front = np.array([radius_m * np.sin(a), radius_m * (1 - np.cos(a))])
        yaw = a  # tangent to the circle at the front (a truck as short as its wheelbase)
        hitch = hitch_point(front, yaw, combination)
        axle = pulled_axle(axle, hitch, yaw, combination)
        yield yaw, hitch, axle


def test_a_trailer_cuts_the_corner_at_the_articulation_of_its_hitch_kinematics():
    combo = Combination.of(17.0)
    assert combo.truck_m + combo.trailer_m < 17.0 and combo.trailer_m > 6.0
    last = list(drive_circle(30.0, combo))[-1]
    yaw, hitch, axle = last
    _, trailer_yaw = trailer_box_center(hitch, axle, combo)
    assert np.linalg.norm(hitch - axle) == pytest.approx(combo.axle_to_hitch_m)
    # steady state: the axle moves on a circle about the same centre, perpendicular to the drawbar
    hitch_radius = np.linalg.norm(hitch - np.array([0.0, 30.0]))
    axle_radius = np.linalg.norm(axle - np.array([0.0, 30.0]))
    assert axle_radius == pytest.approx(np.sqrt(hitch_radius**2 - combo.axle_to_hitch_m**2), abs=0.02)
    bend = np.angle(np.exp(1j * (yaw - trailer_yaw)))
    assert 0.2 < bend < MAX_ARTICULATION_RAD  # the trailer's yaw lags the truck's


def test_a_trailer_straightens_behind_a_straight_truck_and_its_box_stays_clear_of_the_trucks():
    combo = Combination.of(16.0)
    axle = hitch_point(np.zeros(2), 0.0, combo) + np.array([-2.0, 3.0])  # bent far out of line
    truck = footprint(np.array([-combo.truck_m / 2, 0.0]), np.array([combo.truck_m, 2.5]), 0.0)
    bends = []
    for k in range(600):
        front = np.array([0.1 * k, 0.0])
        hitch = hitch_point(front, 0.0, combo)
        axle = pulled_axle(axle, hitch, 0.0, combo)
        center, yaw = trailer_box_center(hitch, axle, combo)
        trailer = footprint(center, np.array([combo.trailer_m, 2.5]), yaw)
        truck_now = footprint(np.array([front[0] - combo.truck_m / 2, 0.0]), np.array([combo.truck_m, 2.5]), 0.0)
        assert truck_now.distance(trailer) > 0.25
        bends.append(abs(yaw))
    assert bends[0] == pytest.approx(MAX_ARTICULATION_RAD) and bends[-1] < 0.01
    assert truck.area > 0
