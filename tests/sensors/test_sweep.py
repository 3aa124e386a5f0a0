from __future__ import annotations

from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest

from cosim.rigs import HDL32E_ELEVATIONS_DEG, HDL64E_ELEVATIONS_DEG
from networks.classes import SemanticClass
from networks.geometry import box_rotations
from networks.mesh import merge
from sensors.errors import SensorConfigError
from sensors.hits import RayHits
from sensors.lidar import INTENSITY_RESPONSES, Lidar, LidarScan, LidarSpec
from sensors.o3d import RaycastingScene, o3c
from sensors.parts import Part, part_albedo
from sensors.weather import DAY

from .reference_forms import lidar_reflectance

KITTI_LIKE = {"beams": 64, "elevations_deg": HDL64E_ELEVATIONS_DEG, "vertical_min_deg": HDL64E_ELEVATIONS_DEG[0],
              "vertical_max_deg": HDL64E_ELEVATIONS_DEG[-1], "azimuth_steps": 2048, "rate_hz": 10.0,
              "firing": "hdl64e", "sweep": "timed"}  # fmt: skip


def kitti_lidar(**kw: object) -> Lidar:
    return Lidar(LidarSpec(**{**KITTI_LIKE, **kw}))  # type: ignore[arg-type]


def room(synth: SimpleNamespace) -> list:
    """Ground and four walls around the origin: a static world seen all around."""
    q = synth.quad
    walls = [q([(x, -25, -1), (x, 25, -1), (x, 25, 9), (x, -25, 9)], SemanticClass.BUILDING) for x in (-30.0, 35.0)]
    walls += [q([(-30, y, -1), (35, y, -1), (35, y, 9), (-30, y, 9)], SemanticClass.BUILDING) for y in (-25.0, 20.0)]
    return [synth.ground(40.0), *walls]


def surface_distance_m(static: list, xyz_map: np.ndarray) -> np.ndarray:
    mesh = merge(static)
    scene = RaycastingScene()
    scene.add_triangles(
        o3c.Tensor.from_numpy(mesh.vertices_m.astype(np.float32)),
        o3c.Tensor.from_numpy(mesh.triangles.astype(np.uint32)),
    )
    return np.asarray(scene.compute_distance(o3c.Tensor.from_numpy(xyz_map.astype(np.float32))).numpy())


def lidar_to_map(lidar: Lidar, ego: object, xyz: np.ndarray) -> np.ndarray:
    map_SE3_lidar = ego.map_SE3_ego().compose(lidar.spec.ego_SE3_sensor)  # type: ignore[attr-defined]
    return np.asarray(map_SE3_lidar.transform_from(xyz.astype(np.float64)))


def test_deskewed_scan_of_a_static_world_from_a_moving_ego_lies_where_the_instant_scan_does(
    synth: SimpleNamespace,
) -> None:
    static = room(synth)
    ego = synth.ego((15.0, 3.0, 0.0))
    world = synth.scene(static)
    timed = kitti_lidar(deskew=True).sense(world, ego, DAY, np.random.default_rng(1)).scan
    instant = kitti_lidar(sweep="instant").sense(world, ego, DAY, np.random.default_rng(1)).scan
    lidar = kitti_lidar()
    raw = surface_distance_m(static, lidar_to_map(lidar, ego, timed.xyz_lidar_m))
    fixed = surface_distance_m(static, lidar_to_map(lidar, ego, timed.xyz_deskewed_lidar_m))
    still = surface_distance_m(static, lidar_to_map(lidar, ego, instant.xyz_lidar_m))
    assert raw.max() > 0.5  # the sweep really is skewed: up to 0.76 m at 15.3 m/s over 50 ms
    assert fixed.max() <= 0.02 and still.max() <= 0.02
    assert abs(len(timed) - len(instant)) < 0.01 * len(instant)


@pytest.mark.parametrize("speed_mps", [-20.0, 12.0])
def test_a_passing_car_is_distorted_by_its_speed_times_each_points_time(
    synth: SimpleNamespace, speed_mps: float
) -> None:
    car = synth.agents([(5, SemanticClass.CAR, 2.0, 7.0, 0.75, 4.5, 1.8, 1.5, 0.0)], [[speed_mps, 0.0, 0.0]])
    world = synth.scene([synth.ground()], car)
    lidar = kitti_lidar()
    scan = lidar.sense(world, synth.ego(), DAY, np.random.default_rng(1)).scan
    instant = kitti_lidar(sweep="instant").sense(world, synth.ego(), DAY, np.random.default_rng(1)).scan
    on = scan.instance_id == 5
    assert on.sum() > 500
    dt = scan.t_s[on].astype(np.float64) - 0.05  # the middle of the 10 Hz sweep
    assert np.ptp(dt) > 0.005
    xyz = lidar_to_map(lidar, synth.ego(), scan.xyz_lidar_m[on])
    back = xyz[:, 0] - speed_mps * dt  # each point moved back by the car's motion since the reference time
    assert np.all(np.abs(back - 2.0) <= 2.25 + 0.02)
    assert np.any(np.abs(xyz[:, 0] - 2.0) > 2.25 + 0.1)  # without moving back they leave the box
    # the car's apparent length changes by v * (time between its two ends)
    was = lidar_to_map(lidar, synth.ego(), instant.xyz_lidar_m[instant.instance_id == 5])
    span_t = dt[np.argmax(xyz[:, 0])] - dt[np.argmin(xyz[:, 0])]
    np.testing.assert_allclose(np.ptp(xyz[:, 0]), np.ptp(was[:, 0]) + speed_mps * span_t, atol=0.05)


PATTERNS = [("hdl64e", HDL64E_ELEVATIONS_DEG), ("hdl32e", HDL32E_ELEVATIONS_DEG), ("even", HDL32E_ELEVATIONS_DEG)]


@pytest.mark.parametrize(("firing", "elevations"), PATTERNS)
def test_point_times_rise_clockwise_from_behind_as_the_firing_pattern_says(
    synth: SimpleNamespace, firing: str, elevations: tuple[float, ...]
) -> None:
    beams, steps, rate = len(elevations), 1084, 20.0
    lidar = Lidar(LidarSpec(beams=beams, elevations_deg=elevations, vertical_min_deg=elevations[0],
                            vertical_max_deg=elevations[-1], azimuth_steps=steps, rate_hz=rate, firing=firing,
                            sweep="timed"))  # type: ignore[arg-type]  # fmt: skip
    scan = lidar.sense(synth.scene(room(synth)), synth.EGO, DAY, np.random.default_rng(1)).scan
    assert len(scan) > 0.9 * beams * steps
    cycle = 1.0 / rate / steps
    azimuth = np.arctan2(scan.xyz_lidar_m[:, 1], scan.xyz_lidar_m[:, 0])
    turned = np.mod(np.pi - azimuth, 2 * np.pi)  # clockwise from straight behind
    column = np.round(turned / (2 * np.pi) * steps) % steps
    offset = scan.t_s - column * cycle
    assert np.all((offset >= -1e-6) & (offset < cycle))  # every shot inside its column's firing cycle
    order = np.argsort(turned, kind="stable")
    assert np.all(np.diff(column[order] * cycle) >= 0)
    assert scan.t_s.max() < 1.0 / rate
    per_ring = np.array([np.median(offset[scan.ring == r]) for r in range(beams)]) / cycle
    if firing == "hdl64e":  # both blocks at once, each from its top beam down
        np.testing.assert_allclose(per_ring[63], 0.0, atol=1e-3)
        np.testing.assert_allclose(per_ring[31], 0.0, atol=1e-3)
        np.testing.assert_allclose(per_ring[0], 31 / 32, atol=1e-3)
    elif firing == "hdl32e":  # 1.152 us of a 46.08 us cycle apart, lower and upper bank interleaved
        np.testing.assert_allclose(per_ring[[0, 16, 1, 17, 31]], np.array([0, 1, 2, 3, 31]) * 1.152 / 46.08, atol=1e-3)
    else:
        np.testing.assert_allclose(per_ring, np.arange(beams) / beams, atol=1e-3)


def test_firing_pattern_needs_its_sensors_beam_count() -> None:
    with pytest.raises(SensorConfigError, match="hdl64e needs 64 beams"):
        LidarSpec(beams=32, firing="hdl64e")


def points_back_in_boxes(lidar: Lidar, ego: object, agents: object, scan: LidarScan, t_ref_s: float) -> np.ndarray:
    """Each object point in its box's frame at the reference time, moved back by its object's motion."""
    out = np.zeros((len(scan), 3))
    on = np.flatnonzero(scan.instance_id > 0)
    xyz = lidar_to_map(lidar, ego, scan.xyz_lidar_m[on])
    xyz += (scan.t_s[on, None] - t_ref_s) * ego.velocity_map_mps  # type: ignore[attr-defined]  # the sensor moved
    row = np.searchsorted(agents.instance_id, scan.instance_id[on])  # type: ignore[attr-defined]
    back = xyz - agents.velocity_map_mps[row] * (scan.t_s[on, None] - t_ref_s)  # type: ignore[attr-defined]
    rot = box_rotations(agents.yaw_map_rad, agents.pitch_rad)[row]  # type: ignore[attr-defined]
    local = np.einsum("kji,kj->ki", rot, back - agents.center_map_m[row])  # type: ignore[attr-defined]
    out[on] = np.abs(local) - agents.lwh_m[row] / 2.0  # type: ignore[attr-defined]
    return out[on]


@pytest.mark.parametrize("reference", ["start", "middle", "end"])
def test_object_points_moved_back_to_the_reference_time_lie_in_their_boxes(
    synth: SimpleNamespace, reference: str
) -> None:
    rows = [(3, SemanticClass.CAR, 12.0, 4.0, 0.75, 4.5, 1.8, 1.5, 0.3), (4, SemanticClass.TRUCK, -15.0, -5.0, 1.6,
            9.0, 2.5, 3.2, 3.0), (7, SemanticClass.PEDESTRIAN, 4.0, -6.0, 0.9, 0.5, 0.6, 1.8, 1.5),
            (9, SemanticClass.BICYCLE, -6.0, 8.0, 0.85, 1.8, 0.6, 1.7, -0.4)]  # fmt: skip
    velocity = [[14.0 * np.cos(0.3), 14.0 * np.sin(0.3), 0], [-20.0, -2.0, 0], [0, 1.4, 0], [4.0, -1.6, 0]]
    agents = synth.agents(rows, velocity)
    ego = synth.ego((11.0, 0.0, 0.0))
    lidar = kitti_lidar(reference=reference)
    scan = lidar.sense(synth.scene([synth.ground()], agents), ego, DAY, np.random.default_rng(3)).scan
    assert set(np.unique(scan.instance_id)) == {0, 3, 4, 7, 9}
    t_ref = {"start": 0.0, "middle": 0.05, "end": 0.1}[reference]
    outside = points_back_in_boxes(lidar, ego, agents, scan, t_ref)
    assert outside.max() <= 0.02
    assert points_back_in_boxes(lidar, ego, agents, scan, t_ref + 0.05).max() > 0.1  # a wrong time fails


def on_circle(centre: np.ndarray, heading: np.ndarray, speed: np.ndarray, rate: np.ndarray, dt: np.ndarray) -> tuple:
    """Where a body moving at ``speed`` along ``heading`` and turning at ``rate`` is after ``dt``
    (a circle's arc), and its heading then."""
    turned = heading + rate * dt
    x = centre[..., 0] + speed / rate * (np.sin(turned) - np.sin(heading))
    y = centre[..., 1] - speed / rate * (np.cos(turned) - np.cos(heading))
    return np.stack([x, y, centre[..., 2] + 0 * dt], -1), turned


def rot_z(angle: np.ndarray) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    out = np.zeros((*np.shape(angle), 3, 3))
    out[..., 0, 0], out[..., 0, 1], out[..., 1, 0], out[..., 1, 1], out[..., 2, 2] = c, -s, s, c, 1.0
    return out


@pytest.mark.parametrize("reference", ["middle", "end"])
def test_points_on_turning_cars_from_a_turning_ego_moved_back_along_their_arcs_lie_in_their_boxes(
    synth: SimpleNamespace, reference: str
) -> None:
    # a car behind on the left turning at 1.2 rad/s (10 m/s round a 8.3 m radius), a bus behind turning at -0.9 rad/s,
    # seen from an ego turning at 0.6 rad/s
    rows = [
        (3, SemanticClass.CAR, -6.0, 7.0, 0.75, 4.5, 1.8, 1.5, 0.4),
        (4, SemanticClass.BUS, -14.0, -2.0, 1.6, 12.0, 2.5, 3.2, 1.4),
    ]
    speed, heading, rate = np.array([10.0, 8.0]), np.array([0.4, 1.4]), np.array([1.2, -0.9])
    velocity = np.stack([speed * np.cos(heading), speed * np.sin(heading), 0 * speed], -1)
    agents = synth.agents(rows, velocity, rate)
    ego_speed, ego_rate = 9.0, 0.6
    ego = synth.ego((ego_speed, 0.0, 0.0), ego_rate)
    lidar = kitti_lidar(reference=reference, deskew=True)
    scan = lidar.sense(synth.scene([synth.ground()], agents), ego, DAY, np.random.default_rng(3)).scan
    t_ref = {"middle": 0.05, "end": 0.1}[reference]
    dt = scan.t_s.astype(np.float64) - t_ref
    # each point in the map where the sensor was when it fired: the ego on its own arc
    map_SE3_lidar = ego.map_SE3_ego().compose(lidar.spec.ego_SE3_sensor)
    ego_at, ego_turned = on_circle(ego.center_map_m, np.zeros_like(dt), ego_speed, ego_rate, dt)
    arm = map_SE3_lidar.translation - ego.center_map_m
    origin = ego_at + np.einsum("kij,j->ki", rot_z(ego_turned), arm)
    xyz = origin + np.einsum("kij,kj->ki", rot_z(ego_turned) @ map_SE3_lidar.rotation, scan.xyz_lidar_m)
    counted = 0
    for k, tid in enumerate((3, 4)):
        on = scan.instance_id == tid
        assert on.sum() > 300
        counted += 1
        box_at, box_heading = on_circle(agents.center_map_m[k], heading[k], speed[k], rate[k], dt[on])
        local = np.einsum("kji,kj->ki", rot_z(box_heading), xyz[on] - box_at)
        assert np.max(np.abs(local) - agents.lwh_m[k] / 2.0) <= 0.02
        # the same points moved back by the velocity alone (the heading kept) land elsewhere on
        # the body: over 5 cm from where the arc puts them
        moved_straight = xyz[on] - agents.center_map_m[k] - velocity[k] * dt[on, None]
        straight = np.einsum("ji,kj->ki", rot_z(heading[k]), moved_straight)
        assert np.max(np.linalg.norm(straight - local, axis=1)) > 0.05
    assert counted == 2
    # the deskewed copy: every ground point in the sensor's frame at the reference time lies on the ground
    ground = scan.semantic_class == SemanticClass.ROAD
    still = map_SE3_lidar.transform_from(scan.xyz_deskewed_lidar_m[ground].astype(np.float64))
    assert np.abs(still[:, 2]).max() <= 0.02
    raw = map_SE3_lidar.transform_from(scan.xyz_lidar_m.astype(np.float64))
    np.testing.assert_allclose(still, xyz[ground], atol=0.02)
    assert np.abs(raw[ground] - xyz[ground]).max() > 0.3


def test_bodies_turning_at_one_rate_before_the_frames_time_and_another_after_are_cast_on_both_arcs(
    synth: SimpleNamespace,
) -> None:
    # cars entering a bend (0.3 rad/s over the step before the frame, 1.4 over the next), one on the
    # left behind (swept before the frame's time), one on the right behind (after), seen from an ego straightening
    # out (0.8 then 0.2 rad/s): each point moved back along the arc of its side of the frame's time
    rows = [(3, SemanticClass.CAR, -6.0, 7.0, 0.75, 4.5, 1.8, 1.5, 0.4),
            (5, SemanticClass.CAR, -6.0, -7.0, 0.75, 4.5, 1.8, 1.5, 0.4)]  # fmt: skip
    speed, heading, before, after = 10.0, 0.4, 0.3, 1.4
    velocity = np.array([[speed * np.cos(heading), speed * np.sin(heading), 0.0]] * 2)
    agents = replace(synth.agents(rows, velocity, [before] * 2), yaw_rate_after_rad_s=np.full(2, after))
    ego_speed, ego_before, ego_after = 9.0, 0.8, 0.2
    ego = replace(synth.ego((ego_speed, 0.0, 0.0), ego_before), yaw_rate_after_rad_s=ego_after)
    lidar = kitti_lidar(reference="middle")
    scan = lidar.sense(synth.scene([synth.ground()], agents), ego, DAY, np.random.default_rng(3)).scan
    dt = scan.t_s.astype(np.float64) - 0.05
    map_SE3_lidar = ego.map_SE3_ego().compose(lidar.spec.ego_SE3_sensor)
    ego_rate = np.where(dt < 0, ego_before, ego_after)
    ego_at, ego_turned = on_circle(ego.center_map_m, np.zeros_like(dt), ego_speed, ego_rate, dt)
    arm = map_SE3_lidar.translation - ego.center_map_m
    origin = ego_at + np.einsum("kij,j->ki", rot_z(ego_turned), arm)
    xyz = origin + np.einsum("kij,kj->ki", rot_z(ego_turned) @ map_SE3_lidar.rotation, scan.xyz_lidar_m)
    for k, (tid, side, other) in enumerate(((3, -1, after), (5, 1, before))):
        on = scan.instance_id == tid
        assert on.sum() > 300 and (np.sign(dt[on]) == side).all()
        for rate, most_m in ((np.where(dt[on] < 0, before, after), 0.02), (np.full(on.sum(), other), None)):
            box_at, box_heading = on_circle(agents.center_map_m[k], heading, speed, rate, dt[on])
            local = np.einsum("kji,kj->ki", rot_z(box_heading), xyz[on] - box_at)
            outside = np.max(np.abs(local) - agents.lwh_m[k] / 2.0)
            assert outside <= most_m if most_m else outside > 0.03  # the other side's rate misses


def test_glass_gives_no_return_from_its_surface(synth: SimpleNamespace) -> None:
    car = synth.agents([(5, SemanticClass.CAR, 8.0, 0.0, 0.75, 4.5, 1.8, 1.5, np.pi / 2)])
    world = synth.scene([synth.ground(), synth.wall_at_x(20.0)], car)
    for sweep in ("instant", "timed"):
        lidar = kitti_lidar(sweep=sweep)
        rays, hits = lidar.cast(world, synth.ego())
        plain = world.cast(rays)
        glass = plain.part == Part.GLASS
        assert glass.sum() > 30
        assert not np.any(hits.part == Part.GLASS)
        assert np.all(hits.range_m[glass] > plain.range_m[glass])  # what lies behind the pane
        assert np.median(hits.range_m[glass] - plain.range_m[glass]) > 0.3
        assert np.any(hits.semantic_class[glass] == SemanticClass.BUILDING)  # some see the wall through the car
        same = ~glass & np.isfinite(plain.range_m)
        np.testing.assert_allclose(hits.range_m[same], plain.range_m[same], atol=2e-3)


def test_same_seed_same_timed_scan(synth: SimpleNamespace) -> None:
    car = synth.agents([(5, SemanticClass.CAR, 8.0, 3.0, 0.75, 4.5, 1.8, 1.5, 0.2)], [[5.0, 1.0, 0.0]])
    world = synth.scene([synth.ground()], car)
    a = kitti_lidar(deskew=True, dropout=0.1).sense(world, synth.ego((8.0, 0, 0)), DAY, np.random.default_rng(5))
    b = kitti_lidar(deskew=True, dropout=0.1).sense(world, synth.ego((8.0, 0, 0)), DAY, np.random.default_rng(5))
    for f in LidarScan.__slots__:
        assert getattr(a.scan, f).tobytes() == getattr(b.scan, f).tobytes()


def test_paint_returns_by_its_colour_plates_and_road_paint_retro_reflect() -> None:
    ids = np.arange(1, 400, dtype=np.uint32)
    paint = np.full(ids.shape[0], int(Part.PAINT), np.uint8)
    car = np.full(ids.shape[0], int(SemanticClass.CAR), np.uint8)
    reflectance, retro = lidar_reflectance(car, paint, ids)
    albedo = part_albedo(paint, ids).mean(axis=1)
    # black weak, white about 7 times stronger, as paint at 905 nm follows its colour (body paint as cargo panels)
    assert reflectance[albedo < 0.1].max() < 0.11 and reflectance[albedo > 0.8].min() > 0.6
    np.testing.assert_allclose(reflectance, 0.05 + 0.7 * albedo, rtol=1e-6)
    assert not retro.any()
    cargo, _ = lidar_reflectance(np.full(2, int(SemanticClass.TRUCK), np.uint8), np.full(2, int(Part.CARGO), np.uint8),
                                 np.array([1, 2], np.uint32))  # fmt: skip
    cargo_albedo = part_albedo(np.full(2, int(Part.CARGO), np.uint8), np.array([1, 2], np.uint32)).mean(axis=1)
    np.testing.assert_allclose(cargo, 0.05 + 0.7 * cargo_albedo, rtol=1e-6)
    parts = np.array([Part.TYRE, Part.PLATE, Part.SURFACE, Part.SURFACE, Part.SURFACE], np.uint8)
    classes = np.array([SemanticClass.CAR, SemanticClass.CAR, SemanticClass.ROAD, SemanticClass.LANE_MARKING,
                        SemanticClass.TRAFFIC_SIGN], np.uint8)  # fmt: skip
    reflectance, retro = lidar_reflectance(classes, parts, np.array([5, 5, 0, 0, 0], np.uint32))
    assert reflectance[0] <= 0.05 and retro.tolist() == [False, True, False, True, True]


def test_road_paint_outshines_asphalt_at_grazing_incidence(synth: SimpleNamespace) -> None:
    stripe = synth.quad(
        [(5, 1, 0.001), (60, 1, 0.001), (60, 1.15, 0.001), (5, 1.15, 0.001)], SemanticClass.LANE_MARKING
    )
    scan = (
        kitti_lidar(sweep="instant")
        .sense(synth.scene([synth.ground(), stripe]), synth.EGO, DAY, np.random.default_rng(1))
        .scan
    )
    far = scan.xyz_lidar_m[:, 0] > 15
    paint = scan.intensity[far & (scan.semantic_class == SemanticClass.LANE_MARKING)]
    road = scan.intensity[far & (scan.semantic_class == SemanticClass.ROAD) & (np.abs(scan.xyz_lidar_m[:, 1]) < 3)]
    assert paint.size > 10 and road.size > 10
    assert np.median(paint) > 20 * np.median(road)


def test_returns_drop_with_received_power_none_from_the_sky_or_beyond_range(synth: SimpleNamespace) -> None:
    lidar = kitti_lidar(sweep="instant", range_10pct_m=50.0)
    world = synth.scene([synth.ground(), synth.wall_at_x(110.0, half_m=300.0), synth.wall_at_x(-130.0, half_m=300.0)])
    rays, hits = lidar.cast(world, synth.EGO)
    chance = lidar.detection_probability(hits, rays)
    road = (hits.semantic_class == SemanticClass.ROAD) & np.isfinite(hits.range_m)
    near, far = road & (hits.range_m < 12), road & (hits.range_m > 70) & (hits.range_m < 100)
    # as in real KITTI scans: the road met 2-3 deg from grazing returns to 35-40 m, hardly from 70 m on
    mid = road & (hits.range_m > 33) & (hits.range_m < 40)
    assert chance[near].min() > 0.95 and chance[mid].min() > 0.9 and chance[far].max() < 0.15
    scan = lidar.sense(world, synth.EGO, DAY, np.random.default_rng(2)).scan
    r = np.linalg.norm(scan.xyz_lidar_m, axis=1)
    ground_points = scan.semantic_class == SemanticClass.ROAD
    assert np.sum(ground_points & (r < 12)) > 0.95 * np.sum(near)
    assert np.sum(ground_points & (r > 70)) < 0.15 * np.sum(far)
    assert r.max() <= 120.0 and not np.any(scan.xyz_lidar_m[:, 0] < -125)  # the wall behind is beyond range
    # a 10 % target facing the sensor at range_10pct_m returns half the time; the road's 12 % a little more
    facing = RayHits(np.array([50.0], np.float32), np.array([SemanticClass.ROAD], np.uint8), np.zeros(1, np.uint32),
                     np.array([[-1.0, 0, 0]], np.float32), np.zeros(1, np.uint8))  # fmt: skip
    ray = np.array([[0, 0, 0, 1, 0, 0]], np.float32)
    np.testing.assert_allclose(lidar.detection_probability(facing, ray), 1 / (1 + (0.1 / 0.12) ** 4), rtol=1e-6)


def test_a_timed_sweep_of_a_still_world_hits_what_the_instant_one_does(synth: SimpleNamespace) -> None:
    rows = [
        (k + 1, SemanticClass.CAR, 12.0 * np.cos(k), 12.0 * np.sin(k) + 0.3 * k, 0.75, 4.5, 1.8, 1.5, 0.7 * k)
        for k in range(8)
    ]
    rows += [
        (20, SemanticClass.PEDESTRIAN, 1.5, 2.0, 0.9, 0.5, 0.6, 1.8, 0.0),
        (21, SemanticClass.BUS, -4.0, -3.5, 1.6, 12.0, 2.5, 3.2, 0.2),
    ]
    world = synth.scene([synth.ground()], synth.agents(rows))
    _, timed = kitti_lidar().cast(world, synth.ego())
    _, instant = kitti_lidar(sweep="instant").cast(world, synth.ego())
    assert (instant.instance_id > 0).sum() > 5000
    assert np.array_equal(timed.instance_id, instant.instance_id)
    np.testing.assert_allclose(timed.range_m, instant.range_m, atol=2e-3)


def test_kitti_reading_keeps_the_rear_of_a_far_car_met_squarely_where_the_road_there_reads_0(
    synth: SimpleNamespace,
) -> None:
    """Met squarely, a clear coat's glint mirrors the beam straight back (an echo ``glint_echo``
    times a matte surface's): the rear of a car 35 m ahead keeps a reading where the road at that
    range (and the same car with a matte surface's echo) reads 0."""
    ahead = synth.agents([(1, SemanticClass.CAR, 35.0, 0.0, 0.75, 4.5, 1.8, 1.5, 0.0)])
    world = synth.scene([synth.ground()], ahead)
    kitti = kitti_lidar(sweep="instant", range_10pct_m=50.0, intensity="kitti")
    scan = kitti.sense(world, synth.EGO, DAY, np.random.default_rng(4)).scan
    car = scan.intensity[scan.instance_id == 1]
    r = np.hypot(scan.xyz_lidar_m[:, 0], scan.xyz_lidar_m[:, 1])
    road = scan.intensity[(scan.semantic_class == SemanticClass.ROAD) & (r > 30) & (r < 40)]
    assert car.size > 50 and np.percentile(car, 75) > 0.2 and np.median(road) == 0.0
    matte_echo = replace(INTENSITY_RESPONSES["kitti"], glint_echo=1.0)
    try:
        INTENSITY_RESPONSES["kitti"], kept = matte_echo, INTENSITY_RESPONSES["kitti"]
        again = kitti.sense(world, synth.EGO, DAY, np.random.default_rng(4)).scan
    finally:
        INTENSITY_RESPONSES["kitti"] = kept
    assert np.percentile(again.intensity[again.instance_id == 1], 75) == 0.0


def test_kitti_intensity_reads_like_real_kitti_scans(synth: SimpleNamespace) -> None:
    """The ``kitti`` intensity against what seven real KITTI scans read (README, LiDAR against real
    KITTI scans): road about 0.26 near and 0 from about 30 m, lane paint about 1.6 times the road,
    most car points 0 (clear-coated paint mirrors the beam away), in KITTI's 0.01 steps up to 0.99."""
    stripe = synth.quad(
        [(5, 1, 0.001), (60, 1, 0.001), (60, 1.15, 0.001), (5, 1.15, 0.001)], SemanticClass.LANE_MARKING
    )
    cars = synth.agents(
        [(k + 1, SemanticClass.CAR, 9.0 + 4.0 * k, -4.0 + 1.5 * k, 0.75, 4.5, 1.8, 1.5, 0.4 * k) for k in range(6)]
    )
    world = synth.scene([synth.ground(), stripe], cars)
    kitti = kitti_lidar(sweep="instant", range_10pct_m=50.0, intensity="kitti")
    scan = kitti.sense(world, synth.EGO, DAY, np.random.default_rng(4)).scan
    x, y = scan.xyz_lidar_m[:, 0], scan.xyz_lidar_m[:, 1]
    road = (scan.semantic_class == SemanticClass.ROAD) & (np.abs(y) < 2.5) & (x > 0)
    paint = scan.semantic_class == SemanticClass.LANE_MARKING
    car = scan.semantic_class == SemanticClass.CAR
    near_road = scan.intensity[road & (x > 5) & (x < 12)]
    assert 0.2 < np.median(near_road) < 0.35
    r = np.hypot(x, y)
    far_road = scan.intensity[(scan.semantic_class == SemanticClass.ROAD) & (r > 32) & (r < 45)]
    assert far_road.size > 100 and np.median(far_road) == 0.0
    near_paint = scan.intensity[paint & (x > 5) & (x < 12)]
    assert near_paint.size > 20 and 1.3 < np.median(near_paint) / np.median(near_road) < 2.2
    assert car.sum() > 500 and np.mean(scan.intensity[car] == 0.0) > 0.4
    assert scan.intensity.max() <= 0.99 and np.allclose(scan.intensity * 100, np.round(scan.intensity * 100), atol=1e-3)
    # each laser reads the same road by its own steady gain (real scans: 0.04 to 0.32 between lasers)
    by_ring = [np.median(scan.intensity[road & (scan.ring == k) & (x > 5) & (x < 12)]) for k in range(10, 30)
               if np.sum(road & (scan.ring == k) & (x > 5) & (x < 12)) > 20]  # fmt: skip
    assert len(by_ring) > 5 and max(by_ring) > 1.3 * min(by_ring)
    physical = kitti_lidar(sweep="instant", range_10pct_m=50.0).sense(world, synth.EGO, DAY, np.random.default_rng(4))
    assert np.median(physical.scan.intensity[(physical.scan.semantic_class == SemanticClass.ROAD)]) < 0.1


def test_kitti_reading_a_clear_coat_glints_on_some_points_more_often_met_squarely() -> None:
    """Real KITTI car points read 0 on 35 % of the points met squarely and 68 % of those met at
    |cos| < 0.5: each point of clear-coated paint glints with a chance that falls off the normal,
    so white paint 10 m away met squarely reads on most points but not all, met obliquely on few;
    where it glints it reads about as bright as a matte surface of its reflectivity."""
    kitti = kitti_lidar(sweep="instant", range_10pct_m=50.0, intensity="kitti")
    n = 4000
    white = np.full(n, 0.05 + 0.7 * 0.9, np.float32)

    def read(cos_inc: float, part: Part) -> np.ndarray:
        return kitti._read_intensity(white, np.zeros(n, bool), np.full(n, cos_inc, np.float32),
                                     np.full(n, 10.0, np.float32), np.full(n, part, np.uint8),
                                     (np.arange(n) % 64).astype(np.uint16), np.random.default_rng(3))  # fmt: skip

    squarely, obliquely, matte = read(1.0, Part.PAINT), read(0.4, Part.PAINT), read(1.0, Part.CARGO)
    assert 0.3 < np.mean(squarely == 0) < 0.5 and np.mean(obliquely == 0) > 0.85
    assert abs(np.median(squarely[squarely > 0]) - np.median(matte)) < 0.03


def test_kitti_reading_is_compressed_bright_walls_read_below_lane_paint(synth: SimpleNamespace) -> None:
    """In real KITTI scans the brightest tenth of the points reads from 0.42, lane paint's median:
    a building (reflectivity 0.45, four times the asphalt's) reads about as the paint does and
    under 1.75 times the road, not 2.2 times (0.66) as the reading linear up to 0.7 did."""
    stripe = synth.quad(
        [(5, 1, 0.001), (60, 1, 0.001), (60, 1.15, 0.001), (5, 1.15, 0.001)], SemanticClass.LANE_MARKING
    )
    wall = synth.quad([(4, 6, -1), (30, 6, -1), (30, 6, 9), (4, 6, 9)], SemanticClass.BUILDING)
    kitti = kitti_lidar(sweep="instant", range_10pct_m=50.0, intensity="kitti")
    scan = kitti.sense(synth.scene([synth.ground(), stripe, wall]), synth.EGO, DAY, np.random.default_rng(4)).scan
    x, y = scan.xyz_lidar_m[:, 0], scan.xyz_lidar_m[:, 1]
    near = (x > 5) & (x < 15)
    road = np.median(scan.intensity[near & (scan.semantic_class == SemanticClass.ROAD) & (np.abs(y) < 0.8)])
    paint = np.median(scan.intensity[near & (scan.semantic_class == SemanticClass.LANE_MARKING)])
    building = scan.intensity[near & (scan.semantic_class == SemanticClass.BUILDING)]
    assert building.size > 100 and 1.3 * road < np.median(building) < min(1.75 * road, paint + 0.03)
    assert 1.3 * road < paint < 2.0 * road


def _kitti_read(kitti: Lidar, reflectance: float, retro: bool, part: Part, cls: SemanticClass, rings: np.ndarray,
                seed: int = 3) -> np.ndarray:  # fmt: skip
    n = rings.shape[0]
    return kitti._read_intensity(np.full(n, reflectance, np.float32), np.full(n, retro), np.full(n, 0.05, np.float32),
                                 np.full(n, 8.0, np.float32), np.full(n, part, np.uint8), rings.astype(np.uint16),
                                 np.random.default_rng(seed), np.full(n, cls, np.uint8))  # fmt: skip


def test_kitti_reading_four_lasers_read_dark_asphalt_near_0_and_lane_paint_as_the_others() -> None:
    """In real KITTI scans four lasers (-13.1, -12.6, -10.2, -9.8 deg) read the road at 0.52-0.88
    of the other lasers' and on dark asphalt often near 0, while lane paint reads the same on
    them as on the others: each has its own intensity floor. A log-normal gain per laser scales
    road and paint alike."""
    kitti = kitti_lidar(sweep="instant", range_10pct_m=50.0, intensity="kitti")
    n = 6000
    weak, other = np.full(n, 29), np.full(n, 30)
    asphalt = [np.median(_kitti_read(kitti, 0.12, False, Part.SURFACE, SemanticClass.ROAD, r)) for r in (weak, other)]
    paint = [
        np.median(_kitti_read(kitti, 0.6, True, Part.SURFACE, SemanticClass.LANE_MARKING, r)) for r in (weak, other)
    ]
    assert (asphalt[0] / asphalt[1]) < 0.75 * (paint[0] / paint[1])
    assert np.mean(_kitti_read(kitti, 0.12, False, Part.SURFACE, SemanticClass.ROAD, weak) < 0.1) > 0.15


def test_kitti_reading_asphalt_grain_and_plates_that_saturate() -> None:
    """Within one laser's ring real KITTI asphalt reads down to 0.4 (p5) and 0.6 (p10) times its
    median (each footprint its own mix of stone and binder), lane paint far less spread; number
    plates (prismatic sheeting) read 0.9-0.99, twice what road paint's glass beads read (0.42)."""
    kitti = kitti_lidar(sweep="instant", range_10pct_m=50.0, intensity="kitti")
    ring = np.full(6000, 40)
    road = _kitti_read(kitti, 0.12, False, Part.SURFACE, SemanticClass.ROAD, ring)
    assert np.mean(road < 0.6 * np.median(road)) > 0.08
    paint = _kitti_read(kitti, 0.6, True, Part.SURFACE, SemanticClass.LANE_MARKING, ring)
    assert np.mean(paint < 0.6 * np.median(paint)) < 0.01
    plate = _kitti_read(kitti, 0.95, True, Part.PLATE, SemanticClass.CAR, ring)
    assert np.median(plate) > 1.8 * np.median(paint)
