from __future__ import annotations

import math
from dataclasses import replace
from types import SimpleNamespace

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import sensors.photo as photo_module
import sensors.shading as shading_module
from networks.classes import SemanticClass
from networks.geometry import SE3
from sensors.camera import SHADOW_LIFT_M, Camera, CameraSpec, depth_to_uint16, encode_depth_png
from sensors.errors import SensorConfigError
from sensors.pinhole import box_corners, project_points
from sensors.shading import CameraFrame, shade_frame
from sensors.weather import DAY, weather_preset

SMALL = CameraSpec(width_px=160, height_px=90)


def pixel_grid(spec: CameraSpec) -> tuple[np.ndarray, np.ndarray]:
    v, u = np.mgrid[0 : spec.height_px, 0 : spec.width_px]
    return u.astype(np.float64), v.astype(np.float64)


def test_intrinsics_follow_fov_and_resolution() -> None:
    K = CameraSpec().pinhole.K
    f = 640.0 / math.tan(math.radians(42.5))
    np.testing.assert_allclose(K, [[f, 0, 639.5], [0, f, 359.5], [0, 0, 1]])


def test_the_optical_frame_looks_along_ego_x_with_y_down() -> None:
    cam_SE3_ego = CameraSpec().ego_SE3_sensor.inverse()
    ahead_left_up = np.array([[10.41, 0.0, 1.64], [10.41, 1.0, 1.64], [10.41, 0.0, 2.64]])
    np.testing.assert_allclose(
        cam_SE3_ego.transform_from(ahead_left_up), [[0, 0, 10], [-1, 0, 10], [0, -1, 10]], atol=1e-12
    )


def test_out_of_range_specs_are_rejected() -> None:
    with pytest.raises(SensorConfigError):
        CameraSpec(hfov_deg=0.0)
    with pytest.raises(SensorConfigError):
        CameraSpec(width_px=2)


@pytest.mark.parametrize("rpy_deg", [(0.0, 0.0, 0.0), (3.0, 10.0, -20.0)])
def test_depth_on_the_ground_plane_matches_the_analytic_depth(
    synth: SimpleNamespace, rpy_deg: tuple[float, float, float]
) -> None:
    spec = CameraSpec(width_px=160, height_px=90, mount_rpy_deg=rpy_deg)
    frame = Camera(spec).sense(synth.scene([synth.ground()]), synth.EGO, DAY, np.random.default_rng(0)).frame
    u, v = pixel_grid(spec)
    K = spec.pinhole.K
    d_cam = np.stack([(u - K[0, 2]) / K[0, 0], (v - K[1, 2]) / K[1, 1], np.ones_like(u)], axis=-1)
    down = (d_cam @ spec.ego_SE3_sensor.rotation.T)[..., 2]
    t = -spec.mount_xyz_m[2] / np.where(down < 0, down, -1e-12)
    expected = np.where((down < 0) & (t * np.linalg.norm(d_cam, axis=-1) <= spec.range_m), t, 0.0)
    seen = expected > 0
    assert 0.2 < seen.mean() < 0.8
    np.testing.assert_allclose(frame.depth_m[seen], expected[seen], rtol=2e-4)
    assert np.all(frame.depth_m[~seen] == 0)
    assert np.all(frame.semantic_class[seen] == SemanticClass.ROAD)
    assert np.all(frame.semantic_class[~seen] == SemanticClass.NONE)


def test_depth_on_a_wall_facing_the_camera_is_constant(synth: SimpleNamespace) -> None:
    frame = Camera(SMALL).sense(synth.scene([synth.wall_at_x(20.41)]), synth.EGO, DAY, np.random.default_rng(0)).frame
    np.testing.assert_allclose(frame.depth_m, 20.0, rtol=1e-5)


def test_depth_pixels_project_back_onto_their_own_pixel(synth: SimpleNamespace) -> None:
    spec = CameraSpec(width_px=160, height_px=90, mount_rpy_deg=(0.0, 8.0, 5.0))
    frame = Camera(spec).sense(synth.scene([synth.ground()]), synth.EGO, DAY, np.random.default_rng(0)).frame
    u, v = pixel_grid(spec)
    hit = frame.hit
    K_inv = np.linalg.inv(spec.pinhole.K)
    xyz_cam = (np.stack([u[hit], v[hit], np.ones(hit.sum())], axis=1) @ K_inv.T) * frame.depth_m[hit, None]
    xyz_map = spec.ego_SE3_sensor.transform_from(xyz_cam)
    uv = project_points(spec.pinhole.K, spec.ego_SE3_sensor.inverse(), xyz_map)
    np.testing.assert_allclose(uv, np.stack([u[hit], v[hit]], axis=1), atol=1e-3)


@settings(max_examples=50, deadline=None)
@given(
    rvec=st.tuples(*[st.floats(-2.0, 2.0)] * 3),
    xyz=st.tuples(*[st.floats(-50.0, 50.0)] * 3),
    seed=st.integers(0, 2**31),
)
def test_project_points_agrees_with_opencv(rvec: tuple[float, ...], xyz: tuple[float, ...], seed: int) -> None:
    """The rotation is built from OpenCV's own rotation vector: going the other way, its
    Rodrigues rounds rotations below about 1e-5 rad to none."""
    rotation, _ = cv2.Rodrigues(np.asarray(rvec, dtype=np.float64))
    cam_SE3_x = SE3(rotation, np.asarray(xyz))
    r = np.random.default_rng(seed)
    z = r.uniform(0.5, 80.0, 20)
    points_cam = np.column_stack([r.uniform(-1.2, 1.2, (20, 2)) * z[:, None], z])
    points_x = cam_SE3_x.inverse().transform_from(points_cam)
    K = CameraSpec().pinhole.K
    expected, _ = cv2.projectPoints(points_x, np.asarray(rvec), cam_SE3_x.translation, K, np.zeros(5))
    np.testing.assert_allclose(project_points(K, cam_SE3_x, points_x), expected.reshape(-1, 2), rtol=0, atol=1e-6)


def test_points_behind_the_camera_project_to_nan() -> None:
    uv = project_points(CameraSpec().pinhole.K, SE3.identity(), [[0.0, 0.0, -5.0], [0.0, 0.0, 5.0]])
    assert np.all(np.isnan(uv[0])) and np.all(np.isfinite(uv[1]))


def test_class_and_instance_per_pixel_on_a_synthetic_scene(synth: SimpleNamespace) -> None:
    boxes = synth.agents([(7, SemanticClass.CAR, 15.0, 0.0, 0.75, 4.5, 1.8, 1.5, 0.0),
                    (9, SemanticClass.PEDESTRIAN, 10.0, 3.0, 0.875, 0.3, 0.5, 1.75, 0.0)])  # fmt: skip
    frame = (
        Camera(SMALL)
        .sense(synth.scene([synth.ground(), synth.wall_at_x(40.0)], boxes), synth.EGO, DAY, np.random.default_rng(0))
        .frame
    )
    cam_SE3_map = SMALL.ego_SE3_sensor.inverse()
    corners = box_corners(boxes.center_map_m, boxes.lwh_m, boxes.rotations())
    for i, inst in enumerate(boxes.instance_id):
        corners_uv = project_points(SMALL.pinhole.K, cam_SE3_map, corners[i])
        lo, hi = np.floor(corners_uv.min(axis=0)), np.ceil(corners_uv.max(axis=0))
        vv, uu = np.nonzero(frame.instance_id == inst)
        assert vv.size > 10
        assert np.all((uu >= lo[0]) & (uu <= hi[0]) & (vv >= lo[1]) & (vv <= hi[1]))
        assert np.all(frame.semantic_class[vv, uu] == boxes.semantic_class[i])
        centre = project_points(SMALL.pinhole.K, cam_SE3_map, boxes.center_map_m[i : i + 1])[0]
        assert frame.instance_id[round(centre[1]), round(centre[0])] == inst
    assert frame.semantic_class[0, 0] == SemanticClass.BUILDING and frame.instance_id[0, 0] == 0
    assert frame.semantic_class[-1, 80] == SemanticClass.ROAD


def test_a_full_size_render_has_the_documented_shapes_and_types(synth: SimpleNamespace) -> None:
    boxes = synth.agents([(3, SemanticClass.BUS, 30.0, -3.0, 1.7, 12.0, 2.5, 3.4, 0.2)])
    frame = (
        Camera(CameraSpec())
        .sense(synth.scene([synth.ground(), synth.wall_at_x(120.0)], boxes), synth.EGO, DAY, np.random.default_rng(0))
        .frame
    )
    assert frame.depth_m.shape == (720, 1280) and frame.depth_m.dtype == np.float32
    assert frame.instance_id.dtype == np.uint32 and frame.semantic_class.dtype == np.uint8
    image = shade_frame(frame)
    assert image.shape == (720, 1280, 3) and image.dtype == np.uint8
    assert np.any(frame.instance_id == 3)
    assert image.std() > 5


def test_camera_frame_rejects_mismatched_arrays_naming_the_field(synth: SimpleNamespace) -> None:
    frame = Camera(SMALL).sense(synth.scene([synth.ground()]), synth.EGO, DAY, np.random.default_rng(0)).frame
    with pytest.raises(ValueError, match=r"CameraFrame\.instance_id: expected shape \(H=90, W=160\), got \(90, 161\)"):
        CameraFrame(frame.depth_m, np.zeros((90, 161), np.uint32), frame.semantic_class, frame.shading)
    with pytest.raises(ValueError, match=r"CameraFrame\.instance_id: expected dtype uint32, got float32"):
        CameraFrame(frame.depth_m, frame.depth_m, frame.semantic_class, frame.shading)


@pytest.mark.parametrize("far", ["crown", "agent"])
def test_sub_rays_with_nothing_within_range_are_misses_as_centre_rays_are(synth: SimpleNamespace, far: str) -> None:
    """An anti-aliasing sub-ray whose hit lies beyond the camera's range has range inf and class,
    instance and part 0, as a centre ray has: a crown or an agent met beyond it is not shaded
    (no NaN normal, no invalid arithmetic on an infinite point)."""
    import warnings

    spec = replace(SMALL, range_m=60.0)
    near = synth.quad([(10.0, 0.0, -20.0), (10.0, 20.0, -20.0), (10.0, 20.0, 20.0), (10.0, 0.0, 20.0)],
                      SemanticClass.BUILDING)  # fmt: skip  # the image's left half, 10 m ahead
    if far == "crown":
        scene = synth.scene([near, synth.wall_at_x(80.0, cls=SemanticClass.VEGETATION)])
    else:
        scene = synth.scene([near], synth.agents([(7, SemanticClass.BUS, 81.0, 0.0, 0.0, 2.0, 200.0, 200.0, 0.0)]))
    frame = Camera(spec).sense(scene, synth.EGO, DAY, np.random.default_rng(0)).frame
    extra = frame.shading.extra
    assert extra is not None
    beyond = ~np.isfinite(extra.range_m)
    assert beyond.sum() > 20 and (extra.semantic_class[~beyond] == SemanticClass.BUILDING).all()  # both sides seen
    assert not extra.semantic_class[beyond].any() and not extra.instance_id[beyond].any()
    assert not extra.part[beyond].any()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        image = shade_frame(frame)
    assert image.shape == (90, 160, 3)


@pytest.mark.parametrize("filter_up", [False, True])
def test_depth_png_holds_millimetres_and_zero_where_unknown(filter_up: bool) -> None:
    depth = np.array([[0.0, 1.2344, 65.535], [65.6, np.inf, 10.0]], dtype=np.float32)
    png = encode_depth_png(depth, filter_up=filter_up)
    decoded = cv2.imdecode(np.frombuffer(png, np.uint8), cv2.IMREAD_UNCHANGED)
    assert decoded.dtype == np.uint16
    np.testing.assert_array_equal(decoded, [[0, 1234, 65535], [0, 0, 10000]])
    np.testing.assert_array_equal(decoded, depth_to_uint16(depth))


@pytest.mark.parametrize("weather", ["day", "night", "fog"])
def test_shading_in_stripes_gives_the_image_of_one_pass(
    synth: SimpleNamespace, monkeypatch: pytest.MonkeyPatch, weather: str
) -> None:
    boxes = synth.agents([(7, SemanticClass.CAR, 15.0, 0.0, 0.75, 4.5, 1.8, 1.5, 0.3)])
    scene = synth.scene([synth.ground(), synth.wall_at_x(150.0)], boxes)
    camera, w = Camera(CameraSpec(width_px=200, height_px=120)), weather_preset(weather)
    frame = camera.sense(scene, synth.EGO, w, np.random.default_rng(1)).frame
    flat = replace(frame, shading=replace(frame.shading, part=None))
    for module in (shading_module, photo_module):  # the flat style's stripes and the realistic one's
        monkeypatch.setattr(module, "STRIPE_PX", 4000)  # 6 stripes, the last one short
    striped, striped_flat = shade_frame(frame), shade_frame(flat)
    assert striped.any() and not np.array_equal(striped, striped_flat)
    for module in (shading_module, photo_module):
        monkeypatch.setattr(module, "STRIPE_PX", 10**9)
    np.testing.assert_array_equal(striped, shade_frame(frame))
    np.testing.assert_array_equal(striped_flat, shade_frame(flat))


def test_sun_shadow_rays_match_a_brute_force_check(synth: SimpleNamespace) -> None:
    # a box standing on the ground ahead: which ground pixels lie in its shadow, by a slab test
    box = synth.agents([(9, SemanticClass.POLE, 9.0, 2.5, 1.0, 2.0, 1.5, 2.0, 0.0)])
    scene = synth.scene([synth.ground()], box)
    spec = CameraSpec(width_px=320, height_px=180, mount_rpy_deg=(0.0, 12.0, 0.0))
    frame = Camera(spec).sense(scene, synth.EGO, DAY, np.random.default_rng(0)).frame
    lit = frame.shading.sun_lit
    assert lit is not None
    ground = (frame.semantic_class.ravel() == SemanticClass.ROAD) & (frame.depth_m.ravel() > 0)
    dirs = spec.pinhole.image_directions() @ spec.ego_SE3_sensor.rotation.T.astype(np.float32)
    origin = spec.ego_SE3_sensor.translation
    points = origin + dirs * (frame.depth_m.ravel() / spec.pinhole.image_directions()[:, 2])[:, None]
    sun = np.asarray(DAY.sun_dir_map) / np.linalg.norm(DAY.sun_dir_map)
    lo = np.array([8.0, 1.75, 0.03])  # the box's mesh: its footprint, standing 3 cm off the road
    hi = np.array([10.0, 3.25, 2.0])
    start = points + np.array([0.0, 0.0, SHADOW_LIFT_M])  # shadow rays leave the road this far above it
    with np.errstate(divide="ignore", invalid="ignore"):
        t0, t1 = (lo - start) / sun, (hi - start) / sun
    near, far = np.minimum(t0, t1).max(axis=1), np.maximum(t0, t1).min(axis=1)
    shadowed = (far >= np.maximum(near, 0.0)) & ground
    assert shadowed.sum() > 50  # the test means something: a shadow is in view
    rim = np.abs(far - np.maximum(near, 0.0)) < 1e-3  # grazing rays at the shadow's edge may go either way
    np.testing.assert_array_equal(~lit[ground & ~rim], shadowed[ground & ~rim])


@pytest.mark.parametrize("weather", ["day", "night"])
def test_lamps_light_as_the_traffic_sets_them(synth: SimpleNamespace, weather: str) -> None:
    # a car seen from behind: its brake lamps, and one indicator flashing on its own side
    from sensors.agents import Lamp
    from sensors.parts import Part

    def render(lamps: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        car = synth.agents([(7, SemanticClass.CAR, 9.0, 0.0, 0.75, 4.5, 1.8, 1.5, 0.0)])
        car = replace(car, lamps=np.array([lamps], np.uint8))
        scene = synth.scene([synth.ground()], car)
        frame = (
            Camera(CameraSpec(width_px=320, height_px=180))
            .sense(scene, synth.EGO, weather_preset(weather), np.random.default_rng(0))
            .frame
        )
        assert frame.shading.part is not None
        return shade_frame(frame).reshape(-1, 3).astype(np.float64), frame.shading.part, frame.instance_id.ravel()

    off, part, _ = render(int(Lamp.LIGHTS))
    tail = part == Part.TAIL_LAMP
    indicator = part == Part.INDICATOR
    u = np.tile(np.arange(320), 180)
    assert tail.sum() > 20 and indicator.sum() > 4  # the test means something: the lamps are in view
    braking, _, _ = render(int(Lamp.LIGHTS | Lamp.BRAKE))
    assert braking[tail].mean() > off[tail].mean() + 15
    left, _, _ = render(int(Lamp.LIGHTS | Lamp.LEFT | Lamp.FLASH))
    dimmed, _, _ = render(int(Lamp.LIGHTS | Lamp.LEFT))  # flashing, but dark at this instant
    on_left, on_right = indicator & (u < 160), indicator & (u >= 160)  # facing away: its left is the image's left
    assert left[on_left].mean() > off[on_left].mean() + 15
    np.testing.assert_allclose(left[on_right].mean(), off[on_right].mean(), atol=2.0)
    np.testing.assert_allclose(dimmed[indicator].mean(), off[indicator].mean(), atol=2.0)


def _bus_shaded(
    synth: SimpleNamespace, weather: str, lamps: int, ahead_m: float, yaw: float
) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """A 12 m bus ``ahead_m`` ahead of the ego heading ``yaw`` with ``lamps`` lit, shaded at 320x180:
    each pixel's BGR and part."""
    bus = synth.agents([(5, SemanticClass.BUS, ahead_m, 0.0, 1.55, 12.0, 2.55, 3.1, yaw)])
    bus = replace(bus, lamps=np.array([lamps], np.uint8))
    frame = (
        Camera(CameraSpec(width_px=320, height_px=180))
        .sense(synth.scene([synth.ground()], bus), synth.EGO, weather_preset(weather), np.random.default_rng(0))
        .frame
    )
    assert frame.shading.part is not None
    return shade_frame(frame).reshape(-1, 3).astype(np.float64), frame.shading.part


def test_a_bus_in_service_shows_lit_windows_at_night_and_a_parked_one_dark(synth: SimpleNamespace) -> None:
    from sensors.agents import Lamp
    from sensors.parts import Part

    def render(weather: str, lamps: int) -> tuple[np.ndarray, np.ndarray]:
        return _bus_shaded(synth, weather, lamps, 8.0, np.pi / 2)  # side on, across the view

    lit, part = render("night", int(Lamp.LIGHTS))
    glass = part == Part.GLASS
    assert glass.sum() > 200  # the test means something: the windows are in view
    parked, _ = render("night", 0)
    assert lit[glass].mean() > parked[glass].mean() + 40
    day_on, _ = render("day", int(Lamp.LIGHTS))
    day_off, _ = render("day", 0)
    np.testing.assert_allclose(day_on[glass].mean(), day_off[glass].mean(), atol=1.0)  # by day nothing shows


def test_a_bus_in_service_lights_its_destination_display_and_a_parked_one_does_not(synth: SimpleNamespace) -> None:
    from sensors.agents import Lamp
    from sensors.parts import Part

    def render(weather: str, lamps: int) -> tuple[np.ndarray, np.ndarray]:
        return _bus_shaded(synth, weather, lamps, 14.0, np.pi)  # facing the camera

    for weather, gain in (("night", 40), ("day", 10)):
        lit, part = render(weather, int(Lamp.LIGHTS))
        display = part == Part.DISPLAY
        assert display.sum() > 20  # the display is in view
        parked, _ = render(weather, 0)
        assert lit[display, 2].mean() > parked[display, 2].mean() + gain, weather  # amber: red channel most
        assert lit[display, 2].mean() > lit[display, 0].mean() + 40, weather


def test_street_faces_handed_over_in_the_map_frame_are_drawn_in_the_cameras_frame() -> None:
    from networks.vocabulary import Lamp, SignKind
    from sensors.shading import SIGN_KINDS, street_faces

    cam_SE3_map = SE3(np.array([[0.0, -1.0, 0.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0]]), np.zeros(3))  # optical axes
    faces = street_faces(np.array([7, 8], np.uint32), np.array([[20.0, 1.0, 3.0], [15.0, -2.0, 2.2]]),
                         np.array([math.pi, math.pi]), np.array([[0.3, 0.35, 1.0], [0.05, 0.6, 0.6]]),
                         [Lamp.RED_YELLOW, SignKind.SPEED_LIMIT], cam_SE3_map)  # fmt: skip
    assert faces.lit.tolist() == [[True, True, False], [False, False, False]]
    assert faces.sign.tolist() == [-1, SIGN_KINDS.index(SignKind.SPEED_LIMIT)]
    assert np.allclose(faces.centre_cam[0], [-1.0, -3.0, 20.0])  # right of the camera is -y of the map
    assert np.allclose(faces.front_cam, [[0.0, 0.0, -1.0]] * 2, atol=1e-6)  # facing the camera
    assert np.allclose(faces.up_cam, [[0.0, -1.0, 0.0]] * 2)  # the map's up is the image's up
