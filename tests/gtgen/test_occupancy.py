"""Occupancy, visibility masks and flow on hand-built scenes with known answers."""

from dataclasses import replace

import numpy as np
import pytest
from shapely.geometry import box as rect

from gtgen.frame import FrameRecord
from gtgen.labels import label_frame
from gtgen.load import load_occupancy
from gtgen.occupancy import (
    FREE_NATIVE,
    OCC3D_CLASSES,
    OCC3D_LUT,
    camera_distances_m,
    camera_pixels,
    camera_rays,
    occupancy_frame,
)
from gtgen.sinks.group import SinkChoice, SinkGroup
from gtgen.sinks.images import FrameImages
from gtgen.sinks.mcap_sink import frame_messages, planned_topics
from gtgen.voxels import OccupancyGrid, box_voxels, triangle_voxels
from networks.classes import SemanticClass
from networks.geometry import SE3, box_rotations
from networks.mesh import flat_polygon, merge, prism
from networks.vocabulary import SensorKind
from sensors.agents import Agents, EgoState, motion_over
from sensors.camera import Camera, CameraSpec
from sensors.lidar import Lidar, LidarSpec
from sensors.scene import FrameScene
from sensors.solids import Solids
from sensors.sweep import reference_s, sensor_pose_at
from sensors.weather import DAY

EGO = EgoState.at(SE3.identity())
GROUND = flat_polygon(rect(-200, -200, 200, 200), 0.0, SemanticClass.ROAD)
SPEC = OccupancyGrid()


def car(x, y, speed_mps=0.0):
    a = Agents.standing([4], [int(SemanticClass.CAR)], [[x, y, 0.75]], [[4.4, 1.8, 1.5]], [0.0])
    velocity = np.array([[speed_mps, 0.0, 0.0]])
    return Agents(
        a.instance_id, a.semantic_class, a.center_map_m, a.lwh_m, a.yaw_map_rad, a.pitch_rad, velocity, a.parked
    )


def frame(static, agents, lidar=True, camera=True, with_meshes=False):
    scene = FrameScene(static, agents)
    rng = np.random.default_rng(0)
    lidars = (Lidar(LidarSpec()).sense(scene, EGO, DAY, rng),) if lidar else ()
    cameras = ()
    if camera:
        spec = CameraSpec(shading="flat")
        depth = Camera(spec).sense(scene, EGO, DAY, rng).frame.depth_m
        cameras = ((spec, camera_distances_m(SPEC, spec, depth)),)  # as the frame loop's step reads them
    meshes = scene.agent_meshes if with_meshes else None
    occupancy = occupancy_frame(
        SPEC, static, Solids(static), agents, EGO.map_SE3_ego(), EGO.velocity_map_mps, lidars, cameras, meshes
    )
    return occupancy, lidars


def test_box_agent_fills_exactly_its_box_and_the_road_fills_one_layer():
    grid = SPEC.grid
    expected, _ = box_voxels(
        grid, np.array([[10.1, 0.3, 0.75]]), box_rotations([0.0], [0.0]), np.array([[4.4, 1.8, 1.5]])
    )
    low_ground = flat_polygon(rect(-200, -200, 200, 200), -0.9, SemanticClass.ROAD)  # in layer 0, under the box
    occupancy, _ = frame(low_ground, car(10.1, 0.3), lidar=False, camera=False)
    cars = np.flatnonzero(occupancy.semantics_native.ravel() == SemanticClass.CAR)
    assert set(cars.tolist()) == set(expected.tolist())
    # x 7.9..12.3 -> voxels 119..130, y -0.6..1.2 -> 98..102 (1.2 m is a voxel face), z 0..1.5 -> 2..6
    ijk = np.stack(np.unravel_index(cars, grid.shape), axis=-1)
    assert (ijk.min(0).tolist(), ijk.max(0).tolist()) == ([119, 98, 2], [130, 102, 6])
    assert np.all(occupancy.instance.ravel()[cars] == 4)
    # on the road (z 0) the layer the road meets is the road's, the car's voxels start above it
    occupancy, _ = frame(GROUND, car(10.1, 0.3), lidar=False, camera=False)
    cars = np.flatnonzero(occupancy.semantics_native.ravel() == SemanticClass.CAR)
    above_road = expected[np.unravel_index(expected, grid.shape)[2] > 2]
    assert set(cars.tolist()) == set(above_road.tolist())
    road = occupancy.semantics_native == SemanticClass.ROAD
    assert road.sum() == 200 * 200 and road[:, :, 2].all()
    assert np.all(occupancy.instance[:, :, 2] == 0)
    assert OCC3D_CLASSES[occupancy.semantics[125, 100, 4]] == "car"
    assert (
        occupancy.semantics_native[0, 0, 10] == FREE_NATIVE and OCC3D_CLASSES[occupancy.semantics[0, 0, 10]] == "free"
    )


def test_building_is_solid_inside_not_only_its_walls():
    building = prism(rect(10.0, 10.0, 20.0, 20.0), -0.05, 12.0, SemanticClass.BUILDING)
    occupancy, _ = frame(merge([GROUND, building]), Agents.empty(), lidar=False, camera=False)
    inside = occupancy.semantics_native[125:150, 125:150, 3:]  # x, y 10..20 m, z 0.2..5.4 m
    assert np.all(inside == SemanticClass.BUILDING)
    assert np.all(occupancy.semantics_native[100:124, 100:124, 3:] == FREE_NATIVE)


@pytest.mark.parametrize("edge_x", [10.1, 10.3])  # the curb near either side of its voxels (10.0-10.4 m)
def test_every_point_lies_within_half_a_voxel_of_a_voxel_of_its_class_where_a_road_meets_a_curb(edge_x):
    """Road, curb and sidewalk share the voxels along the curb; each of those goes to the class whose
    surface in it lies farther than half a voxel from every other voxel of its class, so every LiDAR
    point has a voxel of its Occ3D class within half a voxel (by priority alone, the curb's class
    took them and road points in their far half had none). The terrain under them stays hidden."""
    road = flat_polygon(rect(-200, -200, edge_x, 200), 0.0, SemanticClass.ROAD)
    curb = prism(rect(edge_x, -200, 200, 200), 0.0, 0.15, SemanticClass.CURB)
    terrain = flat_polygon(rect(-250, -250, 250, 250), -0.05, SemanticClass.TERRAIN)
    static = merge([road, curb, terrain])
    occupancy, lidars = frame(static, Agents.empty(), camera=False)
    scan = lidars[0].scan
    xyz = scan.xyz_lidar_m.astype(np.float64) + LidarSpec().ego_SE3_sensor.translation
    g = SPEC.grid.to_grid(xyz)
    inside = SPEC.grid.inside(np.floor(g).astype(int))
    g, cls = g[inside], OCC3D_LUT[scan.semantic_class[inside]]
    near_curb = np.abs(xyz[inside, 0] - edge_x) < 1.0
    assert near_curb.sum() > 100 and set(np.unique(cls[near_curb]).tolist()) == {
        OCC3D_CLASSES.index("driveable_surface"), OCC3D_CLASSES.index("sidewalk")}  # fmt: skip
    semantics = occupancy.semantics
    found = np.zeros(len(cls), np.bool_)
    for offset in np.ndindex(3, 3, 3):
        q = np.clip(np.floor(g + (np.asarray(offset) - 1) * 0.5).astype(int), 0, np.asarray(SPEC.grid.shape) - 1)
        found |= semantics[tuple(q.T)] == cls
    assert found.all()
    assert not (occupancy.semantics == OCC3D_CLASSES.index("terrain")).any()


def test_solids_insides_by_runs_agree_with_every_voxel_centre_cast_alone():
    """One centre cast per run of voxels no wall, top or floor meets gives what casting every
    centre gives: a building standing 1 m up (voxels under its floor stay outside), one with a
    top tier, a gabled house, a tree (its crown solid), seen from an ego turned and pitched."""
    from gtgen.occupancy import _solid_insides
    from networks.buildings import gabled

    solids_mesh = merge(
        [
            prism(rect(6.0, 4.0, 14.0, 12.0), 1.0, 3.0, SemanticClass.BUILDING),
            prism(rect(-20.0, -20.0, -6.0, -8.0), -0.05, 2.5, SemanticClass.BUILDING),
            prism(rect(-17.0, -17.0, -9.0, -11.0), 2.45, 2.0, SemanticClass.BUILDING),
            gabled(rect(10.0, -14.0, 18.0, -8.0), -0.05, 2.6, 1.8, SemanticClass.BUILDING),
            _tree_for_test(-8.0, 10.0),
            _tree_for_test(-3.0, 16.0, "columnar"),
            _tree_for_test(-14.0, 3.0, "conifer"),
        ]
    )
    world = merge([GROUND, solids_mesh])
    solids = Solids(world)
    grid = SPEC.grid
    map_SE3_ego = SE3.from_matrix(_pose(yaw_rad=0.3, pitch_rad=0.04, xyz=(0.7, -0.3, 0.1)))
    ego_SE3_map = map_SE3_ego.inverse()
    tri = world.vertices_m[world.triangles].astype(np.float64)
    flat, source = triangle_voxels(grid, ego_SE3_map.transform_from(tri.reshape(-1, 3)).reshape(-1, 3, 3))
    surface = flat[np.isin(world.triangle_class[source], solids.classes)]
    inside, cls = _solid_insides(grid, solids, map_SE3_ego, surface)
    every = solids.inside(map_SE3_ego.transform_from(grid.centers_m(np.arange(grid.size))))
    every[surface] = 0  # voxels a surface meets are occupied by it: their centres are not asked
    got = np.zeros(grid.size, np.uint8)
    got[inside] = cls
    got[surface] = 0
    assert np.array_equal(got, every)
    counts = np.bincount(got, minlength=6)
    assert counts[SemanticClass.BUILDING] > 3000 and counts[SemanticClass.VEGETATION] > 100
    floating = map_SE3_ego.transform_from(grid.centers_m(np.flatnonzero(got == SemanticClass.BUILDING)))
    near_floating = (floating[:, 0] > 6.5) & (floating[:, 0] < 13.5) & (floating[:, 1] > 4.5) & (floating[:, 1] < 11.5)
    assert near_floating.any() and floating[near_floating, 2].min() > 1.0  # nothing under its floor


@pytest.mark.parametrize("kind", ["broadleaf", "columnar", "conifer"])
def test_a_street_trees_crown_fills_with_vegetation_its_trunk_with_trunk_and_the_air_round_it_stays_free(kind):
    """Every voxel whose centre lies inside the tree's crown (ray parity against the crown alone)
    is VEGETATION, or TRUNK where a limb's surface meets it; the trunk's voxel at 1 m is TRUNK;
    voxels no surface meets and whose centre lies outside the tree are free."""
    grid = SPEC.grid
    tree = _tree_for_test(10.0, 6.0, kind)
    occupancy, _ = frame(merge([GROUND, tree]), Agents.empty(), lidar=False, camera=False)
    native = occupancy.semantics_native.ravel()
    v = tree.vertices_m.astype(np.float64)
    crown = tree.triangles[tree.triangle_class == SemanticClass.VEGETATION]
    low, high = v[crown].reshape(-1, 3).min(axis=0), v[crown].reshape(-1, 3).max(axis=0)
    centres = grid.centers_m(np.arange(grid.size))  # the ego stands at the map's origin
    near = np.flatnonzero(np.all((centres >= low - 0.8) & (centres <= high + 0.8), axis=1))
    inside = _inside_surface(centres[near], v[crown])
    touched, wood = np.zeros(grid.size, np.bool_), np.zeros(grid.size, np.bool_)
    flat, source = triangle_voxels(grid, v[tree.triangles])
    touched[flat] = True
    wood[flat[tree.triangle_class[source] == SemanticClass.TRUNK]] = True
    leafy = near[inside & ~wood[near]]
    assert leafy.size > 20 and np.all(native[leafy] == SemanticClass.VEGETATION)
    assert np.all(native[near[inside & wood[near]]] == SemanticClass.TRUNK)  # the limbs inside the crown
    outside = near[~inside & ~touched[near]]
    assert outside.size > 100 and np.all(native[outside] == FREE_NATIVE)
    ijk = np.floor(grid.to_grid(np.array([[10.0, 6.0, 1.0]]))).astype(int)[0]
    assert occupancy.semantics_native[tuple(ijk)] == SemanticClass.TRUNK


def _inside_surface(points: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """Whether each point lies inside the closed surface of triangles ``tri: (T, 3, 3)`` (a ray
    along a skew direction crosses it an odd number of times)."""
    d = np.array([0.31, 0.17, 0.93])
    e1, e2 = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
    p = np.cross(d, e2)
    det = np.einsum("ij,ij->i", e1, p)
    s = points[:, None, :] - tri[None, :, 0]
    u = np.einsum("ntj,tj->nt", s, p) / det
    q = np.cross(s, e1[None])
    w = (q @ d) / det
    dist = np.einsum("tj,ntj->nt", e2, q) / det
    return ((u >= 0) & (w >= 0) & (u + w <= 1) & (dist > 0)).sum(axis=1) % 2 == 1


def _pose(yaw_rad: float, pitch_rad: float, xyz: tuple[float, float, float]) -> np.ndarray:
    cy, sy, cp, sp = np.cos(yaw_rad), np.sin(yaw_rad), np.cos(pitch_rad), np.sin(pitch_rad)
    m = np.eye(4)
    m[:3, :3] = np.array([[cy, -sy, 0.0], [sy, cy, 0.0], [0.0, 0.0, 1.0]]) @ np.array(
        [[cp, 0.0, sp], [0.0, 1.0, 0.0], [-sp, 0.0, cp]]
    )
    m[:3, 3] = xyz
    return m


def _tree_for_test(x: float, y: float, kind: str = "broadleaf"):
    from networks.trees import street_tree

    return street_tree(x, y, -0.05, 0, kind=kind)


def test_a_standing_ego_gets_the_same_occupancy_from_the_static_voxels_kept_from_its_last_frame(monkeypatch):
    import gtgen.occupancy as occupancy_module

    made = []
    near_index = occupancy_module._static_near_index
    monkeypatch.setattr(occupancy_module, "_static_near_index", lambda *a: made.append(1) or near_index(*a))
    building = prism(rect(6.0, 3.0, 12.0, 9.0), -0.05, 8.0, SemanticClass.BUILDING)
    curb = prism(rect(-30.0, -4.3, 30.0, -4.0), -0.05, 0.15, SemanticClass.CURB)
    static = merge([GROUND, building, curb, _tree_for_test(-8.0, 6.0)])
    solids = Solids(static)
    pose = SE3.from_matrix(_pose(0.3, 0.01, (1.3, -0.7, 0.2)))

    def at(agents, solids):
        return occupancy_frame(SPEC, static, solids, agents, pose, np.zeros(3), ())

    at(car(2.0, -1.0), solids)
    kept = at(car(4.0, -1.5), solids)  # the same pose, mesh and solids: the static voxels kept
    assert len(made) == 1
    fresh = at(car(4.0, -1.5), Solids(static))  # other solids: made again
    assert len(made) == 2
    for name in ("semantics_native", "instance", "mask_lidar", "mask_camera"):
        assert np.array_equal(getattr(kept, name), getattr(fresh, name))
    assert (kept.semantics_native == SemanticClass.BUILDING).sum() > 1000
    assert (kept.semantics_native == SemanticClass.CAR).any()
    moved = SE3(pose.rotation, pose.translation + np.array([0.0, 0.0, 1e-12]))
    occupancy_frame(SPEC, static, solids, car(4.0, -1.5), moved, np.zeros(3), ())
    assert len(made) == 3  # a pose not the same bit for bit: made again


def test_wall_hides_the_voxels_behind_it_from_both_masks():
    wall = prism(rect(8.0, -6.0, 8.4, 6.0), -0.05, 4.0, SemanticClass.BUILDING)
    occupancy, _ = frame(merge([GROUND, wall]), Agents.empty())
    behind = (slice(130, 140), slice(95, 105), slice(3, 8))  # x 12..16 m, y -2..2 m, z 0.2..2.2 m
    before = (slice(110, 115), slice(95, 105), slice(5, 8))  # x 4..6 m, 1.0..2.2 m up
    for mask in (occupancy.mask_lidar, occupancy.mask_camera):
        assert not mask[behind].any()
        assert mask[before].all()
    assert np.all(occupancy.semantics_native[before] == FREE_NATIVE)
    # the wall's voxels that face the sensors are observed, the air above the wall beyond it too
    assert occupancy.mask_lidar[120, 100, 3:8].all()
    assert occupancy.mask_lidar[:, :, :].sum() > occupancy.mask_lidar[behind].size


def test_car_at_10_mps_has_voxel_flow_10_mps_and_its_points_move_10_mps_times_the_sweep_period():
    occupancy, lidars = frame(GROUND, car(12.0, 0.0, speed_mps=10.0), camera=False)
    cars = occupancy.semantics_native == SemanticClass.CAR
    assert np.allclose(occupancy.flow_mps[cars], [10.0, 0.0, 0.0])
    assert np.allclose(occupancy.flow_relative_mps[cars], [10.0, 0.0, 0.0])  # the ego stands still
    assert not occupancy.flow_mps[~cars].any()
    scan, flow = lidars[0].scan, occupancy.point_flow_m[0]
    on_car = scan.instance_id == 4
    assert on_car.sum() > 50
    period = 1.0 / LidarSpec().rate_hz
    assert np.allclose(flow[on_car], [10.0 * period, 0.0, 0.0], atol=1e-6)
    assert not flow[~on_car].any()


def test_a_turning_ego_sees_a_standing_car_sweep_round_it_and_a_turning_car_s_points_move_along_its_arc():
    """Relative flow takes the ego's turning out: a car standing at 12 m ahead of an ego turning
    left at 0.5 rad/s moves, as the ego sees it, at -omega x r (to the right, faster the farther);
    over the ground it stands. A car turning at 0.8 rad/s: its voxels' flow is its velocity plus its
    turning about its centre, its points move along the arc over a sweep period."""
    ego = replace(EGO, yaw_rate_rad_s=0.5, yaw_rate_after_rad_s=0.5, velocity_map_mps=np.array([5.0, 0.0, 0.0]))
    rate = np.array([0.8])  # before the frame's time and after it
    standing, turning = (
        car(12.0, 0.0),
        replace(car(-12.0, 6.0, speed_mps=8.0), yaw_rate_rad_s=rate, yaw_rate_after_rad_s=rate),
    )
    for agents in (standing, turning):
        scene = FrameScene(GROUND, agents)
        lidars = (Lidar(LidarSpec()).sense(scene, ego, DAY, np.random.default_rng(0)),)
        occupancy = occupancy_frame(SPEC, GROUND, Solids(GROUND), agents, ego.map_SE3_ego(), ego.velocity_map_mps,
                                    lidars, ego_yaw_rate_rad_s=ego.turn_rates()[1])  # fmt: skip
        cars = np.flatnonzero(occupancy.semantics_native.ravel() == SemanticClass.CAR)
        assert cars.size > 50
        centre = SPEC.grid.centers_m(cars)
        flow, relative = occupancy.flow_mps.reshape(-1, 3)[cars], occupancy.flow_relative_mps.reshape(-1, 3)[cars]
        spin = np.cross([0.0, 0.0, agents.yaw_rate_after_rad_s[0]], centre - agents.center_map_m[0])
        assert np.allclose(flow, agents.velocity_map_mps[0] + spin, atol=1e-5)
        ego_moves = ego.velocity_map_mps + np.cross([0.0, 0.0, 0.5], centre)  # the ego frame's motion at each centre
        assert np.allclose(relative, flow - ego_moves, atol=1e-5)
        scan, point_flow = lidars[0].scan, occupancy.point_flow_m[0]
        on_car = scan.instance_id == 4
        assert on_car.sum() > 50
        period = 1.0 / LidarSpec().rate_hz
        xyz = scan.xyz_lidar_m[on_car].astype(np.float64) + LidarSpec().ego_SE3_sensor.translation
        turn = agents.yaw_rate_after_rad_s[0] * period
        c, s = np.cos(turn), np.sin(turn)
        arm = xyz - agents.center_map_m[0]
        speed = agents.velocity_map_mps[0, 0]
        # the centre runs along the arc of radius speed / rate; the point turns with the body
        shift = speed * period * np.array([1.0, 0.0, 0.0]) if turn == 0 else (
            speed / agents.yaw_rate_after_rad_s[0] * np.array([np.sin(turn), 1.0 - np.cos(turn), 0.0]))  # fmt: skip
        moved = shift + np.stack([c * arm[:, 0] - s * arm[:, 1], s * arm[:, 0] + c * arm[:, 1], arm[:, 2]], axis=1)
        assert np.allclose(point_flow[on_car], moved - arm, atol=1e-5)
    assert np.abs(relative[:, 1]).max() > 0.5  # turning shows as sideways flow


@pytest.mark.parametrize("reference", ["start", "middle", "end"])
def test_a_timed_sweeps_point_flow_carries_each_point_from_its_own_time(reference):
    """In a timed sweep every point is where its surface was at the point's time ``t``, in the
    LiDAR frame of that time: its flow takes that surface point to where its box carries it by
    ``t`` plus the period (ego and car both moving and turning; the car's rate changes at the
    frame's time), so in the body's own frame the point and the point plus its flow coincide."""
    ego = replace(EGO, velocity_map_mps=np.array([10.0, 0.0, 0.0]), yaw_rate_rad_s=0.3, yaw_rate_after_rad_s=0.5)
    agents = replace(
        car(-10.0, 6.0, speed_mps=8.0), yaw_rate_rad_s=np.array([0.6]), yaw_rate_after_rad_s=np.array([0.9])
    )
    spec = LidarSpec(rate_hz=10.0, sweep="timed", reference=reference)  # type: ignore[arg-type]
    lidar = Lidar(spec).sense(FrameScene(GROUND, agents), ego, DAY, np.random.default_rng(0))
    occupancy = occupancy_frame(SPEC, GROUND, Solids(GROUND), agents, ego.map_SE3_ego(), ego.velocity_map_mps,
                                (lidar,), ego_yaw_rate_rad_s=0.5, ego=ego)  # fmt: skip
    scan, flow = lidar.scan, occupancy.point_flow_m[0].astype(np.float64)
    on_car = np.flatnonzero(scan.instance_id == 4)
    assert on_car.size > 50
    period, t_ref = 1.0 / spec.rate_hz, reference_s(reference, spec.period_s)
    map_SE3_lidar = ego.map_SE3_ego().compose(spec.ego_SE3_sensor)

    def body_frame(k, xyz_lidar, dt):  # a point of the LiDAR frame at the k-th point's time, in the car's frame at dt
        lidar_then = sensor_pose_at(ego, map_SE3_lidar, float(scan.t_s[k]) - t_ref)
        rate = agents.yaw_rate_rad_s[0] if dt < 0 else agents.yaw_rate_after_rad_s[0]
        shift, turn = motion_over(agents.velocity_map_mps[0], rate, dt)
        c, s = np.cos(agents.yaw_map_rad[0] + turn), np.sin(agents.yaw_map_rad[0] + turn)
        d = lidar_then.transform_from(xyz_lidar[None, :])[0] - (agents.center_map_m[0] + shift)
        return np.array([c * d[0] + s * d[1], -s * d[0] + c * d[1], d[2]])

    xyz = scan.xyz_lidar_m.astype(np.float64)
    worst = 0.0
    for k in on_car:
        dt = float(scan.t_s[k]) - t_ref
        here, there = body_frame(k, xyz[k], dt), body_frame(k, xyz[k] + flow[k], dt + period)
        assert np.all(np.abs(here) <= agents.lwh_m[0] / 2 + 0.02)  # the point on its body at its time
        worst = max(worst, float(np.abs(here - there).max()))
    assert worst < 1e-4
    # taken at the frame's time instead, the flow is millimetres to centimetres off
    at_frame_time = occupancy_frame(SPEC, GROUND, Solids(GROUND), agents, ego.map_SE3_ego(), ego.velocity_map_mps,
                                    (lidar,), ego_yaw_rate_rad_s=0.5).point_flow_m[0]  # fmt: skip
    assert np.abs(at_frame_time[on_car] - flow[on_car]).max() > 0.004


def test_occupancy_is_written_per_frame_and_read_back(tmp_path):
    occupancy, lidars = frame(GROUND, car(12.0, 0.0, speed_mps=10.0), camera=False)
    agents = car(12.0, 0.0, speed_mps=10.0)
    labels = label_frame(3, 150_000_000, agents, EGO, lidars, FrameScene(GROUND, agents), 120.0)
    record = FrameRecord(3, 150_000_000, SE3.identity(), lidars, labels, occupancy=occupancy)
    choice = SinkChoice(tmp_path, mcap=False, csv=False, kitti=False, yolo=False, occupancy=True)
    with SinkGroup.open(choice) as sinks:
        sinks.write(record)
    data = load_occupancy(tmp_path, 3)
    assert data["semantics"].shape == (200, 200, 16) and data["semantics"].dtype == np.uint8
    assert np.array_equal(data["semantics"], occupancy.semantics)
    assert np.array_equal(data["mask_lidar"], occupancy.mask_lidar)
    assert data["mask_camera"].dtype == np.bool_
    assert np.array_equal(data["flow"], occupancy.flow_mps)
    assert data["range_m"].tolist() == [-40.0, -40.0, -1.0, 40.0, 40.0, 5.4]
    assert (tmp_path / "occupancy" / "classes.json").exists()


@pytest.mark.parametrize("setting", ["voxel_m=0.3", "range_m=[-40,-40,-1,40,40]", "voxel_m=0.01"])
def test_bad_occupancy_grid_is_one_line_naming_the_key(setting):
    from cosim.errors import ScenarioError
    from cosim.scenario import load_scenario

    with pytest.raises(ScenarioError, match=r"outputs\.occupancy"):
        load_scenario("town05_crowded", [f"outputs.occupancy.{setting}"])


def test_presets_have_the_layouts_of_occ3d_and_openoccupancy():
    from cosim.scenario import OccupancyConfig

    assert OccupancyConfig().grid.grid.shape == (200, 200, 16)
    assert OccupancyConfig(preset="openoccupancy").grid.grid.shape == (512, 512, 40)


def test_mcap_has_the_occupancy_cubes_and_each_points_flow(tmp_path):
    from gtgen.load import iter_messages, lidar_points

    agents = car(12.0, 0.0, speed_mps=10.0)
    occupancy, lidars = frame(GROUND, agents, camera=False)
    labels = label_frame(0, 0, agents, EGO, lidars, FrameScene(GROUND, agents), 120.0)
    record = FrameRecord(0, 0, SE3.identity(), lidars, labels, occupancy=occupancy)
    choice = SinkChoice(tmp_path, mcap=True, csv=False, kitti=False, yolo=False, occupancy=True)
    with SinkGroup.open(choice) as sinks:
        sinks.write(record)
    messages = {topic: m for topic, _, m in iter_messages(tmp_path / "run.mcap", ["/occupancy", "/lidar"])}
    cubes = messages["/occupancy"].entities[0].cubes
    shown = (occupancy.semantics_native != FREE_NATIVE) & (occupancy.mask_lidar | occupancy.mask_camera)
    assert 0 < len(cubes) < shown.sum()  # runs along x are one cube each
    assert sum(round(c.size.x / 0.4) for c in cubes) == shown.sum()
    assert all(c.size.y == pytest.approx(0.4) and c.size.z == pytest.approx(0.4) for c in cubes)
    # the voxels the cubes cover are the shown ones, by class
    covered = np.full(occupancy.semantics_native.shape, FREE_NATIVE, np.uint8)
    rgb = {(round(c.color.r, 3), round(c.color.g, 3), round(c.color.b, 3)) for c in cubes}
    assert len(rgb) == len(np.unique(occupancy.semantics_native[shown]))
    for c in cubes:
        n = round(c.size.x / 0.4)
        i0 = round((c.pose.position.x - c.size.x / 2 + 40.0) / 0.4)
        j, k = int((c.pose.position.y + 40.0) // 0.4), int((c.pose.position.z + 1.0) // 0.4)
        covered[i0 : i0 + n, j, k] = 1
    assert np.array_equal(covered == 1, shown)
    layout = (tmp_path / "foxglove_layout.json").read_text()
    assert '"/occupancy"' in layout
    points = lidar_points(messages["/lidar"])
    on_car = points["instance"] == 4
    assert np.allclose(points["flow_x"][on_car], 0.5) and not points["flow_x"][~on_car].any()


def test_the_planned_topics_name_the_deskewed_cloud_and_the_occupancy_in_write_order():
    agents = car(12.0, 0.0, speed_mps=10.0)
    scene = FrameScene(GROUND, agents)
    lidar = Lidar(LidarSpec(deskew=True)).sense(scene, EGO, DAY, np.random.default_rng(0))
    occupancy, _ = frame(GROUND, agents, camera=False)
    record = FrameRecord(
        0, 0, SE3.identity(), (lidar,), label_frame(0, 0, agents, EGO, (lidar,), scene, 120.0), occupancy=occupancy
    )
    messages = frame_messages(record, FrameImages(()))
    written = [(topic, None if isinstance(m, dict) else type(m)) for topic, m in messages]
    rig = ((SensorKind.LIDAR, "lidar"),)
    assert planned_topics(rig, with_map=False, deskewed=("lidar",), with_occupancy=True) == written
    assert {"/lidar/deskewed", "/occupancy"} <= {topic for topic, _ in written}


def test_nuscenes_export_gets_occ3d_annotations_finding_each_keyframe_by_its_sample_token(records, tmp_path):
    import json
    from dataclasses import replace

    from gtgen.occ3d_export import write_occ3d_annotations
    from gtgen.sinks.nuscenes_sink import NuscenesSetup

    setup = NuscenesSetup(
        "run", 0.25, (("lidar", "lidar", 4.0), ("camera", "camera", 4.0), ("radar", "radar", 4.0)), "skeleton"
    )
    occupancy, _ = frame(GROUND, car(12.0, 0.0), lidar=False, camera=False)
    out = tmp_path / "run"
    out.mkdir()
    choice = SinkChoice(out, mcap=False, csv=False, kitti=False, yolo=False, nuscenes=setup, occupancy=True)
    with SinkGroup.open(choice) as sinks:
        for record in records:  # keyframes at frames 0 and 2
            sinks.write(replace(record, occupancy=replace(occupancy, point_flow_m=())))
    path = write_occ3d_annotations(out, "run")
    assert path == out / "nuscenes" / "annotations.json"
    annotations = json.loads(path.read_text())
    samples = {s["token"]: s for s in json.loads((out / "nuscenes" / "v1.0-trainval" / "sample.json").read_text())}
    frames = {t: f for info in annotations["scene_infos"].values() for t, f in info.items()}
    assert set(frames) == set(samples)
    for sample_token, info in frames.items():
        assert info["timestamp"] == samples[sample_token]["timestamp"]
        assert info["gt_path"].endswith(f"/{sample_token}/labels.npz")
        gt = np.load(out / "nuscenes" / info["gt_path"])
        assert np.array_equal(gt["semantics"], occupancy.semantics)
        (camera,) = info["camera_sensor"].values()  # the rig's one camera
        assert np.asarray(camera["intrinsic"]).shape == (3, 3) and len(camera["extrinsic"]["rotation"]) == 4
        assert (out / "nuscenes" / camera["img_path"]).exists()
    assert sorted(annotations["train_split"] + annotations["val_split"] + annotations["test_split"]) == sorted(
        annotations["scene_infos"]
    )


def test_a_car_fills_the_voxels_of_its_body_within_its_box_and_the_lidar_crosses_only_free_or_surface_voxels():
    from gtgen.voxels import segment_voxels, triangle_voxels

    wall = prism(rect(20.0, -8.0, 20.4, 8.0), -0.05, 4.0, SemanticClass.BUILDING)
    static = merge([GROUND, wall])
    agents = car(9.1, 3.1)  # its faces off the voxels' faces
    occupancy, lidars = frame(static, agents, camera=False, with_meshes=True)
    grid = SPEC.grid
    box, _ = box_voxels(grid, np.array([[9.1, 3.1, 0.75]]), box_rotations([0.0], [0.0]), np.array([[4.4, 1.8, 1.5]]))
    cars = np.flatnonzero(occupancy.semantics_native.ravel() == SemanticClass.CAR)
    assert set(cars.tolist()) < set(box.tolist())  # the body, not all its box (air over the bonnet, under the sills)
    assert len(cars) > 0.5 * len(box)
    scan = lidars[0].scan
    xyz = LidarSpec().ego_SE3_sensor.transform_from(scan.xyz_lidar_m.astype(np.float64))
    ijk = grid.ijk_of(xyz)
    ok = grid.inside(ijk)
    on_car = ok & (scan.instance_id == 4)
    in_car = occupancy.semantics_native[tuple(ijk[on_car].T)] == SemanticClass.CAR
    assert in_car.mean() > 0.9
    # the rest (the tyres' lowest 20 cm, in the road's voxels): a car voxel right above, within half a voxel
    low = xyz[on_car][~in_car]
    assert np.all(low[:, 2] < 0.2 + 1e-6)
    above = grid.ijk_of(low + np.array([0.0, 0.0, grid.voxel_m / 2.0]))
    assert np.all(occupancy.semantics_native[tuple(above.T)] == SemanticClass.CAR)
    # every voxel a ray crossed before the voxel of its return is free, or holds a surface the ray passed by
    meshes = FrameScene(static, agents).agent_meshes
    tris = np.concatenate([static.vertices_m[static.triangles], meshes.vertices_m[meshes.triangles]]).astype(float)
    surface = np.zeros(grid.size, np.bool_)
    surface[triangle_voxels(grid, tris)[0]] = True
    origin = LidarSpec().ego_SE3_sensor.translation
    end_voxel = grid.flat(np.clip(ijk, 0, np.asarray(grid.shape) - 1))
    occupied = occupancy.semantics_native.ravel() != FREE_NATIVE
    for i in range(0, len(xyz), 97):  # every 97th ray
        crossed = np.unique(segment_voxels(grid, origin[None], xyz[i : i + 1]))
        before = crossed[crossed != end_voxel[i]]
        assert np.all(~occupied[before] | surface[before])


def test_a_timed_sweep_from_a_moving_ego_puts_every_static_return_in_an_occupied_observed_voxel():
    wall = prism(rect(15.1, -6.1, 15.5, 6.1), -0.05, 4.0, SemanticClass.BUILDING)
    static = merge([GROUND, wall])
    ego = EgoState(EGO.center_map_m, EGO.lwh_m, 0.0, 0.0, np.array([15.0, 0.0, 0.0]))
    scene = FrameScene(static, Agents.empty())
    spec = LidarSpec(sweep="timed")
    lidar = Lidar(spec).sense(scene, ego, DAY, np.random.default_rng(0))
    assert np.ptp(lidar.scan.t_s) > 0.04
    occupancy = occupancy_frame(
        SPEC, static, Solids(static), Agents.empty(), ego.map_SE3_ego(), ego.velocity_map_mps, (lidar,)
    )
    from gtgen.occupancy import lidar_segments

    _, ends = lidar_segments(lidar, ego.velocity_map_mps)
    ijk = SPEC.grid.ijk_of(ends)
    on_wall = SPEC.grid.inside(ijk) & (lidar.scan.semantic_class == SemanticClass.BUILDING)
    assert on_wall.sum() > 500
    assert np.all(occupancy.semantics_native[tuple(ijk[on_wall].T)] != FREE_NATIVE)
    g = SPEC.grid.to_grid(ends[on_wall])
    building = np.zeros(len(g), np.bool_)  # a building voxel within half a voxel (the wall's foot shares the road's)
    for offset in np.ndindex(3, 3, 3):
        q = np.clip(np.floor(g + (np.asarray(offset) - 1) * 0.5).astype(int), 0, np.asarray(SPEC.grid.shape) - 1)
        building |= occupancy.semantics_native[tuple(q.T)] == SemanticClass.BUILDING
    assert building.all()
    assert np.all(occupancy.mask_lidar[tuple(ijk[on_wall].T)])
    # the correction matters: the sensor moved up to 15 m/s x 0.025 s = 0.375 m from the frame's place
    raw = spec.ego_SE3_sensor.transform_from(lidar.scan.xyz_lidar_m.astype(float))
    assert np.abs(ends - raw)[:, 0].max() > 0.3


@pytest.mark.parametrize("hfov_deg", [85.0, 120.0])
def test_the_cameras_distances_read_from_its_depth_are_those_of_casting_its_grid_rays(hfov_deg):
    """The camera mask's rays are the camera's own rays of every few pixels: their distances read
    from the frame's depth image are those of casting the same rays into the frame's scene
    (a wall, a car, the road, open sky beyond the camera's range), and they sample the image
    one voxel apart at the grid's farthest corner, to the nearest pixel."""
    wall = prism(rect(30, -12, 31, 12), 0.0, 6.0, SemanticClass.BUILDING)
    static = merge([GROUND, wall])
    agents = car(12.0, 1.0)
    scene = FrameScene(static, agents)
    spec = CameraSpec(shading="flat", hfov_deg=hfov_deg, range_m=60.0)
    depth = Camera(spec).sense(scene, EGO, DAY, np.random.default_rng(0)).frame.depth_m
    read = camera_distances_m(SPEC, spec, depth)
    cast = scene.cast(camera_rays(SPEC, spec, EGO.map_SE3_ego())).range_m.astype(np.float64)
    cast[cast > spec.range_m] = np.inf  # the camera's depth holds nothing beyond its range
    assert np.array_equal(np.isinf(read), np.isinf(cast)) and np.isinf(read).sum() > 100
    hit = np.isfinite(cast)
    assert np.allclose(read[hit], cast[hit], rtol=1e-5, atol=1e-5)
    pixels = camera_pixels(SPEC, spec)
    u = np.unique(pixels % spec.width_px)
    v = np.unique(pixels // spec.width_px)
    assert pixels.shape[0] == u.shape[0] * v.shape[0] and len(np.unique(pixels)) == pixels.shape[0]
    corners = np.stack(np.meshgrid(*zip(SPEC.range_m[:3], SPEC.range_m[3:], strict=True)), -1).reshape(-1, 3)
    far_m = float(np.linalg.norm(corners - np.asarray(spec.mount_xyz_m), axis=1).max())
    for gaps in (np.diff(u), np.diff(v)):
        assert gaps.max() - gaps.min() <= 1
        pixel_m = far_m / spec.pinhole.focal_px  # a pixel's width there
        assert (gaps.max() - 1) * pixel_m <= SPEC.voxel_m < (gaps.min() + 1) * pixel_m  # a voxel apart, to a pixel


@pytest.mark.parametrize(("preset", "pitch_deg"), [("occ3d", 0.0), ("occ3d", 12.0), ("openoccupancy", 5.0)])
def test_the_cameras_walks_made_once_mark_what_each_frames_walks_mark(preset, pitch_deg):
    """The camera's grid-resolution rays are fixed on the ego: their walks over the whole range,
    made once and cut at each ray's distance, mark the voxels that walking each ray as far as it
    travelled marks (distances anywhere, on voxel faces as float32 casts give them, 0, beyond the
    grid and none)."""
    from gtgen import voxel_kernels
    from gtgen.occupancy import _camera_walks, camera_directions, camera_reach_m, camera_segments
    from gtgen.voxels import PRESETS, walk_voxels

    spec = PRESETS[preset]
    grid = spec.grid
    small = {"width_px": 480, "height_px": 160} if preset == "openoccupancy" else {}  # fewer rays on the fine grid
    camera = CameraSpec(shading="flat", mount_rpy_deg=(0.0, pitch_deg, 20.0), **small)
    rng = np.random.default_rng(5)
    count = camera_directions(spec, camera).shape[0]
    starts, ends = camera_segments(spec, camera, np.ones(count))  # ends: the unit directions from the mount
    direction = ends - starts
    face = grid.lower_m[0] + grid.voxel_m * rng.integers(np.ceil(grid.to_grid(starts[:1])[0, 0]), grid.shape[0], count)
    on_face = np.where(direction[:, 0] > 0.05, (face - starts[:, 0]) / direction[:, 0], 10.0).astype(np.float32)
    for distance in (
        rng.uniform(0.0, 60.0, count),
        on_face.astype(np.float64),
        np.where(rng.random(count) < 0.3, np.inf, rng.exponential(8.0, count)),
        np.zeros(count),
    ):
        walked = np.zeros(grid.size, np.bool_)
        walk_voxels(grid, *camera_segments(spec, camera, distance), walked)
        cut = np.zeros(grid.size, np.bool_)
        voxel_kernels.mark_walked(*_camera_walks(spec, camera), camera_reach_m(camera, distance), cut)
        assert walked.sum() > 0
        assert np.array_equal(cut, walked)
