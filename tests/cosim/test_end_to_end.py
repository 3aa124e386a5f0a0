"""A short scene on the skeleton grid, written and read back."""

import json
import os
import subprocess
import sys
from collections import defaultdict
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate
from mcap.reader import make_reader

from cosim.loop import run
from cosim.scenario import load_scenario
from cosim.world_setup import prepare_network
from gtgen.load import iter_messages, lidar_points, load_labels, objects_from_table
from gtgen.objects import points_in_boxes
from gtgen.sinks.kitti_sink import SEMANTIC_KITTI_LUT
from gtgen.static_map import MAP_RGBA
from gtgen.table import REFERENCE_COLUMNS
from networks.classes import SemanticClass
from networks.geometry import rotation_from_quaternion_xyzw

DATA = Path(__file__).resolve().parents[1] / "data"
pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def dataset(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("tiny")
    run(load_scenario(str(DATA / "tiny.yaml")), out, progress=False)
    return out


def test_run_writes_the_dataset_files(dataset):
    names = {p.name for p in dataset.iterdir()}
    assert {"run.mcap", "labels.csv", "manifest.json"} <= names
    assert not any(n.endswith(".partial") for n in names)


def test_every_frame_has_transforms_a_point_cloud_and_boxes(dataset):
    topics_per_time = defaultdict(set)
    for topic, log_time, _ in iter_messages(dataset / "run.mcap"):
        topics_per_time[log_time].add(topic)
    assert len(topics_per_time) == 20
    expected = {"/tf", "/lidar", "/radar", "/gt/boxes", "/gt/labels", "/map/vectors"} | {
        f"/camera/{k}" for k in ("image", "depth", "instance", "class", "calibration", "annotations")
    }
    first, *rest = (topics_per_time[t] for t in sorted(topics_per_time))
    assert first == expected | {"/map"}
    assert all(topics == expected for topics in rest)


def test_labels_csv_starts_with_the_reference_columns(dataset):
    labels = load_labels(dataset / "labels.csv")
    assert list(labels.columns[: len(REFERENCE_COLUMNS)]) == REFERENCE_COLUMNS
    assert labels["frame"].nunique() == 20
    assert (labels["type"] == "car").any() and (labels["type"] == "pedestrian").any()


def test_lidar_points_of_an_object_lie_inside_its_box(dataset):
    labels = load_labels(dataset / "labels.csv")
    clouds = [m for _, _, m in iter_messages(dataset / "run.mcap", topics=["/lidar"])]
    tagged_total = 0
    for frame, cloud in enumerate(clouds):
        pts = lidar_points(cloud)
        rows = labels[labels["frame"] == frame]
        boxes, _ = objects_from_table(rows)
        tagged = pts[pts["instance"] > 0]
        index = np.searchsorted(boxes.track_id, tagged["instance"], sorter=np.argsort(boxes.track_id))
        order = np.argsort(boxes.track_id)
        index = order[np.clip(index, 0, len(order) - 1)]
        assert np.all(boxes.track_id[index] == tagged["instance"]), "a point is tagged with an unlabelled object"
        xyz_ego = np.column_stack(
            [tagged["x"], tagged["y"], tagged["z"] + 1.95]
        )  # lidar mount: 1.95 m above the ego origin
        assert np.all(points_in_boxes(xyz_ego, boxes, index, tolerance_m=0.02))
        tagged_total += len(tagged)
    assert tagged_total > 1000


def test_point_counts_in_labels_match_the_cloud(dataset):
    labels = load_labels(dataset / "labels.csv")
    clouds = [m for _, _, m in iter_messages(dataset / "run.mcap", topics=["/lidar"])]
    pts = lidar_points(clouds[5])
    rows = labels[labels["frame"] == 5]
    for track_id, count in zip(rows["id"], rows["lidar_points"], strict=True):
        assert int(np.sum(pts["instance"] == track_id)) == count


def test_same_seed_gives_identical_labels_and_messages(dataset, tmp_path):
    """A second run from the command line, in a fresh interpreter with another string hash
    seed (set and dict order must not leak into the traffic or the labels)."""
    env = {**os.environ, "PYTHONHASHSEED": "12345"}
    cmd = [
        sys.executable,
        "-m",
        "cosim",
        "run",
        str(DATA / "tiny.yaml"),
        "--out",
        str(tmp_path),
        "--no-summary",
        "--no-progress",
    ]
    subprocess.run(cmd, check=True, env=env, capture_output=True)
    assert (tmp_path / "labels.csv").read_bytes() == (dataset / "labels.csv").read_bytes()
    assert raw_messages(tmp_path / "run.mcap") == raw_messages(dataset / "run.mcap")


def raw_messages(path: Path) -> list[tuple[str, int, bytes]]:
    with path.open("rb") as stream:
        return [(c.topic, m.log_time, m.data) for _, c, m in make_reader(stream).iter_messages()]


def test_kitti_layout_has_one_file_per_frame_and_parsable_labels(dataset):
    kitti = dataset / "kitti"
    for sub, ext in (("image_2", "png"), ("velodyne", "bin"), ("label_2", "txt"), ("calib", "txt")):
        assert len(list((kitti / sub).glob(f"*.{ext}"))) == 20, sub
    calib = dict(line.split(": ", 1) for line in (kitti / "calib" / "000005.txt").read_text().splitlines())
    P2 = np.array(calib["P2"].split(), float).reshape(3, 4)
    velo = np.fromfile(kitti / "velodyne" / "000005.bin", dtype="<f4").reshape(-1, 4)
    assert len(velo) > 10000 and np.all((velo[:, 3] >= 0) & (velo[:, 3] <= 1))
    rows = [line.split() for text in (kitti / "label_2").glob("*.txt") for line in text.read_text().splitlines()]
    assert rows, "no KITTI labels in 20 frames"
    for r in rows:
        kitti_types = {"Car", "Van", "Truck", "Pedestrian", "Person_sitting", "Cyclist", "Tram", "Misc"}
        assert len(r) == 15 and r[0] in kitti_types
        left, top, right, bottom = map(float, r[4:8])
        h, x, y, z = float(r[8]), float(r[11]), float(r[12]), float(r[13])
        assert 0 <= left <= right <= 1280 and 0 <= top <= bottom <= 720
        u, v, w = P2 @ np.array([x, y - h / 2, z, 1.0])  # the box centre, from its bottom centre
        if float(r[1]) == 0.0 and z > 0:
            assert left - 1 <= u / w <= right + 1 and top - 1 <= v / w <= bottom + 1


def test_yolo_boxes_are_normalised_and_name_known_classes(dataset):
    yolo = dataset / "yolo"
    data = (yolo / "data.yaml").read_text()
    assert "pedestrian" in data and "path:" not in data  # no absolute path: the folder can be moved
    lines = [line.split() for f in (yolo / "labels").glob("*.txt") for line in f.read_text().splitlines()]
    assert len(list((yolo / "images").glob("*.jpg"))) == 20
    for cls, *box in lines:
        assert 0 <= int(cls) <= 13  # road users 0-5, traffic lights by state 6-10, signs 11-13
        cx, cy, w, h = map(float, box)
        assert 0 < w <= 1 and 0 < h <= 1
        assert min(cx - w / 2, cy - h / 2) >= -1e-6 and max(cx + w / 2, cy + h / 2) <= 1 + 1e-6


def test_summary_writes_statistics_and_pictures(dataset):
    from gtgen.summary import write_summary

    stats = write_summary(dataset)
    names = {p.name for p in (dataset / "summary").iterdir()}
    assert {"stats.csv", "objects_per_frame.png", "distance.png", "visibility.png", "bev_000000.png"} <= names
    assert {"camera_000000.png", "camera_000010.png", "camera_000019.png"} <= names
    labels = load_labels(dataset / "labels.csv")
    total = stats[stats["class"] == "all"].iloc[0]
    assert total["seen_per_frame"] == pytest.approx((labels["seen"] == 1).sum() / 20)
    content = dict(pd.read_csv(dataset / "summary" / "content.csv").itertuples(index=False))
    near = labels[(labels["seen"] == 1) & (labels["distance"] <= 50) & (labels["parked"] == 0)]
    assert content["car"] == pytest.approx((near["type"] == "car").sum() / 20, abs=1e-3)
    assert content["frames"] == 20 and content["ego_speed_frames"] == 20


def test_ego_stopped_share_from_the_transforms_matches_the_runs_own(dataset):
    from gtgen.content import measure

    manifest = json.loads((dataset / "manifest.json").read_text())
    content = measure(dataset)
    # the run counts SUMO's speed, the tool the distance between frames: they may differ in a frame
    # where the ego starts or stops
    assert abs(content.stopped_share - manifest["ego_stopped_share"]) <= 2 / 20


def test_static_map_is_written_once_at_the_first_frame_with_every_classed_triangle(dataset):
    with (dataset / "run.mcap").open("rb") as stream:
        messages = [(c.topic, m.log_time, m.data) for _, c, m in make_reader(stream).iter_messages()]
    maps = [(t, data) for topic, t, data in messages if topic == "/map"]
    assert len(maps) == 1
    assert maps[0][0] == min(t for _, t, _ in messages)
    (entity,) = SceneUpdate.FromString(maps[0][1]).entities
    assert entity.frame_id == "map" and entity.frame_locked
    mesh = prepare_network(load_scenario(str(DATA / "tiny.yaml"))).world.mesh
    expected = {cls: int(np.sum(mesh.triangle_class == cls)) for cls in MAP_RGBA}
    written = {
        cls: len(prim.indices) // 3
        for prim in entity.triangles
        for cls, rgba in MAP_RGBA.items()
        if np.allclose([prim.color.r, prim.color.g, prim.color.b, prim.color.a], rgba)
    }
    assert written == {cls: n for cls, n in expected.items() if n}
    assert written[SemanticClass.ROAD] > 100 and written[SemanticClass.BUILDING] > 100


def test_lane_markings_are_bright_in_the_lidar_and_classed_in_the_camera(dataset):
    """Every frame has LiDAR points on paint, at least twice as intense as the road at the same
    range; the camera's class mask has paint pixels."""
    import cv2

    for _, _, cloud in iter_messages(dataset / "run.mcap", ["/lidar"]):
        points = lidar_points(cloud)
        paint = points["class"] == SemanticClass.LANE_MARKING
        assert paint.sum() > 50
        rng = np.hypot(points["x"], points["y"])
        for lo, hi in ((3.0, 8.0), (8.0, 15.0)):
            band = (rng >= lo) & (rng < hi)
            road = band & (points["class"] == SemanticClass.ROAD)
            if (band & paint).sum() >= 10 and road.sum() >= 10:
                assert points["intensity"][band & paint].mean() >= 2.0 * points["intensity"][road].mean()
    masks = [
        cv2.imdecode(np.frombuffer(m.data, np.uint8), cv2.IMREAD_UNCHANGED)
        for _, _, m in iter_messages(dataset / "run.mcap", ["/camera/class"])
    ]
    assert len(masks) == 20
    assert all(np.sum(mask == SemanticClass.LANE_MARKING) > 200 for mask in masks)


def test_a_run_that_will_not_fit_on_the_disk_stops_early_with_one_line_and_no_dataset(tmp_path, monkeypatch):
    import shutil
    from collections import namedtuple

    from cosim.errors import CosimError

    usage = namedtuple("usage", "total used free")
    monkeypatch.setattr(shutil, "disk_usage", lambda path: usage(10**9, 10**9 - 10**6, 10**6))  # 1 MB free
    expected = r"not enough free disk space for this run: about [0-9.]+ [MG]B in all .* 1 MB free"
    with pytest.raises(CosimError, match=expected) as err:
        # 20 frames: the size is extrapolated after the 10th (a run of at least 60 frames: the 30th)
        run(load_scenario(str(DATA / "tiny.yaml"), ["frames=20"]), tmp_path, progress=False)
    assert "\n" not in str(err.value)
    assert sorted(p.name for p in tmp_path.iterdir()) == []


def test_semantic_kitti_point_labels_match_the_point_cloud_and_poses_follow_the_ego(dataset):
    kitti = dataset / "kitti"
    clouds = [lidar_points(m) for _, _, m in iter_messages(dataset / "run.mcap", ["/lidar"])]
    assert len(list((kitti / "labels").glob("*.label"))) == len(clouds) == 20
    for index in (0, 7, 19):
        labels = np.fromfile(kitti / "labels" / f"{index:06d}.label", dtype="<u4")
        velo = np.fromfile(kitti / "velodyne" / f"{index:06d}.bin", dtype="<f4").reshape(-1, 4)
        cloud = clouds[index]
        assert len(labels) == len(velo) == len(cloud)
        np.testing.assert_array_equal(labels & 0xFFFF, SEMANTIC_KITTI_LUT[cloud["class"]])
        np.testing.assert_array_equal(labels >> 16, cloud["instance"] & 0x7FFF)
        written = {1, 10, 11, 13, 15, 18, 30, 40, 44, 48, 50, 51, 60, 70, 71, 72, 80, 81, 99}
        assert set(np.unique(labels & 0xFFFF)) <= written
        assert {10, 40, 50, 60} <= set(np.unique(labels & 0xFFFF))
    poses = np.loadtxt(kitti / "poses.txt").reshape(-1, 3, 4)
    assert poses.shape == (20, 3, 4)
    np.testing.assert_allclose(poses[0], np.eye(4)[:3], atol=1e-9)
    tf = [m.transforms[0] for _, _, m in iter_messages(dataset / "run.mcap", ["/tf"])]  # map -> ego

    def camera_in_map(t) -> np.ndarray:
        q = t.rotation
        return rotation_from_quaternion_xyzw(q.x, q.y, q.z, q.w) @ [0.41, 0.0, 1.64] + [
            t.translation.x,
            t.translation.y,
            t.translation.z,
        ]

    moved = np.linalg.norm(camera_in_map(tf[-1]) - camera_in_map(tf[0]))
    assert moved > 1.0
    assert abs(np.linalg.norm(poses[-1][:, 3]) - moved) < 0.01
    calib = dict(line.split(": ", 1) for line in (kitti / "calib.txt").read_text().splitlines())
    assert {"P0", "P1", "P2", "P3", "Tr"} <= set(calib)


def test_every_further_camera_gets_its_own_label_columns(tmp_path):
    cameras = (
        "sensors.cameras=[{name: front, shading: flat}, "  # their look is not under test here
        "{name: rear, mount_xyz_m: [-1.0, 0, 1.6], mount_rpy_deg: [0, 0, 180], shading: flat}]"
    )
    overrides = ["frames=8", cameras, "outputs.kitti=false", "outputs.yolo=false"]
    run(load_scenario(str(DATA / "tiny.yaml"), overrides), tmp_path, progress=False)
    labels = load_labels(tmp_path / "labels.csv")
    assert list(labels.columns[: len(REFERENCE_COLUMNS)]) == REFERENCE_COLUMNS
    assert {"rear_occluded", "rear_visible_fraction", "rear_modal_left", "rear_alpha"} <= set(labels.columns)
    seen_behind = labels[labels["rear_visible_px"] > 0]
    assert len(seen_behind) > 0 and (seen_behind["x"] < 0).all()
    seen_ahead = labels[labels["camera_visible_px"] > 0]
    assert len(seen_ahead) > 0 and (seen_ahead["x"] > 0).all()
    json_rows = [o for _, _, m in iter_messages(tmp_path / "run.mcap", ["/gt/labels"]) for o in m["objects"]]
    assert len(json_rows) == len(labels) and "rear_visible_fraction" in json_rows[0]


def test_foxglove_layout_names_only_topics_of_the_mcap(dataset):
    import json

    layout = json.loads((dataset / "foxglove_layout.json").read_text())
    named: set[str] = set()

    def walk(node) -> None:
        if isinstance(node, dict):
            for key, value in node.items():
                if key in ("topics", "annotations"):
                    named.update(value)
                elif key in ("imageTopic", "calibrationTopic", "topicPath"):
                    named.add(value)
                walk(value)
        elif isinstance(node, list):
            for item in node:
                walk(item)

    walk(layout)
    topics = {topic for topic, _, _ in raw_messages(dataset / "run.mcap")}
    assert {"/lidar", "/radar", "/gt/boxes", "/map", "/camera/image", "/camera/annotations", "/gt/labels"} <= named
    assert named <= topics


def test_kitti_boxes_hold_exactly_each_objects_lidar_points_under_a_strict_test(dataset):
    """As OpenPCDet reads KITTI (camera -> LiDAR through Tr_velo_to_cam and R0_rect, the box
    centre half a height above its bottom, heading -(pi/2 + rotation_y)) and as its CPU
    points-in-box test counts (|dz| <= h/2, |dx| < l/2, |dy| < w/2, here without its 1 cm slack):
    every point of the object (SemanticKITTI's instance id) in its box, and no point of the
    static world; where boxes overlap (two people walking side by side), the other's points too."""
    kitti, labels = dataset / "kitti", load_labels(dataset / "labels.csv")
    compared = 0
    for label_file in sorted((kitti / "label_2").glob("*.txt")):
        frame = int(label_file.stem)
        lines = (kitti / "calib" / label_file.name).read_text().splitlines()
        calib = {k: np.array(v.split(), float) for k, v in (line.split(": ", 1) for line in lines)}
        tr = np.vstack([calib["Tr_velo_to_cam"].reshape(3, 4), [0, 0, 0, 1]])
        rect_to_velo = np.linalg.inv(
            np.vstack([np.hstack([calib["R0_rect"].reshape(3, 3), np.zeros((3, 1))]), [0, 0, 0, 1]]) @ tr
        )
        points = np.fromfile(kitti / "velodyne" / f"{label_file.stem}.bin", dtype="<f4").reshape(-1, 4)[:, :3]
        instance = np.fromfile(kitti / "labels" / f"{label_file.stem}.label", dtype="<u4") >> 16
        rows = labels[(labels["frame"] == frame) & labels["left"].notna() & (labels["seen"] == 1)]
        rows = rows[~rows["type"].isin(["traffic_light", "traffic_sign"])]  # not in KITTI's labels
        for line, (_, row) in zip(label_file.read_text().splitlines(), rows.iterrows(), strict=True):
            v = line.split()
            h, w, length, ry = float(v[8]), float(v[9]), float(v[10]), float(v[14])
            centre = (rect_to_velo @ [float(v[11]), float(v[12]), float(v[13]), 1.0])[:3] + np.array([0.0, 0.0, h / 2])
            d = points - centre
            c, s = np.cos(np.pi / 2 + ry), np.sin(np.pi / 2 + ry)  # rotation by -heading
            dx, dy = c * d[:, 0] - s * d[:, 1], s * d[:, 0] + c * d[:, 1]
            inside = (np.abs(d[:, 2]) <= h / 2) & (np.abs(dx) < length / 2) & (np.abs(dy) < w / 2)
            own = inside & (instance == int(row["id"]) % 32768)
            assert int(own.sum()) == row["lidar_points"], (frame, row["id"], row["type"])
            assert np.all(instance[inside] > 0), (frame, row["id"], row["type"])  # no static point in a box
            compared += 1
    assert compared > 50


def test_vehicles_carry_the_subtype_and_lamps_the_camera_draws(dataset):
    from sensors.bodies import BODIES, body_of

    labels = load_labels(dataset / "labels.csv")
    vehicles = labels[labels["type"].isin(["car", "truck", "bus"])]
    assert len(vehicles) and vehicles["subtype"].notna().all()
    for row in vehicles.drop_duplicates("id").itertuples():
        body = BODIES[row.class_id][body_of(row.class_id, np.array([row.l, row.w, row.h]), row.id)]
        assert row.subtype == body.name
    others = labels[~labels["type"].isin(["car", "truck", "bus"])]
    assert others["subtype"].isna().all()
    assert set(labels["brake_lamps"]) <= {0, 1} and set(labels["indicator"].dropna()) <= {"left", "right", "both"}
    assert (labels.loc[labels["parked"] == 1, "brake_lamps"] == 0).all()
    assert labels.loc[labels["type"] == "pedestrian", "indicator"].isna().all()
