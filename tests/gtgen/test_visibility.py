"""Labels from rays on hand-built scenes with known answers."""

import numpy as np
import pytest
from shapely.geometry import box as rect

from gtgen.counting import count_hits, mask_counts_and_boxes
from gtgen.labels import label_frame
from gtgen.visibility import modal_boxes, occlusion_level, visibility_bin
from networks.classes import SemanticClass
from networks.geometry import SE3
from networks.mesh import flat_polygon, merge, prism
from sensors.agents import Agents, EgoState
from sensors.camera import Camera, CameraSpec
from sensors.lidar import Lidar, LidarSpec
from sensors.radar import Radar, RadarSpec
from sensors.scene import FrameScene
from sensors.weather import DAY

EGO = EgoState.at(SE3.identity())  # the ego stands at the map origin, facing +x
GROUND = flat_polygon(rect(-200, -200, 200, 200), 0.0, SemanticClass.ROAD)


def agents(rows):
    """rows: (id, class, x, y, l, w, h, yaw) with the box standing on the ground."""
    a = np.asarray(rows, dtype=np.float64).reshape(-1, 8)
    center = np.column_stack([a[:, 2], a[:, 3], a[:, 6] / 2])
    return Agents.standing(a[:, 0].astype(int), a[:, 1].astype(int), center, a[:, 4:7], a[:, 7])


def label(static, a, camera_spec=None, lidar=True, radar=True):
    scene = FrameScene(static, a)
    rng = np.random.default_rng(0)
    sensors = [Camera(camera_spec or CameraSpec())]
    sensors += [Lidar(LidarSpec())] if lidar else []
    sensors += [Radar(RadarSpec())] if radar else []
    outputs = tuple(sensor.sense(scene, EGO, DAY, rng) for sensor in sensors)
    return label_frame(0, 0, a, EGO, outputs, scene, 120.0), outputs[0].frame


def test_pedestrian_half_hidden_behind_a_wall_is_half_visible():
    # The wall's edge lies in the vertical plane through the camera and the pedestrian's
    # axis of symmetry, so exactly the pedestrian's left half is hidden.
    wall = prism(rect(3.0, 0.0, 3.2, 5.0), 0.0, 4.0, SemanticClass.BUILDING)
    ped = agents([(7, SemanticClass.PEDESTRIAN, 6.41, 0.0, 0.4, 0.6, 1.8, 0.0)])
    labels, _ = label(merge([GROUND, wall]), ped, lidar=False, radar=False)
    cam = labels.cameras[0]
    assert cam.visibility.fraction[0] == pytest.approx(0.5, abs=0.05)
    assert cam.visibility.occluded[0] == 1


def test_pedestrian_partly_behind_a_car_is_partly_occluded():
    scene_agents = agents(
        [
            (1, SemanticClass.CAR, 5.0, 0.6, 4.5, 1.9, 1.5, np.pi / 2),
            (2, SemanticClass.PEDESTRIAN, 9.0, 0.0, 0.4, 0.6, 1.8, 0.0),
        ]
    )
    labels, frame = label(GROUND, scene_agents, lidar=False, radar=False)
    ped = int(np.flatnonzero(labels.objects.track_id == 2)[0])
    vis = labels.cameras[0].visibility
    assert 0.0 < vis.fraction[ped] < 0.8 and vis.occluded[ped] in (1, 2)
    assert vis.visible_px[ped] == int(np.sum(frame.instance_id == 2))


def test_parked_car_behind_a_building_gets_no_rays_and_is_not_seen():
    building = prism(rect(15.0, -10.0, 25.0, 10.0), 0.0, 12.0, SemanticClass.BUILDING)
    a = agents(
        [(5, SemanticClass.CAR, 30.0, 0.0, 4.5, 1.9, 1.5, 0.0), (6, SemanticClass.CAR, 10.0, -4.0, 4.5, 1.9, 1.5, 0.0)]
    )
    labels, _ = label(merge([GROUND, building]), a)
    hidden = int(np.flatnonzero(labels.objects.track_id == 5)[0])
    visible = int(np.flatnonzero(labels.objects.track_id == 6)[0])
    assert labels.lidar_points[hidden] == 0 and labels.radar_points[hidden] == 0
    assert labels.cameras[0].visibility.visible_px[hidden] == 0
    assert not labels.seen[hidden] and labels.cameras[0].visibility.occluded[hidden] == 3
    assert labels.seen[visible] and labels.lidar_points[visible] > 0


def test_object_behind_the_camera_is_truncated_and_not_visible_in_it():
    labels, _ = label(GROUND, agents([(3, SemanticClass.CAR, -12.0, 0.0, 4.5, 1.9, 1.5, 0.0)]), radar=False)
    cam = labels.cameras[0]
    assert cam.boxes.truncated[0] == 1.0 and cam.visibility.occluded[0] == 3
    assert labels.lidar_points[0] > 0 and labels.seen[0]


def test_modal_box_is_tight_around_the_mask():
    mask = np.zeros((10, 20), np.uint32)
    mask[2:5, 3:9] = 4
    mask[7, 15] = 9
    boxes = modal_boxes(mask, np.array([4, 9, 11], np.uint32))
    assert boxes[0].tolist() == [3, 2, 8, 4] and boxes[1].tolist() == [15, 7, 15, 7]
    assert np.all(np.isnan(boxes[2]))


def test_mask_counts_and_boxes_in_one_pass_equal_count_hits_and_modal_boxes():
    rng = np.random.default_rng(7)
    ids_pool = np.array([0, 1, 3, 7, 9, 11, 2**32 - 1], np.uint32)
    for trial in range(300):
        h, w = (int(n) for n in rng.integers(0, 24, 2))
        mask = rng.choice(ids_pool[[0, 2, 3, 4, 6]], size=(h, w))
        if trial % 3 == 0:
            mask = np.repeat(mask, 3, axis=1)  # runs along rows
        track_ids = rng.choice(ids_pool, size=int(rng.integers(0, 7)))  # 0, repeats, absent ids
        counts, boxes = mask_counts_and_boxes(mask, track_ids)
        assert counts.dtype == np.int32 and boxes.dtype == np.float64
        np.testing.assert_array_equal(counts, count_hits(mask.ravel(), track_ids))
        np.testing.assert_array_equal(boxes, modal_boxes(mask, track_ids))


def test_occlusion_levels_and_visibility_bins_follow_their_thresholds():
    f = np.array([1.0, 0.8, 0.79, 0.6, 0.4, 0.39, 0.01, 0.0])
    assert occlusion_level(f).tolist() == [0, 0, 1, 1, 1, 2, 2, 3]
    assert visibility_bin(f).tolist() == [4, 4, 3, 3, 2, 1, 1, 1]
