"""Boxes hold their objects on slopes: a loop of ramps (8.75 % up, a bend on top, 8.75 % down)
driven by long trucks and buses, seen from an ego that climbs and descends with them."""

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from cosim.loop import run
from cosim.scenario import load_scenario
from gtgen.load import iter_messages, lidar_points, load_labels, objects_from_table
from gtgen.objects import points_in_boxes
from networks.convert import import_opendrive
from networks.geometry import SE3, rotation_from_quaternion_xyzw
from networks.plain import PlainEdge, PlainNetwork, PlainNode, write_opendrive
from networks.world import load_net

pytestmark = pytest.mark.slow
FRAMES = 200
TOP_M = 14.0  # the ramps climb 14 m over 160 m


def ramps() -> PlainNetwork:
    """A loop: up a straight ramp, round a bend on top, down a ramp, back along the ground."""
    up = tuple((x, 0.0, TOP_M * x / 160.0) for x in np.linspace(0.0, 160.0, 9))
    bend = tuple((160.0 + 100.0 * math.sin(t), 100.0 - 100.0 * math.cos(t), TOP_M) for t in np.linspace(0, 1.5708, 9))
    down = tuple((260.0, 100.0 + y, TOP_M * (1.0 - y / 160.0)) for y in np.linspace(0.0, 160.0, 9))
    nodes = (PlainNode("a", 0, 0, 0), PlainNode("b", 160, 0, TOP_M), PlainNode("c", 260, 100, TOP_M),
             PlainNode("d", 260, 260, 0), PlainNode("e", 0, 260, 0))  # fmt: skip
    edges = []
    for (a, b), shape in (("ab", up), ("bc", bend), ("cd", down), ("de", ()), ("ea", ())):
        edges += [
            PlainEdge(f"{a}{b}", a, b, num_lanes=2, shape=shape),
            PlainEdge(f"{b}{a}", b, a, num_lanes=2, shape=shape[::-1]),
        ]
    return PlainNetwork(nodes, tuple(edges))


@pytest.fixture(scope="module")
def drive(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("ramps")
    xodr = write_opendrive(ramps(), root / "plain", root / "ramps.xodr")
    net = load_net(import_opendrive(xodr))
    uphill = min(e.getID() for e in net.getEdges(withInternal=False) if not e.getFunction()
                 and e.getShape3D()[0][2] < 1.0 and e.getShape3D()[-1][2] > TOP_M - 1.0)  # fmt: skip
    scene = root / "ramps.yaml"
    traffic = "{vehicles: 30, pedestrians: 0, mix: {car: 0.4, truck: 0.3, bus: 0.3}}"
    scene.write_text(
        f"network: {xodr}\nframes: {FRAMES}\nseed: 2\nwarmup_s: 40\ntraffic: {traffic}\nego: {{route: ['{uphill}']}}\n"
    )
    camera = "sensors.cameras=[{width_px: 320, height_px: 180, shading: flat}]"  # KITTI's boxes, not its look
    rig = [camera, "sensors.radars=[]", "outputs.yolo=false"]
    run(load_scenario(str(scene), rig), root / "out", progress=False)
    return root / "out"


def _frames(out: Path):
    """Per frame: the label rows, their boxes and the object-tagged LiDAR points in the ego frame
    with the row index of their object."""
    labels = load_labels(out / "labels.csv")
    transforms = [m for _, _, m in iter_messages(out / "run.mcap", ["/tf"])]
    clouds = [m for _, _, m in iter_messages(out / "run.mcap", ["/lidar"])]
    for frame, (tf, cloud) in enumerate(zip(transforms, clouds, strict=True)):
        (t,) = [t for t in tf.transforms if t.child_frame_id == cloud.frame_id]
        q = t.rotation
        ego_SE3_lidar = SE3(
            rotation_from_quaternion_xyzw(q.x, q.y, q.z, q.w),
            np.array([t.translation.x, t.translation.y, t.translation.z]),
        )
        p = lidar_points(cloud)
        tagged = p[p["instance"] > 0]
        rows = labels[labels["frame"] == frame]
        boxes, _ = objects_from_table(rows)
        order = np.argsort(boxes.track_id)
        index = order[np.clip(np.searchsorted(boxes.track_id, tagged["instance"], sorter=order), 0, len(order) - 1)]
        assert np.all(boxes.track_id[index] == tagged["instance"]), "a point is tagged with an unlabelled object"
        xyz = ego_SE3_lidar.transform_from(np.column_stack([tagged["x"], tagged["y"], tagged["z"]]).astype(float))
        yield frame, rows, boxes, xyz, index


def test_every_object_point_lies_in_its_pitched_box_on_the_ramps(drive):
    """Within 2 cm, on every frame; yaw-only boxes would leave the ends of pitched trucks and
    buses out."""
    points = outside_yaw_only = 0
    pitches, rolls = [], []
    for _, rows, boxes, xyz, index in _frames(drive):
        assert np.all(points_in_boxes(xyz, boxes, index, tolerance_m=0.02))
        level = replace(boxes, pitch_ego_rad=0 * boxes.pitch_ego_rad, roll_ego_rad=0 * boxes.roll_ego_rad)
        outside_yaw_only += int((~points_in_boxes(xyz, level, index, tolerance_m=0.02)).sum())
        points += len(index)
        pitches += rows.loc[rows["lidar_points"] > 0, "pitch"].abs().tolist()
        rolls += rows.loc[rows["lidar_points"] > 0, "roll"].abs().tolist()
    assert points > 20_000
    assert max(pitches) > 0.06 and max(rolls) > 0.01  # pitched and rolled relative to the ego
    assert outside_yaw_only > 100


def test_kitti_boxes_are_upright_and_hold_each_objects_points(drive):
    """KITTI's boxes turn by yaw only: on a slope they are the smallest such box that holds the
    object's box, so every point of the object lies in its KITTI box."""
    labels = load_labels(drive / "labels.csv")
    checked = longer = 0
    for label_file in sorted((drive / "kitti" / "label_2").glob("*.txt")):
        frame = int(label_file.stem)
        lines = (drive / "kitti" / "calib" / label_file.name).read_text().splitlines()
        calib = {k: np.array(v.split(), float) for k, v in (line.split(": ", 1) for line in lines)}
        velo_to_cam = np.vstack([calib["Tr_velo_to_cam"].reshape(3, 4), [0, 0, 0, 1]])
        cam_to_velo = np.linalg.inv(velo_to_cam)
        scan = np.fromfile(drive / "kitti" / "velodyne" / f"{label_file.stem}.bin", dtype="<f4").reshape(-1, 4)
        ids = np.fromfile(drive / "kitti" / "labels" / f"{label_file.stem}.label", dtype="<u4") >> 16
        rows = labels[(labels["frame"] == frame) & labels["left"].notna() & (labels["seen"] == 1)]
        rows = rows[~rows["type"].isin(["traffic_light", "traffic_sign"])]  # not in KITTI's labels
        objects = [line for line in label_file.read_text().splitlines() if not line.startswith("DontCare")]
        for line, (_, row) in zip(objects, rows.iterrows(), strict=True):  # (a frame with none has a DontCare line)
            v = line.split()
            h, w, length, ry = float(v[8]), float(v[9]), float(v[10]), float(v[14])
            centre = (cam_to_velo @ [float(v[11]), float(v[12]), float(v[13]), 1.0])[:3] + np.array([0.0, 0.0, h / 2])
            d = scan[ids == (int(row["id"]) & 0x7FFF), :3] - centre
            c, s = np.cos(np.pi / 2 + ry), np.sin(np.pi / 2 + ry)
            dx, dy = c * d[:, 0] - s * d[:, 1], s * d[:, 0] + c * d[:, 1]
            assert np.all((np.abs(d[:, 2]) <= h / 2) & (np.abs(dx) <= length / 2) & (np.abs(dy) <= w / 2))
            checked += 1
            longer += int(length > row["l"] + 0.05)
    assert checked > 100 and longer > 10
