"""The fast ray engine agrees with the reference on a town: every ray's hit or miss, its
distance within 0.1 mm, its object for at least 99.9 % of rays (ties where faces meet)."""

import sys

import numpy as np
import pytest

from networks.classes import AGENT_CLASSES
from networks.convert import import_opendrive
from networks.geometry import SE3
from networks.towns import town_opendrive
from networks.world import build_world
from sensors.agents import Agents, EgoState
from sensors.camera import Camera, CameraSpec
from sensors.engine import open_engine
from sensors.lidar import Lidar, LidarSpec
from sensors.scene import StaticCrop

try:
    from sensors.mitsuba_engine import MitsubaEngine
except (ImportError, RuntimeError, OSError) as err:  # the machine cannot run it: say why
    pytest.skip(f"the Mitsuba engine cannot start here: {err}", allow_module_level=True)


@pytest.fixture(scope="module")
def town():
    world = build_world(import_opendrive(town_opendrive("skeleton")))
    xmin, ymin, xmax, ymax = world.bounds_m
    rng = np.random.default_rng(4)
    n = 150
    center = np.column_stack([rng.uniform(xmin, xmax, n), rng.uniform(ymin, ymax, n), np.full(n, 0.8)])
    classes = rng.choice([int(c) for c in AGENT_CLASSES], n)
    agents = Agents.standing(np.arange(1, n + 1), classes, center, rng.uniform([1, 0.5, 1.5], [8, 2.5, 3], (n, 3)),
                             rng.uniform(-np.pi, np.pi, n))  # fmt: skip
    ego = EgoState.at(SE3.from_xyz_rpy([(xmin + xmax) / 2, (ymin + ymax) / 2, 0.0], yaw=0.7))
    return StaticCrop(world.mesh, 200.0).around(ego.map_SE3_ego().translation), agents, ego


def test_both_engines_give_the_same_hits(town):
    static, agents, ego = town
    reference, fast = open_engine("open3d")[0].scene(static, agents), MitsubaEngine().scene(static, agents)
    camera, lidar = Camera(CameraSpec(width_px=640, height_px=360)), Lidar(LidarSpec())
    map_SE3_cam = ego.map_SE3_ego().compose(camera.spec.ego_SE3_sensor)
    pairs = [(reference.cast(lidar.rays(ego.map_SE3_ego())), fast.cast(lidar.rays(ego.map_SE3_ego())))]
    pairs.append(
        tuple(s.cast_from(map_SE3_cam.translation, map_SE3_cam.rotation, camera._dirs_cam) for s in (reference, fast))
    )
    for a, b in pairs:
        np.testing.assert_array_equal(a.hit, b.hit)
        both = a.hit & b.hit
        assert np.abs(a.range_m[both] - b.range_m[both]).max() < 1e-4
        assert (a.instance_id == b.instance_id).mean() >= 0.999 and (
            a.semantic_class == b.semantic_class
        ).mean() >= 0.999
        assert (a.instance_id > 0).sum() > 50  # agents are in view
        same = both & (a.instance_id == b.instance_id)
        assert np.abs(np.abs(np.einsum("ij,ij->i", a.normal[same], b.normal[same])) - 1.0).max() < 1e-3


def test_occlusion_queries_agree_with_the_nearest_hit(town):
    # shadow rays from the camera's hits towards the sun: some blocked, some free
    static, agents, ego = town
    camera = Camera(CameraSpec(width_px=320, height_px=180))
    sun = np.array([0.5, 0.3, 0.4]) / np.linalg.norm([0.5, 0.3, 0.4])
    for scene in (open_engine("open3d")[0].scene(static, agents), MitsubaEngine().scene(static, agents)):
        hits = scene.cast(camera.rays(ego.map_SE3_ego()))
        rays = camera.rays(ego.map_SE3_ego())[hits.hit]
        rays[:, :3] += rays[:, 3:] * (hits.range_m[hits.hit, None] - 0.05)
        rays[:, 3:] = sun
        blocked = scene.occluded(rays)
        np.testing.assert_array_equal(blocked, np.isfinite(scene.cast(rays).range_m))
        assert 0 < blocked.sum() < len(blocked)  # both kinds of ray are there


def test_both_engines_give_the_same_timed_sweep(town):
    static, agents, ego = town
    moving = Agents(agents.instance_id, agents.semantic_class, agents.center_map_m, agents.lwh_m, agents.yaw_map_rad,
                    agents.pitch_rad, np.random.default_rng(5).uniform(-15, 15, (len(agents), 3)) * [1, 1, 0],
                    agents.parked)  # fmt: skip
    driving = EgoState(ego.center_map_m, ego.lwh_m, ego.yaw_map_rad, 0.0, np.array([12.0, 4.0, 0.0]))
    lidar = Lidar(LidarSpec(sweep="timed"))
    (_, a), (_, b) = (
        lidar.cast(s, driving)
        for s in (open_engine("open3d")[0].scene(static, moving), MitsubaEngine().scene(static, moving))
    )
    np.testing.assert_array_equal(a.hit, b.hit)
    both = a.hit & b.hit
    assert np.abs(a.range_m[both] - b.range_m[both]).max() < 1e-4
    assert (a.instance_id == b.instance_id).mean() >= 0.999 and (a.instance_id > 0).sum() > 100


def test_auto_falls_back_to_open3d_with_one_line_when_the_fast_engine_cannot_start(monkeypatch):
    monkeypatch.setitem(sys.modules, "sensors.mitsuba_engine", None)  # its import fails, as without LLVM
    engine, notice = open_engine("auto")
    assert engine.name == "open3d"
    assert notice.startswith("note: the fast ray engine (Mitsuba) cannot start here (") and "\n" not in notice
    from sensors.errors import SensorConfigError

    with pytest.raises(SensorConfigError, match="engine mitsuba cannot start here"):
        open_engine("mitsuba")


def test_face_normals_are_numpys_bit_for_bit(town):
    from sensors.agents import agent_meshes
    from sensors.mitsuba_engine import _face_normals

    static, agents, _ = town
    meshes = agent_meshes(agents)
    triangles = np.concatenate([meshes.triangles, [[0, 0, 1]]])  # one degenerate: a zero normal
    for vertices, tris in ((static.vertices_m, static.triangles), (meshes.vertices_m, triangles)):
        v = vertices.astype(np.float32)
        n = np.cross(v[tris[:, 1]] - v[tris[:, 0]], v[tris[:, 2]] - v[tris[:, 0]])
        length = np.linalg.norm(n, axis=1, keepdims=True)
        want = np.asarray(n / np.where(length > 0, length, 1.0), np.float32)
        got = _face_normals(vertices, tris)
        np.testing.assert_array_equal(got.view(np.uint32), want.view(np.uint32))
    assert not _face_normals(meshes.vertices_m, triangles)[-1].any()


def test_rays_given_as_rows_or_as_columns_give_the_same_hits(town):
    static, agents, ego = town
    scene = MitsubaEngine().scene(static, agents)
    rays = Camera(CameraSpec(width_px=96, height_px=64)).rays(ego.map_SE3_ego())
    rows, columns = scene.cast(rays), scene.cast(np.asfortranarray(rays))
    assert rows.hit.any() and (rows.instance_id > 0).any()
    for a, b in zip(rows.__dataclass_fields__, columns.__dataclass_fields__, strict=True):
        np.testing.assert_array_equal(getattr(rows, a), getattr(columns, b))
    np.testing.assert_array_equal(scene.occluded(rays), scene.occluded(np.asfortranarray(rays)))


def test_a_hits_class_instance_part_and_normal_come_from_its_row_or_its_agents_template(town):
    from sensors.agents import template_of
    from sensors.mitsuba_engine import NO_SLOT, _rows_of, _template_key

    static, agents, _ = town
    scene = MitsubaEngine().scene(static, agents)
    inst = scene._instances
    rng = np.random.default_rng(2)
    n = 20_000
    slots = rng.integers(0, inst.agent_of_slot.shape[0], n).astype(np.uint32)
    slots[inst.agent_of_slot[slots] < 0] = NO_SLOT  # an empty slot: no ray meets it
    slots[rng.random(n) < 0.3] = NO_SLOT  # the static world, or nothing
    held = slots != NO_SLOT
    templates = {s: template_of(*_template_key(k)) for s, k in enumerate(k for k, c in inst.layout for _ in range(c))}
    rows = rng.integers(0, scene._nothing_row + 1, n).astype(np.uint32)
    rows[held] = [rng.integers(0, templates[s].triangles.shape[0]) for s in slots[held].tolist()]
    cls, instance, part, normal_bits = _rows_of(
        rows, slots, scene._class_of_row, scene._normal_of_row, inst.slot_class, inst.slot_instance, inst.slot_first,
        inst.slot_turn, inst.part, inst.normal,
    )  # fmt: skip
    np.testing.assert_array_equal(cls[~held], scene._class_of_row[rows[~held]])
    np.testing.assert_array_equal(normal_bits[~held], scene._normal_of_row[rows[~held]])
    assert not instance[~held].any() and not part[~held].any()
    a = inst.agent_of_slot[slots[held]]
    np.testing.assert_array_equal(cls[held], agents.semantic_class[a])
    np.testing.assert_array_equal(instance[held], agents.instance_id[a])
    want_part = [templates[s].triangle_part[r] for s, r in zip(slots[held].tolist(), rows[held].tolist(), strict=True)]
    np.testing.assert_array_equal(part[held], want_part)
    # the normal: the posed triangle's (float64), within float32's rounding
    posed = []
    rotations, lwh = agents.rotations(), agents.lwh_m - [0.0, 0.0, 0.03]
    for s, r, k in zip(slots[held].tolist(), rows[held].tolist(), a.tolist(), strict=True):
        v = templates[s].unit_vertices[templates[s].triangles[r]] * lwh[k] @ rotations[k].T
        c = np.cross(v[1] - v[0], v[2] - v[0])
        posed.append(c / np.linalg.norm(c))
    assert np.abs(normal_bits[held].view(np.float32) - np.array(posed)).max() < 1e-6


def test_map_directions_are_cv2s_and_follow_the_rotation():
    import cv2

    from sensors.rays import map_directions

    dirs = Camera(CameraSpec(width_px=40, height_px=30)).spec.pinhole.image_directions()
    for yaw in (0.3, 0.3, 1.1):
        rotation = SE3.from_xyz_rpy([0.0, 0.0, 0.0], 0.1, 0.2, yaw).rotation
        want = cv2.transform(dirs.reshape(-1, 1, 3), rotation.astype(np.float32)).reshape(-1, 3)
        got = map_directions(rotation, dirs)
        np.testing.assert_array_equal(got.view(np.uint32), want.view(np.uint32))
        assert not got.flags.writeable
    assert map_directions(rotation, dirs) is got and map_directions(rotation, dirs.copy()) is not got


def _same_hits(a, b):
    for name in ("range_m", "semantic_class", "instance_id", "normal", "part"):
        np.testing.assert_array_equal(getattr(a, name).view(np.uint8), getattr(b, name).view(np.uint8))


def _moves(agents):
    """Eight frames of ``agents``: as given, a third moved, another third moved, all standing, one
    moved, all standing, half of them left, all back with a third of them walkers."""
    import dataclasses

    frames = [agents]
    for step in range(1, 6):
        centre = frames[-1].center_map_m.copy()
        if step < 3:
            centre[step::3, 0] += 0.25
        elif step == 4:
            centre[0, 1] += 0.5
        frames.append(dataclasses.replace(agents, center_map_m=centre))
    frames.append(frames[-1].select(np.arange(len(agents)) % 2 == 0))
    walkers = frames[-2].semantic_class.copy()
    walkers[::3] = 15
    frames.append(dataclasses.replace(frames[-2], semantic_class=walkers))
    return frames


def test_an_agents_hits_do_not_depend_on_the_frames_before(town):
    static, agents, ego = town
    rays = Lidar(LidarSpec()).rays(ego.map_SE3_ego())
    sun = rays.copy()
    sun[:, 3:] = np.array([0.3, 0.2, 0.93], np.float32) / np.linalg.norm([0.3, 0.2, 0.93])
    engine = MitsubaEngine()
    for frame in _moves(agents):
        scene, fresh = engine.scene(static, frame), MitsubaEngine().scene(static, frame)
        _same_hits(scene.cast(rays), fresh.cast(rays))
        np.testing.assert_array_equal(scene.occluded(sun), fresh.occluded(sun))
        np.testing.assert_array_equal(scene.cast_raw(rays), fresh.cast_raw(rays))
    held = engine.instances.agent_of_slot
    assert (held < 0).sum() > len(agents) // 3  # the agents that left hold no instance


def test_an_engine_restored_from_a_checkpoint_lays_out_the_agents_as_the_engine_that_ran_on(town):
    import json

    static, agents, ego = town
    rays = Lidar(LidarSpec()).rays(ego.map_SE3_ego())
    frames = _moves(agents)

    def layout(scene):
        return scene._instances.layout, scene._instances.agent_of_slot.tobytes()

    engine = MitsubaEngine()
    ran_on, states = [], []
    for frame in frames:
        scene = engine.scene(static, frame)
        ran_on.append((layout(scene), scene.cast(rays)))
        states.append(json.loads(json.dumps(engine.checkpoint())))
    differs = 0
    for k in range(len(frames) - 1):
        restored, fresh = MitsubaEngine(), MitsubaEngine()
        restored.restore(states[k])
        for frame, (want_layout, want_hits) in zip(frames[k + 1 :], ran_on[k + 1 :], strict=True):
            scene = restored.scene(static, frame)
            assert layout(scene) == want_layout
            _same_hits(scene.cast(rays), want_hits)
            differs += layout(fresh.scene(static, frame)) != want_layout
    assert differs > 0  # without the checkpoint the layout is another
    assert MitsubaEngine().checkpoint() == {"slots": []}


def test_silhouettes_cast_in_the_templates_agree_with_the_posed_meshes(town):
    """The fast engine casts each agent's silhouette in its template's unit mesh; the reference
    casts the agent's posed mesh: the same rays hit (a ray grazing an edge may differ)."""
    static, agents, ego = town
    reference, fast = open_engine("open3d")[0].scene(static, agents), MitsubaEngine().scene(static, agents)
    rng = np.random.default_rng(0)
    origin = ego.map_SE3_ego().translation + np.array([0.0, 0.0, 1.6])
    per = 400  # rays aimed at points in and around each agent's box
    target = agents.center_map_m[:, None, :] + rng.uniform(-0.7, 0.7, (len(agents), per, 3)) * agents.lwh_m[:, None, :]
    d = target.reshape(-1, 3) - origin
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    rays = np.hstack([np.broadcast_to(origin, d.shape), d]).astype(np.float32)
    owner = np.repeat(agents.instance_id, per).astype(np.uint32)
    owner[::97] = 10_000  # no such agent: never hit
    expected, alone = reference.hits_alone(rays, owner), fast.hits_alone(rays, owner)
    assert expected.sum() > 10_000 and not alone[owner == 10_000].any()
    assert (alone != expected).mean() <= 1e-4
