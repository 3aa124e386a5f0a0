"""Map ground truth against what the sensors saw: paint points on the map's lines, road points
in its drivable raster, the ego on its lane, elements that follow the ego's motion."""

import json
from pathlib import Path

import numpy as np
import pytest
import shapely
from shapely.geometry import LineString, Polygon

from cosim.loop import run
from cosim.scenario import load_scenario
from gtgen.load import iter_messages, lidar_points, load_map_frame
from networks.classes import SemanticClass
from networks.geometry import SE3, rotation_from_quaternion_xyzw

pytestmark = pytest.mark.slow
DATA = Path(__file__).resolve().parents[1] / "data"
LIDAR_ONLY = ["sensors.cameras=[]", "sensors.radars=[]", "outputs.kitti=false", "outputs.yolo=false", "frames=100"]
PAINT = (SemanticClass.LANE_MARKING, SemanticClass.LANE_MARKING_YELLOW)


@pytest.fixture(scope="module", params=["tiny", "town07_village"])
def drive(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp(request.param)
    scene = str(DATA / "tiny.yaml") if request.param == "tiny" else request.param
    extra = [] if request.param == "tiny" else ["traffic.vehicles=40", "traffic.pedestrians=20", "warmup_s=30"]
    run(load_scenario(scene, LIDAR_ONLY + extra), out, progress=False)
    return out


def _frames(run_dir: Path):
    """Per frame: the LiDAR points in the ego frame with their classes, the map vectors and layers."""
    transforms = [m for _, _, m in iter_messages(run_dir / "run.mcap", ["/tf"])]
    clouds = [m for _, _, m in iter_messages(run_dir / "run.mcap", ["/lidar"])]
    for frame, (tf, cloud) in enumerate(zip(transforms, clouds, strict=True)):
        (t,) = [t for t in tf.transforms if t.child_frame_id == cloud.frame_id]
        q = t.rotation
        ego_SE3_lidar = SE3(
            rotation_from_quaternion_xyzw(q.x, q.y, q.z, q.w),
            np.array([t.translation.x, t.translation.y, t.translation.z]),
        )
        p = lidar_points(cloud)
        xyz = ego_SE3_lidar.transform_from(np.column_stack([p["x"], p["y"], p["z"]]).astype(np.float64))
        vectors, layers = load_map_frame(run_dir, frame)
        yield frame, xyz, p["class"], vectors, layers


def test_every_paint_point_lies_on_a_line_or_crossing_of_the_frames_map(drive):
    checked = 0
    for _, xyz, cls, vectors, _ in _frames(drive):
        half_x, half_y = vectors["range_m"]
        inside = (np.abs(xyz[:, 0]) < half_x - 0.3) & (np.abs(xyz[:, 1]) < half_y - 0.3)
        paint = xyz[np.isin(cls, PAINT) & inside, :2]
        lines = [LineString(e["points"]) for e in vectors["elements"]
                 if e["type"] in ("lane_divider", "edge_line", "stop_line")]  # fmt: skip
        crossings = [
            Polygon(e["points"]) for e in vectors["elements"] if e["type"] == "crossing" and len(e["points"]) > 3
        ]
        marks = shapely.union_all(lines + crossings)
        distance = shapely.distance(marks, shapely.points(paint))
        assert np.all(distance <= 0.15 + 1e-3), (vectors["frame"], float(distance.max()), paint[np.argmax(distance)])
        checked += len(paint)
    assert checked > 5000


def test_road_points_fall_in_the_drivable_raster_and_sidewalk_points_do_not(drive):
    # Crossings' ends past a junction's outline are paved at the road's level, so drivable too
    # (town07_village has one beside a walking area's corner). Known: where a sidewalk's end meets
    # a junction's corner the sidewalk's strip and the map's outline of it differ by centimetres,
    # and the junction's road shows through there (town07_village: 3 road points of 1.24 M, 0.9 m
    # inside the walkway); at most one road point in 10,000 may land there.
    road_checked = walk_checked = road_off = 0
    for _, xyz, cls, vectors, layers in _frames(drive):
        half_x, half_y = vectors["range_m"]
        res = vectors["resolution_m"]
        row = np.floor((half_x - xyz[:, 0]) / res).astype(int)
        col = np.floor((half_y - xyz[:, 1]) / res).astype(int)
        drivable = layers["drivable"]
        h, w = drivable.shape
        inside = (row >= 1) & (row < h - 1) & (col >= 1) & (col < w - 1)
        near = np.zeros_like(drivable)  # drivable within one pixel
        deep = np.ones_like(drivable)  # drivable and all eight neighbours too
        for dr in (-1, 0, 1):
            for dc in (-1, 0, 1):
                shifted = np.roll(np.roll(drivable, dr, 0), dc, 1)
                near |= shifted
                deep &= shifted
        road = inside & np.isin(cls, [SemanticClass.ROAD, SemanticClass.CROSSING, *PAINT])
        road_off += int((near[row[road], col[road]] == 0).sum())
        walk = inside & (cls == SemanticClass.SIDEWALK)
        assert np.all(deep[row[walk], col[walk]] == 0), vectors["frame"]
        road_checked += int(road.sum())
        walk_checked += int(walk.sum())
    assert road_checked > 100_000 and walk_checked > 1_000
    assert road_off <= road_checked // 10_000, (road_off, road_checked)


def test_the_ego_is_on_the_lane_the_map_names_every_frame(drive):
    lanes = {lane["lane_id"]: lane for lane in json.loads((drive / "map" / "map.json").read_text())["lanes"]}
    frames = 0
    for _, _, _, vectors, _ in _frames(drive):
        lane = lanes[vectors["ego_lane"]]  # SUMO's lane for the ego at that step
        centre = np.asarray(lane["centre_m"])[:, :2]
        pose = np.asarray(vectors["map_SE3_ego"])
        body = LineString([pose[:2, 3], pose[:2, 3] + pose[:2, 0] * 2.6])  # footprint centre to front bumper
        # SUMO puts a vehicle on a lane by its front bumper: the lane reaches the ego's body
        assert LineString(centre).distance(body) < lane["width_m"] / 2.0 + 0.3, vectors["frame"]
        on_road = not vectors["ego_lane"].startswith(":")  # not inside a junction
        assert vectors["route_ahead"] and (
            not on_road or vectors["ego_lane"].rsplit("_", 1)[0] == vectors["route_ahead"][0]
        )
        frames += 1
    assert frames == 100


def test_elements_follow_the_egos_motion_between_frames(drive):
    cuts = set(json.loads((drive / "manifest.json").read_text()).get("scene_cuts", []))
    previous = None
    compared = 0
    for frame, _, _, vectors, _ in _frames(drive):
        pose = np.asarray(vectors["map_SE3_ego"])
        pieces: dict[int, list[np.ndarray]] = {}  # an element the range cuts in two comes in two pieces
        for e in vectors["elements"]:
            pieces.setdefault(e["id"], []).append(np.asarray(e["points"]))
        if previous is not None and frame not in cuts:
            old_pose, old = previous
            motion = np.linalg.inv(pose) @ old_pose  # previous ego frame -> this ego frame
            half_x, half_y = vectors["range_m"]
            for eid, parts in pieces.items():
                if eid not in old:
                    continue
                lines = [LineString(p @ motion[:2, :2].T + motion[:2, 3]) for p in old[eid]]
                moved = shapely.union_all([line for line in lines if line.length > 0.01])
                if moved.is_empty:
                    continue
                points = np.concatenate(parts)
                keep = (np.abs(points[:, 0]) < half_x - 2.0) & (np.abs(points[:, 1]) < half_y - 2.0)
                if keep.any():
                    gap = shapely.distance(moved, shapely.points(points[keep]))
                    assert np.all(gap <= 0.02), (frame, eid, float(gap.max()))
                    compared += int(keep.sum())
        previous = (pose, pieces)
    assert compared > 1000


def test_the_map_topic_draws_the_elements_in_the_ego_frame(drive):
    updates = [m for _, _, m in iter_messages(drive / "run.mcap", ["/map/vectors"])]
    assert len(updates) == 100
    vectors, _ = load_map_frame(drive, 0)
    (entity,) = updates[0].entities
    assert entity.frame_id == "ego" and len(entity.lines) == len(vectors["elements"])
