"""The camera's optics: lens distortion (OpenCV's plumb_bob: rays, projection, field of view,
refusal of lenses that fold the image, labels that stay on the distorted image) and motion
blur over the shutter's time."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import cv2
import numpy as np
import pytest

from gtgen.objects import ObjectBoxes
from gtgen.projection import camera_boxes
from networks.classes import SemanticClass

if TYPE_CHECKING:
    from sensors.photo import AgentBoxes
from networks.geometry import SE3
from networks.mesh import box_mesh, merge
from sensors.agents import Agents
from sensors.camera import Camera, CameraSpec
from sensors.errors import SensorConfigError
from sensors.photo import BLACK_PERCENTILE, BLACK_TOE
from sensors.pinhole import Pinhole
from sensors.scene import FrameScene
from sensors.weather import DAY

from .conftest import EGO
from .reference_forms import auto_levels

KITTI_RAW_LENS = (-0.3691481, 0.1968681, 0.001353473, 0.0005677587, -0.06770705)
"""KITTI raw's camera 2 (2011_09_26 calibration): 1392x512 px, fx 959.8."""
KITTI_HFOV_DEG = math.degrees(2.0 * math.atan(696.0 / 959.8))


def test_rays_and_projection_are_opencvs_and_each_others_inverse() -> None:
    pinhole = Pinhole(1392, 512, KITTI_HFOV_DEG, KITTI_RAW_LENS)
    rng = np.random.default_rng(3)
    uv = np.stack([rng.uniform(0, 1391, 2000), rng.uniform(0, 511, 2000)], axis=1)
    rays = pinhole.pixel_directions(uv[:, 0], uv[:, 1])
    assert np.abs(pinhole.project(rays) - uv).max() < 1e-6
    opencv, _ = cv2.projectPoints(
        rays.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), pinhole.K, np.asarray(KITTI_RAW_LENS)
    )
    assert np.abs(opencv.reshape(-1, 2) - uv).max() < 1e-6


def test_barrel_distortion_widens_the_view_and_culling_follows_it() -> None:
    bent = Pinhole(1392, 512, KITTI_HFOV_DEG, KITTI_RAW_LENS)
    hfov, vfov = bent.view_fov_deg
    assert hfov > KITTI_HFOV_DEG + 10 and vfov > bent.vfov_deg
    assert Pinhole(1392, 512, KITTI_HFOV_DEG).view_fov_deg == (KITTI_HFOV_DEG, bent.vfov_deg)


@pytest.mark.parametrize("lens", [(0.0, -2.0, 0.0, 0.0, 0.0), (-0.3, 0.1, 0.0, 0.0, -0.02), (math.nan, 0, 0, 0, 0)])
def test_a_lens_that_folds_the_image_is_refused_in_one_line(lens: tuple[float, ...]) -> None:
    with pytest.raises(SensorConfigError, match=r"camera front: distortion .* cannot be used") as err:
        CameraSpec(name="front", distortion=lens)  # type: ignore[arg-type]
    assert "\n" not in str(err.value)


def test_labels_2d_box_is_the_silhouette_of_a_box_seen_through_the_lens() -> None:
    """A box near the image's corner, where the lens bends most: the pixels the camera renders
    of it fill exactly the 2D box the labels project (to the pixel), which a pinhole's
    projection misses by pixels."""
    spec = CameraSpec(width_px=640, height_px=360, hfov_deg=70.0, distortion=(-0.35, 0.15, 0.0, 0.0, -0.03))
    camera = Camera(spec)
    assert spec.pinhole.check_lens() is None
    centre, lwh = np.array([9.0, 4.2, 2.6]), (1.5, 1.5, 1.5)
    mesh = box_mesh(lwh, SemanticClass.BUILDING)
    mesh = type(mesh)(mesh.vertices_m + centre, mesh.triangles, mesh.triangle_class)
    frame = camera.sense(FrameScene(mesh, Agents.empty()), EGO, DAY, np.random.default_rng(0)).frame
    vv, uu = np.nonzero(frame.semantic_class == SemanticClass.BUILDING)
    assert vv.size > 500 and uu.min() < spec.width_px * 0.25  # near the top-left corner
    boxes = ObjectBoxes(np.array([1]), np.array([int(SemanticClass.BUILDING)]), centre[None, :], np.array([lwh]),
                        np.zeros(1), np.zeros(1), np.zeros(1), np.zeros((1, 3)), np.zeros(1, bool))  # fmt: skip
    ego_SE3_map = EGO.map_SE3_ego().inverse()
    assert np.allclose(ego_SE3_map.as_matrix(), np.eye(4))
    left, top, right, bottom = camera_boxes(spec.pinhole, spec.ego_SE3_sensor, boxes).amodal_px[0]
    # a pixel is rendered where its centre ray meets the box: the extreme pixel centres lie
    # within one pixel inside the projected box's edges
    assert left - 0.01 <= uu.min() <= left + 1.0 and right - 1.0 <= uu.max() <= right + 0.01
    assert top - 0.01 <= vv.min() <= top + 1.0 and bottom - 1.0 <= vv.max() <= bottom + 0.01
    pinhole = Pinhole(640, 360, 70.0)  # the same box through a pinhole lands elsewhere
    straight = camera_boxes(pinhole, spec.ego_SE3_sensor, boxes).amodal_px[0]
    assert abs(straight[0] - left) > 5.0 and abs(straight[1] - top) > 5.0


def test_the_mcap_calibration_carries_the_lens() -> None:
    from gtgen.sinks.foxglove import calibration
    from sensors.camera import CameraOutput

    spec = CameraSpec(width_px=64, height_px=36, distortion=(-0.1, 0.01, 0.0, 0.0, 0.0))
    frame = Camera(spec).sense(FrameScene(box_mesh((1, 1, 1), SemanticClass.BUILDING), Agents.empty()), EGO, DAY,
                               np.random.default_rng(0)).frame  # fmt: skip
    message = calibration(0, CameraOutput(spec, frame))
    assert message.distortion_model == "plumb_bob" and list(message.D) == [-0.1, 0.01, 0.0, 0.0, 0.0]


def _crossing(shutter_s: float, ego_mps: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Image and class mask of a car crossing 12 m ahead at 10 m/s in front of a wall."""
    from .conftest import agents, ground, wall_at_x

    spec = CameraSpec(width_px=320, height_px=180, shutter_s=shutter_s)
    car = agents([(1, SemanticClass.CAR, 12.0, 0.0, 0.75, 4.5, 1.8, 1.5, math.pi / 2)], [[0.0, 10.0, 0.0]])
    ego = type(EGO)(EGO.center_map_m, EGO.lwh_m, 0.0, 0.0, np.array([ego_mps, 0.0, 0.0]))
    scene = FrameScene(merge([ground(), wall_at_x(30.0)]), car)
    frame = Camera(spec).sense(scene, ego, DAY, np.random.default_rng(0)).frame
    from sensors.shading import shade_frame

    return shade_frame(frame).astype(np.float32), frame.instance_id


def test_a_crossing_car_blurs_along_its_motion_and_the_still_world_stays_sharp() -> None:
    sharp, instance = _crossing(0.0)
    blurred, same = _crossing(0.02)  # 10 m/s over 20 ms at 12 m: about 4 px at this focal length
    assert np.array_equal(instance, same)  # labels and masks are the frame's instant, unblurred
    car = instance == 1
    far = ~cv2.dilate(car.astype(np.uint8), np.ones((15, 15), np.uint8)).astype(bool)
    assert np.abs(blurred - sharp)[far].max() <= 1.0  # the wall and road do not move: as sharp as before

    def energy(image: np.ndarray, axis: int) -> float:
        grey = image.mean(axis=2)
        step = np.abs(np.diff(grey, axis=axis))[:-1, :] if axis == 1 else np.abs(np.diff(grey, axis=axis))[:, :-1]
        return float(step[car[:-1, :-1]].mean())

    # across the motion (along image rows) the car loses its detail; up and down far less
    across, along = energy(blurred, 1) / energy(sharp, 1), energy(blurred, 0) / energy(sharp, 0)
    assert across < 0.8 and along > 0.9
    assert across < along - 0.15


def test_the_egos_own_motion_blurs_the_still_world() -> None:
    sharp, _ = _crossing(0.0, ego_mps=0.0)
    blurred, _ = _crossing(0.03, ego_mps=20.0)
    assert np.abs(blurred - sharp).mean() > 1.0


@pytest.mark.parametrize(
    ("options", "message"),
    [
        ({"shutter_s": 0.08}, r"shutter_s must be 0\.\.0\.05 s \(at most one frame at rate_hz 20\), got 0\.08"),
        ({"shutter_s": -0.01}, r"shutter_s must be 0\.\.0\.05"),
        ({"shutter_s": 0.01, "shading": "flat"}, r"shutter_s \(motion blur\) needs shading: realistic"),
    ],
)
def test_a_shutter_longer_than_a_frame_or_on_the_flat_camera_is_refused(options: dict, message: str) -> None:
    with pytest.raises(SensorConfigError, match=r"camera front: " + message):
        CameraSpec(name="front", **options)


_ = SE3


def test_auto_contrast_sets_the_frames_black_level_and_keeps_its_order() -> None:
    # a veiled frame: its darkest grey is 60 of 255 (ambient and sky light over everything)
    rng = np.random.default_rng(3)
    grey = rng.uniform(60.0, 250.0, 10_000).astype(np.float32)
    image = np.repeat(grey[:, None], 3, axis=1)
    image[:, 2] += 6.0  # a little red
    out = auto_levels(image.copy(), 1.3)
    out_grey = out.mean(axis=1)
    # the darkest 2 % at the camera's black level, the darker still in order below it, none flattened
    assert np.percentile(out_grey, BLACK_PERCENTILE) == pytest.approx(BLACK_TOE, abs=2.0)
    below = np.sort(out_grey)[: len(grey) * 2 // 100 - 2]
    assert below.min() > 0.0 and len(np.unique(below)) > 0.9 * len(below)
    assert np.all(np.diff(out_grey[np.argsort(grey)]) >= -1e-3)  # darker stays darker
    assert np.all(out_grey <= image.mean(axis=1) + 1e-3)  # it never brightens
    red_before = image[:, 2] - image.mean(axis=1)
    # colours 1.3 times further from grey, not stretched with it: a veiled rain frame's black
    # level (60 here) would otherwise push its colours 1.3 x 1.31 from grey
    np.testing.assert_allclose(out[:, 2] - out_grey, 1.3 * red_before, atol=1e-3)
    # a frame whose darkest pixels are black already keeps its greys
    dark = np.repeat(np.concatenate([np.zeros(100), np.linspace(0.0, 255.0, 900)]).astype(np.float32)[:, None], 3, 1)
    np.testing.assert_allclose(auto_levels(dark.copy(), 1.0), dark, atol=1e-3)


def test_contact_shadow_pairs_are_the_points_within_each_boxs_reach() -> None:
    # the gridded search against every ground hit and box tested directly
    from sensors.shade_kernels import contact_pairs

    rng = np.random.default_rng(12)
    n = 20_000
    dirs = rng.uniform(-0.6, 0.6, (n, 3)).astype(np.float32)
    range_m = rng.uniform(1.0, 100.0, n).astype(np.float32)
    range_m[::97] = np.inf  # misses
    origin = np.array([3.5, -2.25, 1.7], np.float32)
    cls = rng.integers(0, 4, n).astype(np.uint8)
    instance = np.where(rng.random(n) < 0.1, rng.integers(1, 50, n), 0).astype(np.uint32)
    is_ground = np.zeros(256, np.bool_)
    is_ground[[1, 2]] = True
    cx, cy = rng.uniform(-70, 70, 25), rng.uniform(-70, 70, 25)
    reach = rng.uniform(0.5, 9.0, 25)
    yaw = rng.uniform(-np.pi, np.pi, 25)
    cs, sn = np.cos(yaw).astype(np.float32), np.sin(yaw).astype(np.float32)
    pt, box, ax, ay = contact_pairs(dirs, range_m, cls, instance, is_ground, origin, cx, cy, reach, cs, sn)
    p = origin + dirs * range_m[:, None]
    gx, gy = p[:, 0], p[:, 1]
    ground = np.isfinite(range_m) & is_ground[cls] & (instance == 0)
    want = {
        (i, k)
        for k in range(25)
        for i in np.flatnonzero(ground & (np.abs(gx - cx[k]) < reach[k]) & (np.abs(gy - cy[k]) < reach[k]))
    }
    assert set(zip(pt.tolist(), box.tolist(), strict=True)) == want and len(pt) == len(want) > 100
    dx, dy = gx[pt] - cx[box].astype(np.float32), gy[pt] - cy[box].astype(np.float32)
    np.testing.assert_array_equal(ax, np.abs(cs[box] * dx + sn[box] * dy))
    np.testing.assert_array_equal(ay, np.abs(-sn[box] * dx + cs[box] * dy))


def _placed(local: np.ndarray, centre: np.ndarray, yaw: float) -> np.ndarray:
    """Points in a box's own frame (x along, y left, z up from its centre) placed in the map frame
    for the box at ``centre`` heading ``yaw``."""
    c, s = math.cos(yaw), math.sin(yaw)
    turn = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    return (local @ turn.T + centre).astype(np.float32)


def _one_box(
    instance: int, centre: tuple[float, float, float], lwh: tuple[float, float, float], yaw: float
) -> AgentBoxes:
    """The camera's boxes of one standing agent with no lamps lit."""
    from sensors.photo import AgentBoxes

    return AgentBoxes(
        np.array([instance], np.uint32), np.array([centre]), np.array([lwh]), np.array([yaw]),
        np.zeros(1, np.uint8), np.zeros((1, 3)),
    )  # fmt: skip


def _plate_points(centre: np.ndarray, yaw: float) -> np.ndarray:
    """Points over a rear number plate (520 x 110 mm, 0.5 m up) of a 4.5 x 1.8 x 1.5 m car
    standing at ``centre`` (box centre, map frame) heading ``yaw``."""
    across, up = np.meshgrid(np.linspace(-0.26, 0.26, 105), np.linspace(0.45, 0.56, 23))
    local = np.stack([np.full(across.size, -2.25), across.ravel(), up.ravel() - 0.75], axis=1)
    return _placed(local, centre, yaw)


def test_number_plates_keep_their_characters_as_their_vehicle_moves_and_differ_between_vehicles():
    from sensors.photo import plate_ink

    def ink(instance: int, centre: tuple[float, float, float], yaw: float) -> np.ndarray:
        boxes = _one_box(instance, centre, (4.5, 1.8, 1.5), yaw)
        points = _plate_points(np.array(centre), yaw)
        return plate_ink(points, np.full(len(points), instance, np.uint32), boxes)

    here = ink(7, (10.0, 5.0, 0.75), 0.3)
    assert 0.15 < here.mean() < 0.6  # characters, not a blank or a black plate
    for centre, yaw in [((25.0, 9.5, 0.75), 0.3), ((-40.0, 12.0, 0.9), 2.1), ((310.0, -77.0, 0.75), -1.2)]:
        moved = ink(7, centre, yaw)
        assert (moved != here).mean() < 0.01, (centre, yaw)  # the same characters wherever it drives
    assert (ink(8, (10.0, 5.0, 0.75), 0.3) != here).mean() > 0.2  # another vehicle, other characters
    columns = here.reshape(23, 105).any(axis=0)
    assert not columns.all()  # spaces between the characters


def _bus_window_points(centre: np.ndarray, yaw: float) -> np.ndarray:
    """Points over the left side windows (1.05-2.65 m up) of a 12 x 2.55 x 3.1 m bus standing at
    ``centre`` (box centre, map frame) heading ``yaw``."""
    along, up = np.meshgrid(np.linspace(-5.4, 5.2, 400), np.linspace(1.05, 2.65, 60))
    local = np.stack([along.ravel(), np.full(along.size, 1.27), up.ravel() - 1.55], axis=1)
    return _placed(local, centre, yaw)


def test_a_lit_bus_shows_seat_backs_and_passengers_that_ride_with_it():
    from sensors.photo import bus_cabin

    def cabin(instance: int, centre: tuple[float, float, float], yaw: float) -> np.ndarray:
        boxes = _one_box(instance, centre, (12.0, 2.55, 3.1), yaw)
        points = _bus_window_points(np.array(centre), yaw)
        return bus_cabin(points, np.full(len(points), instance, np.uint32), boxes).reshape(60, 400)

    here = cabin(5, (20.0, -3.0, 1.55), 0.4)
    low, high = here[:8], here[-15:]  # at the seat backs, under the ceiling
    assert low.mean() < 0.6 < high.mean()  # darker seat rows below the glow
    dark = here < 0.15
    assert 0.03 < dark.mean() < 0.3  # passengers' silhouettes, not an empty or a blacked-out bus
    assert dark[20:50].any(axis=0).mean() > 0.1  # heads and bodies above the seat backs
    for centre, yaw in [((-60.0, 14.0, 1.55), 2.5), ((5.0, 80.0, 1.7), -1.0)]:
        moved = cabin(5, centre, yaw)
        assert (np.abs(moved - here) > 0.01).mean() < 0.01, (centre, yaw)  # the same people in their seats
    other = cabin(6, (20.0, -3.0, 1.55), 0.4)
    assert ((other < 0.15) != dark).mean() > 0.02  # another bus, other passengers


def test_heavy_vehicles_marker_lamps_glow_at_night_while_their_lights_are_on():
    from dataclasses import replace

    from sensors.agents import Lamp
    from sensors.parts import Part
    from sensors.photo import LAMP_BGR, lamp_light

    markers = np.array([Part.SIDE_MARKER, Part.FRONT_OUTLINE, Part.REAR_OUTLINE], np.uint8)
    points = np.array([[0.0, 1.27, -1.0], [6.0, 1.1, 1.5], [-6.0, 1.1, 1.3]], np.float32)  # a 12 m bus at the origin
    instance = np.full(3, 5, np.uint32)
    off = _one_box(5, (0.0, 0.0, 0.0), (12.0, 2.55, 3.1), 0.0)
    on = replace(off, lamps=np.array([Lamp.LIGHTS], np.uint8))
    assert (lamp_light(points, instance, markers, on, 1.0) > 0.5).all()
    assert not lamp_light(points, instance, markers, off, 1.0).any()  # parked, lights off
    assert not lamp_light(points, instance, markers, on, 0.0).any()  # by day they do not show
    side, front, rear = LAMP_BGR[markers]
    assert side[2] > side[1] > side[0] and rear[2] > 10 * rear[1] and front.min() > 0.8  # amber, red, white
