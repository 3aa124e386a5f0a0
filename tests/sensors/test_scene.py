"""The frame scene: class and instance per ray, silhouettes of agents taken alone."""

import math

import numpy as np

from networks.classes import SemanticClass
from networks.geometry import SE3
from networks.mesh import ClassedMesh
from sensors.agents import Agents, agent_meshes
from sensors.camera import Camera, CameraSpec
from sensors.o3d import INVALID_ID, RaycastingScene, o3c
from sensors.scene import FrameScene


def cars_in_a_row(n: int) -> Agents:
    """Cars one behind the other along +x (each hides part of the next), some turned."""
    x = 8.0 + 6.0 * np.arange(n)
    center = np.column_stack([x, 0.6 * np.sin(x), np.full(n, 0.75)])
    size = np.tile([4.5, 1.8, 1.5], (n, 1))
    yaw = np.linspace(0.0, math.pi / 3, n)
    return Agents.standing(np.arange(10, 10 + n), np.full(n, int(SemanticClass.CAR)), center, size, yaw)


def all_hits_reference(meshes, rays: np.ndarray) -> set[tuple[int, int]]:
    """(ray, instance) for every agent a ray passes through, by Open3D's list_intersections."""
    scene = RaycastingScene()
    scene.add_triangles(
        o3c.Tensor.from_numpy(meshes.vertices_m), o3c.Tensor.from_numpy(meshes.triangles.astype(np.uint32))
    )
    result = scene.list_intersections(o3c.Tensor.from_numpy(rays))
    instance = meshes.triangle_instance[result["primitive_ids"].numpy()]
    return set(zip(result["ray_ids"].numpy().tolist(), instance.tolist(), strict=True))


def test_a_ray_hits_an_agent_alone_exactly_when_it_passes_through_it_among_all():
    agents = cars_in_a_row(6)
    meshes = agent_meshes(agents)
    camera = Camera(CameraSpec(width_px=96, height_px=54, mount_xyz_m=(0.0, 0.0, 1.2)))
    pixels = camera.rays(SE3.identity())
    rays = np.tile(pixels, (len(agents), 1))  # ask each pixel's ray about every car
    owner = np.repeat(agents.instance_id, pixels.shape[0])
    scene = FrameScene(ClassedMesh.empty(), agents)
    alone = scene.hits_alone(rays, owner)
    reference = all_hits_reference(meshes, rays)
    expected = np.array([(i, int(o)) in reference for i, o in enumerate(owner)])
    np.testing.assert_array_equal(alone, expected)
    first = scene.cast(rays).instance_id
    assert expected.sum() > 200 and (expected & (first != owner)).sum() > 20  # hidden parts count too


def test_cast_tells_class_and_instance_of_static_agent_and_missed_rays():
    h = 50.0
    ground = ClassedMesh(np.array([[-h, -h, 0.0], [h, -h, 0.0], [h, h, 0.0], [-h, h, 0.0]]),
                         np.array([[0, 1, 2], [0, 2, 3]]), np.full(2, int(SemanticClass.SIDEWALK)))  # fmt: skip
    scene = FrameScene(ground, cars_in_a_row(1))
    rays = np.array([[0, 0, 5, 0, 0, -1], [8, 0, 5, 0, 0, -1], [0, 0, 5, 0, 0, 1]], np.float32)
    hits = scene.cast(rays)
    assert hits.semantic_class.tolist() == [int(SemanticClass.SIDEWALK), int(SemanticClass.CAR), 0]
    assert hits.instance_id.tolist() == [0, 10, 0]
    assert hits.range_m[0] == 5.0 and 3.0 < hits.range_m[1] < 4.0 and np.isinf(hits.range_m[2])
    assert scene.cast_raw(rays)["geometry_ids"].numpy()[2] == INVALID_ID


def test_kept_silhouette_scenes_answer_as_fresh_ones_while_agents_stand_and_move():
    from sensors.scene import AloneScenes, Open3DEngine

    camera = Camera(CameraSpec(width_px=96, height_px=54, mount_xyz_m=(0.0, 0.0, 1.2)))
    pixels = camera.rays(SE3.identity())
    engine = Open3DEngine()
    agents = cars_in_a_row(4)
    kept: dict[int, object] = {}
    for frame in range(3):
        if frame == 2:  # the second car moves, the others stand; the last leaves
            center = agents.center_map_m.copy()
            center[1, 0] += 0.5
            agents = Agents.standing(agents.instance_id[:3], agents.semantic_class[:3], center[:3],
                                     agents.lwh_m[:3], agents.yaw_map_rad[:3])  # fmt: skip
        scene = engine.scene(ClassedMesh.empty(), agents)
        rays = np.tile(pixels, (len(agents), 1))
        owner = np.repeat(agents.instance_id, pixels.shape[0])
        alone = scene.hits_alone(rays, owner)
        meshes = scene.agent_meshes
        fresh = FrameScene(ClassedMesh.empty(), agents).hits_alone(rays, owner)
        cast = np.zeros(rays.shape[0], np.bool_)  # each agent's own scene, cast for its nearest hit
        for instance in agents.instance_id.tolist():
            tri = meshes.triangles[meshes.triangle_instance == instance]
            own = RaycastingScene()
            own.add_triangles(o3c.Tensor.from_numpy(meshes.vertices_m),
                              o3c.Tensor.from_numpy(tri.astype(np.uint32)))  # fmt: skip
            mine = owner == instance
            found = own.cast_rays(o3c.Tensor.from_numpy(rays[mine]))["geometry_ids"].numpy()
            cast[mine] = found != INVALID_ID
        np.testing.assert_array_equal(alone, fresh)
        np.testing.assert_array_equal(alone, cast)
        assert alone.sum() > 100
        scenes = engine._alone._scenes
        now = {i: s for i, (_, s) in scenes.items()}
        if frame == 1:
            assert all(now[i] is kept[i] for i in now)  # all stood: every scene kept
        if frame == 2:
            assert set(now) == {10, 11, 12}  # the one that left is dropped
            assert now[10] is kept[10] and now[12] is kept[12] and now[11] is not kept[11]
        kept = now
    assert isinstance(engine._alone, AloneScenes)
