from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from cosim.demand import CHILD, KINDS, PEDESTRIAN
from networks.classes import AGENT_CLASSES, SemanticClass
from networks.geometry import SE3, box_rotations, place_in_boxes
from sensors.agents import AGENT_LIFT_M, Agents, _placed, agent_meshes, body_keys, template_of
from sensors.bodies import (
    BODIES,
    GAIT_PHASES,
    PACES_MPS,
    WALKER_LENGTH_PER_HEIGHT,
    WALKER_POSES,
    body_of,
    foot_pose,
    pedestrian,
    pose_of,
    step_m,
    stride_m,
    walker_length_m,
)
from sensors.lidar import Lidar, LidarSpec
from sensors.parts import Part
from sensors.pinhole import box_corners
from sensors.weather import DAY


def random_agents(n: int, seed: int = 3) -> Agents:
    r = np.random.default_rng(seed)
    cls = r.choice([int(c) for c in AGENT_CLASSES], n)
    lwh = r.uniform([0.3, 0.4, 1.0], [12.0, 2.6, 3.5], (n, 3))
    return Agents(
        np.arange(1, n + 1),
        cls,
        r.uniform(-30, 30, (n, 3)),
        lwh,
        r.uniform(-np.pi, np.pi, n),
        r.uniform(-0.2, 0.2, n),
        np.zeros((n, 3)),
        np.zeros(n, bool),
    )


def corners(agents_: Agents) -> np.ndarray:
    return box_corners(agents_.center_map_m, agents_.lwh_m, agents_.rotations())


def in_box_frame(agents_: Agents, index: int, xyz_map: np.ndarray) -> np.ndarray:
    map_SE3_box = SE3(agents_.rotations()[index], agents_.center_map_m[index])
    return map_SE3_box.inverse().transform_from(xyz_map)


def all_templates() -> list[tuple[str, int, object]]:
    return [
        (b.name, pose, template_of(c, i, pose))
        for c, bodies in BODIES.items()
        for i, b in enumerate(bodies)
        for pose in range(b.poses)
    ]


def test_every_agent_class_has_body_types_inside_the_unit_box_in_every_pose() -> None:
    assert {int(c) for c in AGENT_CLASSES} <= set(BODIES)
    for name, pose, template in all_templates():
        assert np.abs(template.unit_vertices).max() <= 0.5, (name, pose)
        assert template.triangles.shape[0] > 100, name
        assert template.triangle_part.shape == (template.triangles.shape[0],)


def test_body_types_touch_the_ground_and_the_roof_of_their_box() -> None:
    walkers = {b.name for b in BODIES[int(SemanticClass.PEDESTRIAN)]}
    for name, pose, template in all_templates():
        assert template.unit_vertices[:, 2].min() == pytest.approx(-0.5), name
        if name in walkers and pose > 0:  # walking, the hips ride lower while both feet are down
            assert 0.46 <= template.unit_vertices[:, 2].max() <= 0.5, (name, pose)
        else:
            assert template.unit_vertices[:, 2].max() == pytest.approx(0.5), name


def test_vehicles_have_the_parts_detectors_learn() -> None:
    wanted = {Part.GLASS, Part.TYRE, Part.RIM, Part.HEADLAMP, Part.TAIL_LAMP, Part.PLATE}
    for cls in (SemanticClass.CAR, SemanticClass.TRUCK, SemanticClass.BUS):
        for i, body in enumerate(BODIES[int(cls)]):
            parts = {Part(p) for p in np.unique(template_of(int(cls), i, 0).triangle_part)}
            assert wanted <= parts, body.name
    walker = {Part(p) for p in np.unique(template_of(int(SemanticClass.PEDESTRIAN), 0, 1).triangle_part)}
    assert {Part.SKIN, Part.HAIR, Part.TOP, Part.TROUSERS, Part.SHOES} <= walker


def test_a_standing_walker_wears_trousers_as_wide_as_real_ones() -> None:
    # an adult's trouser legs are about 15 cm across at the knee and 12 cm at the hem; a
    # detector finds a person 25-50 px tall by the outline of the legs
    body = pedestrian(None)
    left_leg = body.vertices[np.unique(body.triangles[body.parts == Part.TROUSERS])]
    left_leg = left_leg[left_leg[:, 1] > 0]
    for z_m, across_m in ((0.92 - 0.45, 0.135), (0.07, 0.105)):  # knee, hem
        ring = left_leg[np.abs(left_leg[:, 2] - z_m) < 0.02]
        assert np.ptp(ring[:, 1]) >= across_m, z_m


def test_every_car_shows_a_windscreen_and_a_rear_window_of_glass() -> None:
    """Glass facing forward and up (the windscreen, however far it is raked) and facing back
    (the rear window) on every car body type; the roof is paint."""
    for i, body in enumerate(BODIES[int(SemanticClass.CAR)]):
        t = template_of(int(SemanticClass.CAR), i, 0)
        v = t.unit_vertices[t.triangles] * np.asarray(body.lwh_m)  # (M, 3, 3) in metres
        n = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
        n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
        glass = t.triangle_part == Part.GLASS
        area = 0.5 * np.linalg.norm(np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0]), axis=1)
        ahead = glass & (np.abs(n[:, 0]) > 0.3) & (np.abs(n[:, 2]) > 0.3) & (v[:, :, 0].mean(axis=1) > 0)
        behind = glass & (np.abs(n[:, 0]) > 0.3) & (v[:, :, 0].mean(axis=1) < 0)
        assert area[ahead].sum() > 0.5, (body.name, area[ahead].sum())  # m2 of windscreen
        assert area[behind].sum() > 0.2, (body.name, area[behind].sum())
        roof = (np.abs(n[:, 2]) > 0.99) & (v[:, :, 2].mean(axis=1) > 0.45 * body.lwh_m[2])
        assert area[glass & roof].sum() < 0.02, body.name  # at most the thin edges of a window panel


def test_every_body_type_lies_inside_its_box_over_its_class_size_range() -> None:
    r = np.random.default_rng(5)
    rows = []
    for spec in [*KINDS.values(), PEDESTRIAN]:
        lo = np.array([spec.length_m[0], spec.width_m[0], spec.height_m[0]])
        hi = np.array([spec.length_m[1], spec.width_m[1], spec.height_m[1]])
        for _ in range(40):
            rows.append((int(spec.semantic_class), r.uniform(lo, hi)))
        for body in BODIES.get(int(spec.semantic_class), ()):  # and around each body type's own size
            for _ in range(6):
                rows.append((int(spec.semantic_class), np.asarray(body.lwh_m) * r.uniform(0.95, 1.05, 3)))
    n = len(rows)
    boxes = Agents(np.arange(1, n + 1, dtype=np.uint32), np.array([c for c, _ in rows], np.uint8),
                   r.uniform(-30, 30, (n, 3)), np.array([s for _, s in rows]), r.uniform(-np.pi, np.pi, n),
                   r.uniform(-0.2, 0.2, n), r.uniform(-2, 2, (n, 3)), np.zeros(n, bool))  # fmt: skip
    for c, bodies in BODIES.items():  # every body type of every class is drawn (rare ones among many ids)
        if len(bodies) > 1:
            drawn = {body_of(c, np.asarray(b.lwh_m), k) for b in bodies for k in range(1, 2000)}
            assert drawn == set(range(len(bodies))), c
    meshes = agent_meshes(boxes)
    for i, inst in enumerate(boxes.instance_id):
        vert_ids = np.unique(meshes.triangles[meshes.triangle_instance == inst])
        local = in_box_frame(boxes, i, meshes.vertices_m[vert_ids].astype(np.float64))
        assert np.all(np.abs(local) <= boxes.lwh_m[i] / 2 + 1e-4)


def test_a_walker_is_inside_its_box_at_every_gait_phase_and_pace_and_stands_when_still() -> None:
    # walkers of every height and width the traffic draws (adults and children), in boxes as
    # long as the traffic gives them, at every pace and gait phase, walking along +x
    heights = [*np.linspace(*PEDESTRIAN.height_m, 4), *np.linspace(*CHILD.height_m, 3)]
    widths = [*np.linspace(*PEDESTRIAN.width_m, 4), *np.linspace(*CHILD.width_m, 3)]
    rows = [(h, w, pace, k) for h, w in zip(heights, widths, strict=True) for pace in PACES_MPS
            for k in range(GAIT_PHASES)]  # fmt: skip
    n = len(rows)
    h = np.array([r[0] for r in rows])
    walkers = Agents(
        np.arange(1, n + 1, dtype=np.uint32),
        np.full(n, int(SemanticClass.PEDESTRIAN), np.uint8),
        np.column_stack([np.arange(n) * 3.0, np.zeros(n), h / 2]),
        np.column_stack([walker_length_m(h), [r[1] for r in rows], h]),
        np.zeros(n),
        np.zeros(n),
        np.column_stack([[r[2] for r in rows], np.zeros(n), np.zeros(n)]),
        np.zeros(n, bool),
        gait_cycles=np.array([7 + (r[3] + 0.5) / GAIT_PHASES for r in rows]),
    )
    poses = body_keys(walkers)[:, 2]
    assert sorted(set(poses.tolist())) == list(range(1, WALKER_POSES))  # every pace, every phase
    templates = {template_of(int(SemanticClass.PEDESTRIAN), 0, p).unit_vertices.tobytes() for p in poses}
    assert len(templates) == WALKER_POSES - 1
    meshes = agent_meshes(walkers)
    for i, inst in enumerate(walkers.instance_id):
        vert_ids = np.unique(meshes.triangles[meshes.triangle_instance == inst])
        local = in_box_frame(walkers, i, meshes.vertices_m[vert_ids].astype(np.float64))
        assert np.all(np.abs(local) <= walkers.lwh_m[i] / 2 + 1e-4), rows[i]
    assert pose_of(int(SemanticClass.PEDESTRIAN), 0.05, 3.3) == 0  # standing still: the standing pose
    assert pose_of(int(SemanticClass.PEDESTRIAN), 0.05, 3.3, 1.7, 2.4) == 0


def test_a_walkers_box_holds_its_stride_and_its_body_keeps_its_proportions() -> None:
    # the box's length is the body's reach fore and aft over every gait phase at the fastest
    # pace, so a body scaled into it is neither squashed nor stretched along its heading
    for i, body in enumerate(BODIES[int(SemanticClass.PEDESTRIAN)]):
        pieces = [body.build(p).vertices for p in range(body.poses)]
        lo, hi = np.min([v.min(axis=0) for v in pieces], axis=0), np.max([v.max(axis=0) for v in pieces], axis=0)
        length, height = hi[0] - lo[0], hi[2] - lo[2]
        assert length / height == pytest.approx(WALKER_LENGTH_PER_HEIGHT, abs=0.005), body.name
        assert np.ptp(pieces[0][:, 0]) < 0.35  # standing: feet together, 0.3 m deep
        assert body.lwh_m[0] == pytest.approx(WALKER_LENGTH_PER_HEIGHT * body.lwh_m[2], abs=0.01)
        template = template_of(int(SemanticClass.PEDESTRIAN), i, 0)
        assert np.ptp(template.unit_vertices[:, 0]) < 0.35  # the standing body fills a third of the box
    # real walkers' boxes: nuScenes 0.73 m long on average, KITTI 0.8, Waymo 0.91 (standing ones included)
    assert 0.85 <= float(walker_length_m(1.75)) <= 1.05


def test_a_walkers_feet_keep_their_ground_and_step_as_far_as_its_height_and_speed_take_it() -> None:
    # a foot on the ground moves back under the walker exactly as fast as the walker goes on,
    # so the gait phase from the distance walked leaves no foot sliding; the step (heel to heel
    # at heel strike) is 0.415 x the height at 1.34 m/s and grows as speed^0.42
    for height, speed in ((1.75, 1.34), (1.6, 0.8), (1.2, 1.1), (1.9, 1.4)):
        step = step_m(height, speed)
        s = height / 1.75
        if speed == 1.34 and height == 1.75:
            assert step == pytest.approx(0.726, abs=0.001)
        for u0, u1 in ((0.1, 0.35), (0.42, 0.58)):  # flat foot: the heel; rolling over: the toe
            corner = (-0.06 * s, -0.07 * s) if u0 < 0.4 else (0.16 * s, -0.07 * s)
            points = []
            for u in (u0, u1):
                x, z, pitch = foot_pose(u, step, s)
                c, sn = np.cos(pitch), np.sin(pitch)
                points.append((x + c * corner[0] - sn * corner[1], z + sn * corner[0] + c * corner[1]))
            (xa, za), (xb, zb) = points
            assert za == pytest.approx(0.0, abs=1e-9) and zb == pytest.approx(0.0, abs=1e-9)  # on the ground
            assert xa - xb == pytest.approx(2 * step * (u1 - u0), abs=1e-9)  # back by the distance walked
        front, rear = foot_pose(0.0, step, s)[0], foot_pose(0.5, step, s)[0]  # a heel strikes, the other rolls
        assert abs(front + rear) < 0.03 * s  # the hips midway between the ankles
        assert 0.85 * step < front - rear < step
    assert stride_m(1.75, 1.7) == stride_m(1.75, 1.4)  # faster walkers: the fastest pace's steps
    assert step_m(1.75, 0.8) / step_m(1.75, 1.34) == pytest.approx((0.8 / 1.34) ** 0.42)


def test_a_walkers_legs_follow_the_gait_cycles_it_has_walked() -> None:
    c = int(SemanticClass.PEDESTRIAN)
    at = [pose_of(c, 1.34, 0.0, 1.75, cycles) for cycles in np.arange(16) / GAIT_PHASES + 3.01]
    pace = PACES_MPS.index(1.4)
    assert at == [1 + pace * GAIT_PHASES + k % GAIT_PHASES for k in range(16)]
    # not counted: the phase from the distance along its heading over its stride
    stride = stride_m(1.75, 1.34)
    assert pose_of(c, 1.34, stride * (2 + 3.5 / GAIT_PHASES), 1.75) == 1 + pace * GAIT_PHASES + 3
    slow = stride_m(1.75, 0.8) * 0.5 / GAIT_PHASES
    assert pose_of(c, 0.8, slow, 1.75) == 1 + PACES_MPS.index(0.8) * GAIT_PHASES  # a slower pace, phase 0
    assert pose_of(c, 0.3, 0.0, 1.75, 0.01) == 1  # the slowest pace, phase 0


def test_body_type_fits_the_size_and_is_stable_over_a_track() -> None:
    car = int(SemanticClass.CAR)
    names = [b.name for b in BODIES[car]]
    tall = {names[body_of(car, np.array([4.9, 1.95, 1.95]), i)] for i in range(1, 200)}
    low = {names[body_of(car, np.array([4.6, 1.8, 1.42]), i)] for i in range(1, 200)}
    assert "van" in tall and "sedan" not in tall
    assert "van" not in low and "sedan" in low
    assert all(
        body_of(car, np.array([4.5, 1.8, 1.5]), 42) == body_of(car, np.array([4.5, 1.8, 1.5]), 42) for _ in range(3)
    )
    truck = int(SemanticClass.TRUCK)
    assert BODIES[truck][body_of(truck, np.array([12.0, 2.5, 3.8]), 3)].name == "semi_trailer"


def test_each_triangle_carries_its_agents_instance_and_class() -> None:
    boxes = random_agents(40)
    meshes = agent_meshes(boxes)
    class_of = dict(zip(boxes.instance_id.tolist(), boxes.semantic_class.tolist(), strict=True))
    assert set(meshes.triangle_instance.tolist()) == set(class_of)
    expected = np.array([class_of[i] for i in meshes.triangle_instance.tolist()])
    np.testing.assert_array_equal(meshes.triangle_class, expected)
    keys = body_keys(boxes)
    for (inst, _cls), (c, body, pose) in zip(class_of.items(), keys.tolist(), strict=True):
        assert np.sum(meshes.triangle_instance == inst) == template_of(c, body, pose).triangles.shape[0]


def test_a_class_without_template_is_drawn_as_its_box_standing_just_off_the_road(synth: SimpleNamespace) -> None:
    boxes = synth.agents([(5, SemanticClass.POLE, 1.0, 2.0, 1.0, 2.0, 1.0, 2.0, 0.3)])
    meshes = agent_meshes(boxes)
    assert meshes.triangles.shape == (12, 3)
    expected = corners(boxes)[0]
    expected[:, 2] = np.maximum(expected[:, 2], AGENT_LIFT_M)  # the bottom 3 cm above the box's (the road)
    np.testing.assert_allclose(np.sort(meshes.vertices_m, axis=0), np.sort(expected, axis=0), atol=1e-5)


def numpy_agent_meshes(agents_: Agents) -> tuple[np.ndarray, ...]:
    """The merged mesh posed one body type and pose at a time with numpy (place_in_boxes), the
    triangles put in order of instance id by a stable sort."""
    rotations = agents_.rotations()
    center = agents_.center_map_m + rotations[:, :, 2] * (AGENT_LIFT_M / 2.0)
    lwh = agents_.lwh_m - np.array([0.0, 0.0, AGENT_LIFT_M])
    groups, group_of = np.unique(body_keys(agents_), axis=0, return_inverse=True)
    verts, tris, inst, cls, parts, offset = [], [], [], [], [], 0
    for g, (c, body, pose) in enumerate(groups.tolist()):
        mask = group_of.ravel() == g
        template = template_of(c, body, pose)
        ids = agents_.instance_id[mask]
        n, v, t = len(ids), template.unit_vertices.shape[0], template.triangles.shape[0]
        verts.append(place_in_boxes(template.unit_vertices, center[mask], lwh[mask], rotations[mask]).reshape(-1, 3))
        firsts = offset + v * np.arange(n, dtype=np.int32)[:, None, None]
        tris.append((template.triangles[None] + firsts).reshape(-1, 3))
        inst.append(np.repeat(ids, t))
        cls.append(np.full(n * t, c, np.uint8))
        parts.append(np.tile(template.triangle_part, n))
        offset += n * v
    order = np.argsort(np.concatenate(inst), kind="stable")
    return (np.concatenate(verts).astype(np.float32), np.concatenate(tris).astype(np.int32)[order],
            np.concatenate(inst)[order], np.concatenate(cls)[order], np.concatenate(parts)[order])  # fmt: skip


def test_a_compiled_vertex_is_placed_as_numpy_places_it_to_the_float64_bit() -> None:
    r = np.random.default_rng(5)
    n, v = 40, 50
    unit = r.uniform(-0.5, 0.5, (v, 3))
    unit[r.random((v, 3)) < 0.1] = 0.0
    center, lwh = r.uniform(-3.0, 3.0, (n, 3)), r.uniform(0.3, 15.0, (n, 3))  # near 0: the sums' low bits show
    rotations = box_rotations(r.uniform(-np.pi, np.pi, n), r.uniform(-0.2, 0.2, n) * (r.random(n) < 0.5))
    numpys = place_in_boxes(unit, center, lwh, rotations)
    mine = np.array([[[_placed(*rotations[a, i], *(unit[k] * lwh[a]), center[a, i]) for i in range(3)]
                      for k in range(v)] for a in range(n)])  # fmt: skip
    assert mine.tobytes() == numpys.tobytes()


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_the_compiled_merged_mesh_is_numpys_to_the_bit(seed: int) -> None:
    # every class, walkers and cyclists on the move (their poses), repeated ids, far from the origin
    r = np.random.default_rng(seed)
    n = 120
    boxes = random_agents(n, seed)
    boxes = Agents(
        r.integers(1, 60, n).astype(np.uint32), boxes.semantic_class, boxes.center_map_m + r.uniform(-3e3, 3e3, 3),
        boxes.lwh_m, boxes.yaw_map_rad, boxes.pitch_rad * (r.random(n) < 0.5), r.uniform(-3, 3, (n, 3)),
        boxes.parked, gait_cycles=np.where(r.random(n) < 0.5, r.uniform(0, 50, n), np.nan),
    )  # fmt: skip
    meshes = agent_meshes(boxes)
    got = (meshes.vertices_m, meshes.triangles, meshes.triangle_instance, meshes.triangle_class, meshes.triangle_part)
    for mine, numpys in zip(got, numpy_agent_meshes(boxes), strict=True):
        assert mine.dtype == numpys.dtype and mine.shape == numpys.shape
        assert mine.tobytes() == numpys.tobytes()


def test_no_agents_give_an_empty_mesh() -> None:
    meshes = agent_meshes(Agents.empty())
    assert meshes.vertices_m.shape == (0, 3) and meshes.triangles.shape == (0, 3)


def test_box_corners_follow_yaw(synth: SimpleNamespace) -> None:
    boxes = synth.agents([(1, SemanticClass.CAR, 10.0, 0.0, 0.75, 4.0, 2.0, 1.5, np.pi / 2)])
    box = corners(boxes)[0]
    np.testing.assert_allclose(box.min(axis=0), [9.0, -2.0, 0.0], atol=1e-9)
    np.testing.assert_allclose(box.max(axis=0), [11.0, 2.0, 1.5], atol=1e-9)


def test_lidar_points_on_shaped_agents_lie_inside_their_boxes(synth: SimpleNamespace, rng: np.random.Generator) -> None:
    sizes = [
        (SemanticClass.CAR, 4.5, 1.8, 1.5),
        (SemanticClass.TRUCK, 7.5, 2.5, 3.2),
        (SemanticClass.BUS, 12.0, 2.5, 3.4),
        (SemanticClass.MOTORCYCLE, 2.2, 0.8, 1.7),
        (SemanticClass.BICYCLE, 1.8, 0.6, 1.75),
        (SemanticClass.PEDESTRIAN, 0.7, 0.6, 1.75),
    ]
    bearing = np.arange(len(sizes)) * 1.0
    rows = [
        (i + 1, cls, 6.0 * np.cos(b), 6.0 * np.sin(b), hgt / 2, lng, wid, hgt, b + 0.4)
        for i, ((cls, lng, wid, hgt), b) in enumerate(zip(sizes, bearing, strict=True))
    ]
    boxes = synth.agents(rows)
    lidar = Lidar(LidarSpec(beams=32, azimuth_steps=1024))
    scan = lidar.sense(synth.scene([synth.ground()], boxes), synth.EGO, DAY, rng).scan
    xyz_map = lidar.spec.ego_SE3_sensor.transform_from(scan.xyz_lidar_m)
    for i, inst in enumerate(boxes.instance_id):
        on = scan.instance_id == inst
        assert on.sum() > 20
        local = in_box_frame(boxes, i, xyz_map[on])
        assert np.all(np.abs(local) <= boxes.lwh_m[i] / 2 + 0.02)
        assert np.all(scan.semantic_class[on] == boxes.semantic_class[i])


def test_no_two_parts_of_a_body_share_a_plane_where_they_overlap() -> None:
    # coplanar faces of two parts would leave a ray's part (its colour, its LiDAR return) to the
    # ray engine's tie-break, which changes with the rest of the scene
    from collections import defaultdict

    from shapely.geometry import Polygon

    for bodies in BODIES.values():
        for body in bodies:
            for pose in range(body.poses):
                piece = body.build(pose)
                v = piece.vertices[piece.triangles]
                n = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
                area = np.linalg.norm(n, axis=1)
                n = n / np.maximum(area, 1e-12)[:, None]
                n *= np.sign(n[np.arange(len(n)), np.argmax(np.abs(n), axis=1)])[:, None]
                d = np.einsum("ij,ij->i", n, v[:, 0])
                planes = defaultdict(list)
                for i in np.flatnonzero(area > 1e-7):
                    planes[(*np.round(n[i], 3), round(float(d[i]), 3))].append(int(i))
                for key, ids in planes.items():
                    if len({int(piece.parts[i]) for i in ids}) < 2:
                        continue
                    normal = np.asarray(key[:3])
                    u = np.cross(normal, [0.0, 0.0, 1.0] if abs(normal[2]) < 0.9 else [1.0, 0.0, 0.0])
                    u /= np.linalg.norm(u)
                    w = np.cross(normal, u)
                    flat = [Polygon(np.stack([v[i] @ u, v[i] @ w], 1)) for i in ids]
                    for a in range(len(ids)):
                        for b in range(a + 1, len(ids)):
                            if piece.parts[ids[a]] != piece.parts[ids[b]]:
                                assert flat[a].intersection(flat[b]).area < 1e-6, (body.name, pose, key)


def _wheels_m(cls: int, lwh_m: tuple[float, float, float], instance: int) -> list[np.ndarray]:
    """The tyre vertices (m, in the agent's box) of an agent of this size, one array per wheel
    (grouped by axle and side)."""
    size = np.asarray(lwh_m, np.float64)
    body = body_of(cls, size, instance)
    pose = pose_of(cls, 5.0, 0.0, lwh_m[2], length_m=lwh_m[0])
    t = template_of(cls, body, pose)
    root = np.arange(t.unit_vertices.shape[0])

    def find(i: int) -> int:
        while root[i] != i:
            root[i] = root[root[i]]
            i = int(root[i])
        return i

    for a, b, c in t.triangles[t.triangle_part == Part.TYRE].tolist():  # a wheel: its tyre's connected triangles
        root[find(b)] = find(a)
        root[find(c)] = find(a)
    tyre = np.unique(t.triangles[t.triangle_part == Part.TYRE])
    group = np.array([find(int(i)) for i in tyre])
    v = t.unit_vertices[tyre] * size
    return [v[group == g] for g in np.unique(group)]


def test_a_trucks_wheels_stay_round_and_its_cab_keeps_its_length_over_the_class_size_range() -> None:
    # a box stretched to a truck's box would squash its wheels into ovals and its cab into a
    # sliver on a short truck: each truck is drawn in the proportion nearest its box's
    truck = int(SemanticClass.TRUCK)
    for lwh in ((4.2, 2.3, 2.7), (5.5, 2.4, 2.4), (6.9, 2.38, 2.73), (9.25, 2.53, 3.66), (12.0, 2.5, 3.8),
                (16.5, 2.55, 4.0)):  # fmt: skip
        for instance in range(1, 6):
            for tyre in _wheels_m(truck, lwh, instance):
                across, tall = np.ptp(tyre[:, 0]), np.ptp(tyre[:, 2])
                assert 0.85 < across / tall < 1.18, (lwh, instance, across / tall)
                assert 0.65 < tall < 1.25, (lwh, instance, tall)  # a truck's tyre: about 1 m
            size = np.asarray(lwh)
            t = template_of(truck, body_of(truck, size, instance), pose_of(truck, 5.0, 0.0, lwh[2], length_m=lwh[0]))
            cab = t.unit_vertices[np.unique(t.triangles[t.triangle_part == Part.CAB])] * size
            cab_per_height = np.ptp(cab[:, 0]) / lwh[2]  # a cab 2.2 m long on a truck 3.4 m high: 0.65
            assert 0.5 < cab_per_height < 0.85, (lwh, instance, cab_per_height)


def _first_part_along_y(piece: object, x: float, z: float) -> int:
    """The part a ray from far out on +y towards -y at (x, z) meets first."""
    v = piece.vertices[piece.triangles]  # type: ignore[attr-defined]
    a, b, c = v[:, 0], v[:, 1], v[:, 2]
    # barycentric test of the point (x, z) in each triangle's projection on the xz plane
    d = (b[:, 0] - a[:, 0]) * (c[:, 2] - a[:, 2]) - (c[:, 0] - a[:, 0]) * (b[:, 2] - a[:, 2])
    ok = np.abs(d) > 1e-12
    d = np.where(ok, d, 1.0)
    s = ((x - a[:, 0]) * (c[:, 2] - a[:, 2]) - (c[:, 0] - a[:, 0]) * (z - a[:, 2])) / d
    t = ((b[:, 0] - a[:, 0]) * (z - a[:, 2]) - (x - a[:, 0]) * (b[:, 2] - a[:, 2])) / d
    inside = ok & (s >= 0) & (t >= 0) & (s + t <= 1)
    y = a[:, 1] + s * (b[:, 1] - a[:, 1]) + t * (c[:, 1] - a[:, 1])
    hit = np.flatnonzero(inside)
    return int(piece.parts[hit[np.argmax(y[hit])]])  # type: ignore[attr-defined]


def test_a_trucks_front_wheel_shows_below_its_cab_from_the_side() -> None:
    # the cab's side is cut over the front wheel, as on real trucks: seen from the side, the
    # wheel shows up to above its hub, not only its lower half under a flat cab
    for body in BODIES[int(SemanticClass.TRUCK)] + BODIES[int(SemanticClass.CONSTRUCTION_VEHICLE)]:
        for pose in range(body.poses):
            piece = body.build(pose)
            tyre = piece.vertices[np.unique(piece.triangles[piece.parts == Part.TYRE])]
            front = tyre[tyre[:, 0] > tyre[:, 0].max() - 1.2]
            x, r = float(front[:, 0].mean()), float(np.ptp(front[:, 2]) / 2)
            for z in (r, 1.5 * r):  # the hub and half way up from it to the tyre's top
                assert _first_part_along_y(piece, x, z) in {Part.TYRE, Part.RIM, Part.CHROME}, (body.name, pose, z)


def test_truck_cabs_are_mostly_white_as_on_the_road() -> None:
    from sensors.parts import part_albedo

    cabs = part_albedo(np.full(400, int(Part.CAB), np.uint8), np.arange(1, 401, dtype=np.uint32)).mean(axis=1)
    cars = part_albedo(np.full(400, int(Part.PAINT), np.uint8), np.arange(1, 401, dtype=np.uint32)).mean(axis=1)
    assert (cabs > 0.8).mean() > 0.35 and (cabs < 0.1).mean() < 0.1
    assert (cabs > 0.8).mean() > (cars > 0.8).mean() and (cabs < 0.1).mean() < (cars < 0.1).mean()
    for body in BODIES[int(SemanticClass.TRUCK)]:
        assert Part.CAB in set(body.build(0).parts.tolist()), body.name


def test_riders_wheels_stay_round_in_their_kinds_nominal_box() -> None:
    # each body fills its box: a body drawn taller than its kind's box would be squashed, its
    # wheels into ovals lying on their side
    from cosim.demand import KINDS

    for kind, cls in (("motorcycle", SemanticClass.MOTORCYCLE), ("bicycle", SemanticClass.BICYCLE)):
        lwh = KINDS[kind].mean_lwh_m
        for tyre in _wheels_m(int(cls), lwh, 1):
            across, tall = np.ptp(tyre[:, 0]), np.ptp(tyre[:, 2])
            assert 0.94 < across / tall < 1.06, (kind, across / tall)


def test_bicycle_tyres_are_as_thick_as_real_ones() -> None:
    # city and trekking tyres are 40-50 mm: a thinner ring vanishes at 15 m
    cls = int(SemanticClass.BICYCLE)
    for tyre in _wheels_m(cls, (1.76, 0.60, 1.74), 1):
        centre = (tyre.min(axis=0) + tyre.max(axis=0)) / 2
        radius = np.hypot(tyre[:, 0] - centre[0], tyre[:, 2] - centre[2])
        assert np.ptp(radius) >= 0.04 and np.ptp(tyre[:, 1]) >= 0.04, (np.ptp(radius), np.ptp(tyre[:, 1]))


def test_a_cyclists_feet_stay_on_the_pedals_at_every_crank_phase() -> None:
    from sensors.bodies import bicycle

    for k in range(GAIT_PHASES):
        piece = bicycle(2 * np.pi * k / GAIT_PHASES)
        shoes = piece.vertices[np.unique(piece.triangles[piece.parts == Part.SHOES])]
        pedals = piece.vertices[np.unique(piece.triangles[piece.parts == Part.TRIM])]
        pedals = pedals[pedals[:, 2] < 0.6]  # not the saddle or the grips
        for side in (1.0, -1.0):
            shoe, pedal = shoes[side * shoes[:, 1] > 0], pedals[side * pedals[:, 1] > 0]
            assert 0.0 < shoe[:, 2].min() - pedal[:, 2].max() < 0.02, (k, side)  # the sole just above the pedal
            assert shoe[:, 0].min() < pedal[:, 0].mean() < shoe[:, 0].max(), (k, side)


def test_motorcyclists_wear_riding_gear_in_their_own_colours() -> None:
    from sensors.bodies import motorcycle
    from sensors.parts import part_albedo

    parts = set(motorcycle().parts.tolist())
    assert {Part.HELMET, Part.GLASS, Part.JACKET, Part.SHOES, Part.ENGINE, Part.HEADLAMP} <= parts
    assert not {Part.SKIN, Part.HAIR, Part.TOP} & parts  # a full-face helmet, a jacket, gloves
    ids = np.arange(1, 401, dtype=np.uint32)

    def colour(part: Part) -> np.ndarray:
        return part_albedo(np.full(len(ids), int(part), np.uint8), ids)

    helmet, paint, jacket = colour(Part.HELMET), colour(Part.PAINT), colour(Part.JACKET)
    shade = helmet.mean(axis=1)
    assert ((shade < 0.1) | (shade > 0.8)).mean() > 0.55  # black and white most
    assert (np.abs(helmet - paint).max(axis=1) < 0.05).mean() < 0.3  # not the machine's paint
    assert (jacket.mean(axis=1) < 0.2).mean() > 0.6  # dark jackets most
    frames = colour(Part.FRAME).mean(axis=1)
    assert (frames < 0.25).mean() > 0.4 and (frames > 0.5).mean() > 0.1  # bicycle frames: dark most, some bright


def test_a_bus_hangs_its_mirrors_ahead_of_its_windscreen_and_shows_its_destination_above_it() -> None:
    # a city bus or coach seen from ahead: "rabbit-ear" mirrors on arms at both front corners,
    # ahead of the windscreen's upper half, and the destination display over the windscreen
    for body in BODIES[int(SemanticClass.BUS)]:
        piece = body.build(0)
        glass, trim, display = (piece.vertices[np.unique(piece.triangles[piece.parts == p])]
                                for p in (Part.GLASS, Part.TRIM, Part.DISPLAY))  # fmt: skip
        front = glass[glass[:, 0] > glass[:, 0].max() - 0.05]  # the windscreen and the display's glass
        for side in (-1.0, 1.0):
            mirror = trim[(trim[:, 0] > front[:, 0].max() + 0.2) & (side * trim[:, 1] > 0.8)]
            assert len(mirror), (body.name, side)
            assert mirror[:, 2].min() > 0.6 * body.lwh_m[2], (body.name, side)
        assert display[:, 0].min() > front[:, 0].max() - 0.05, body.name
        screen = front[front[:, 2] < display[:, 2].min()]
        assert np.ptp(screen[:, 2]) > 1.2 and np.ptp(screen[:, 1]) > 0.9 * body.lwh_m[1], body.name  # a big windscreen
        assert display[:, 2].min() > screen[:, 2].max(), body.name


def test_a_trucks_box_is_outlined_in_contour_marking_at_its_rear_and_along_its_sides() -> None:
    # UN ECE R48: heavy vehicles carry retro-reflective tape along the outline of their body's
    # rear and along its sides; it stays inside the box on every proportion
    for body in BODIES[int(SemanticClass.TRUCK)]:
        for pose in range(body.poses):
            piece = body.build(pose)
            v = piece.vertices
            tape = v[np.unique(piece.triangles[piece.parts == Part.RETRO_YELLOW])]
            rear = tape[tape[:, 0] < v[:, 0].min() + 0.05]
            assert np.ptp(rear[:, 1]) > 0.9 * np.ptp(v[:, 1]), (body.name, pose)
            assert np.ptp(rear[:, 2]) > 0.5 * np.ptp(v[:, 2]), (body.name, pose)
            for side in (-1.0, 1.0):
                along = tape[side * tape[:, 1] > 0.5 * np.ptp(v[:, 1]) - 0.02]
                assert np.ptp(along[:, 0]) > 0.5 * np.ptp(v[:, 0]), (body.name, pose, side)
            assert np.abs(tape[:, 1]).max() <= np.abs(v[:, 1]).max(), (body.name, pose)


def _first_parts(piece, origins: np.ndarray, targets: np.ndarray) -> np.ndarray:  # type: ignore[no-untyped-def]
    """The part each ray from ``origins`` towards ``targets`` meets first on ``piece`` (-1: none)."""
    from sensors.o3d import INVALID_ID, RaycastingScene, o3c

    scene = RaycastingScene()
    scene.add_triangles(
        o3c.Tensor.from_numpy(piece.vertices.astype(np.float32)),
        o3c.Tensor.from_numpy(piece.triangles.astype(np.uint32)),
    )
    d = targets - origins
    rays = np.hstack([origins, d / np.linalg.norm(d, axis=1, keepdims=True)]).astype(np.float32)
    prim = scene.cast_rays(o3c.Tensor.from_numpy(rays))["primitive_ids"].numpy()
    return np.where(prim == INVALID_ID, -1, piece.parts[np.minimum(prim, len(piece.parts) - 1)].astype(np.int64))


def test_buses_and_trucks_carry_marker_lamps_seen_from_outside() -> None:
    # UN ECE R48: amber side markers along vehicles over 6 m long (at most 3 m apart, the first
    # within 3 m of the front, the last within 1 m of the rear), end-outline
    # lamps at the top corners of those over 2.1 m wide (white ahead, red behind); each lamp is
    # the first thing a ray from outside meets on its way to the lamp's middle
    heavy = [(b, p) for c in (SemanticClass.BUS, SemanticClass.TRUCK, SemanticClass.TRAILER)
             for b in BODIES[int(c)] for p in range(b.poses)]  # fmt: skip
    for body, pose in heavy:
        piece = body.build(pose)
        v = piece.vertices
        width = np.ptp(v[:, 1])
        for part, axis in ((Part.SIDE_MARKER, 1), (Part.FRONT_OUTLINE, 0), (Part.REAR_OUTLINE, 0)):
            tri = piece.triangles[piece.parts == part]
            if part == Part.FRONT_OUTLINE and body.name == "box_trailer":
                assert len(tri) == 0  # a trailer's front faces its truck
                continue
            centres = v[tri.reshape(-1, 12, 3)].reshape(-1, 36, 3).mean(axis=1)  # each lamp is a box: 12 triangles
            origins = centres.copy()
            origins[:, axis] = np.sign(centres[:, axis]) * 30.0  # from outside, square to the lamp
            assert (_first_parts(piece, origins, centres) == part).all(), (body.name, pose, part.name)
            if part == Part.SIDE_MARKER:
                for side in (-1.0, 1.0):
                    xs = np.sort(centres[side * centres[:, 1] > 0, 0])
                    assert len(xs) >= 2 and xs[0] < v[:, 0].min() + 1.0, (body.name, pose)
                    assert xs[-1] > v[:, 0].max() - 3.0 and np.diff(xs).max() <= 3.0 + 1e-6, (body.name, pose)
                    assert centres[:, 2].max() < 1.5, (body.name, pose)  # R48: 0.25-1.5 m high
            else:
                ahead = part == Part.FRONT_OUTLINE
                assert len(centres) == 2, (body.name, part.name)
                assert (np.sign(centres[:, 0]) == (1 if ahead else -1)).all(), (body.name, part.name)
                assert np.ptp(centres[:, 1]) > 0.8 * width, (body.name, part.name)  # at the corners
                end = v[:, 0] > v[:, 0].max() - 0.5 if ahead else v[:, 0] < v[:, 0].min() + 0.5
                top = v[end, 2].max()  # the top of its end of the body
                assert centres[:, 2].min() > top - 0.35, (body.name, part.name)
