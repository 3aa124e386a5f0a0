"""Every writer on small hand-made frame records (no SUMO): write, read back with the format's
own reader or a plain parser, compare with the records."""

from pathlib import Path

import cv2
import numpy as np
import pandas as pd
import pytest
import yaml

from gtgen.load import iter_messages, lidar_points, radar_points
from gtgen.objects import EXPORT_MARGIN_M
from gtgen.sinks.group import SinkChoice, SinkGroup
from gtgen.sinks.kitti_sink import KITTI_TYPES, SEMANTIC_KITTI_LUT
from gtgen.sinks.yolo_sink import YOLO_CLASSES
from gtgen.table import label_table, table_columns
from networks.classes import SemanticClass
from networks.geometry import rotation_from_quaternion_xyzw
from sensors.agents import Agents
from sensors.shading import shade_frame


@pytest.fixture(scope="module")
def written(records, tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("written")
    with SinkGroup.open(SinkChoice(out)) as sinks:
        for record in records:
            sinks.write(record)
    return out


def test_labels_csv_reads_back_as_the_label_table_of_every_frame(records, written):
    text = {"hazard_event": str, "indicator": str, "subtype": str}
    csv = pd.read_csv(written / "labels.csv", dtype=text, keep_default_na=False, na_values=[""])
    for name in text:
        csv[name] = csv[name].fillna("")
    assert list(csv.columns) == table_columns(records[0].labels)
    expected = pd.concat([pd.DataFrame(label_table(r.labels)) for r in records], ignore_index=True)
    assert len(csv) == len(expected) == sum(len(r.labels) for r in records)
    for name in expected.columns:
        if expected[name].dtype.kind == "f":
            decimals = 3 if name == "timestamp" else 4
            np.testing.assert_allclose(csv[name], expected[name], atol=0.51 * 10**-decimals, err_msg=name)
        else:
            assert csv[name].astype(str).tolist() == expected[name].astype(str).tolist(), name


def kitti_rows(path: Path) -> list[list[str]]:
    return [line.split() for line in path.read_text().splitlines()]


def kitti_calib(path: Path) -> dict[str, np.ndarray]:
    return {k: np.array(v.split(), float) for k, v in (line.split(": ", 1) for line in path.read_text().splitlines())}


def kitti_box_pixels(row: list[str], P2: np.ndarray, margin_m: float = 0.0) -> np.ndarray:
    """The 3D box of a KITTI label row projected with P2, as KITTI's devkit draws it: corners
    around the bottom centre ``location``, turned by ``rotation_y`` about the camera's y axis;
    shrunk by ``margin_m`` on each side and lowered by it first."""
    h, w, length = (float(v) for v in row[8:11])
    x, y, z, ry = (float(v) for v in row[11:15])
    w, length, y = w - 2 * margin_m, length - 2 * margin_m, y + margin_m
    cx = np.array([1, 1, -1, -1, 1, 1, -1, -1]) * length / 2
    cy = np.array([0, 0, 0, 0, -1, -1, -1, -1]) * h
    cz = np.array([1, -1, -1, 1, 1, -1, -1, 1]) * w / 2
    c, s = np.cos(ry), np.sin(ry)
    corners = np.stack([c * cx + s * cz + x, cy + y, -s * cx + c * cz + z, np.ones(8)])
    uvw = P2 @ corners
    return uvw[:2] / uvw[2]


def test_kitti_labels_read_back_as_the_seen_objects_and_their_boxes_project_onto_the_image(records, written):
    kitti = written / "kitti" / "training"
    for record in records:
        name = f"{record.frame_index:06d}"
        rows = kitti_rows(kitti / "label_2" / f"{name}.txt")
        calib = kitti_calib(kitti / "calib" / f"{name}.txt")
        camera = record.cameras[0]
        np.testing.assert_allclose(calib["P2"].reshape(3, 4), camera.spec.pinhole.P, rtol=1e-11)
        objects, cam = record.labels.objects, record.labels.cameras[0]
        in_image = record.labels.seen & np.isfinite(cam.boxes.clipped_px[:, 0])
        assert len(rows) == int(in_image.sum()) > 0
        for row, i in zip(rows, np.flatnonzero(in_image), strict=True):
            assert row[0] == KITTI_TYPES[SemanticClass(int(objects.semantic_class[i]))]
            assert int(row[2]) == cam.visibility.occluded[i]
            np.testing.assert_allclose([float(v) for v in row[4:8]], cam.boxes.clipped_px[i], atol=0.006)
            grown = objects.lwh_m[i, [2, 1, 0]] + np.array([0.0, 2, 2]) * EXPORT_MARGIN_M  # h, w, l
            np.testing.assert_allclose([float(v) for v in row[8:11]], grown, atol=6e-5)
            uv = kitti_box_pixels(row, calib["P2"].reshape(3, 4), EXPORT_MARGIN_M)
            if float(row[1]) == 0.0:  # not truncated: the projected box is the 2D box
                np.testing.assert_allclose(
                    [uv[0].min(), uv[1].min(), uv[0].max(), uv[1].max()], [float(v) for v in row[4:8]], atol=0.2
                )


def test_kitti_velodyne_and_semantic_kitti_labels_hold_every_lidar_point(records, written):
    kitti = written / "kitti" / "training"
    for record in records:
        name, scan = f"{record.frame_index:06d}", record.lidars[0].scan
        velo = np.fromfile(kitti / "velodyne" / f"{name}.bin", dtype="<f4").reshape(-1, 4)
        np.testing.assert_array_equal(velo[:, :3], scan.xyz_lidar_m)
        np.testing.assert_array_equal(velo[:, 3], scan.intensity)
        labels = np.fromfile(kitti / "labels" / f"{name}.label", dtype="<u4")
        np.testing.assert_array_equal(labels & 0xFFFF, SEMANTIC_KITTI_LUT[scan.semantic_class])
        np.testing.assert_array_equal(labels >> 16, scan.instance_id)
        image = cv2.imread(str(kitti / "image_2" / f"{name}.png"))
        np.testing.assert_array_equal(image, shade_frame(record.cameras[0].frame))


def test_kitti_calibration_maps_lidar_points_into_the_camera_and_poses_follow_the_ego(records, written):
    kitti = written / "kitti" / "training"
    calib = kitti_calib(kitti / "calib" / "000000.txt")
    record = records[0]
    lidar, camera = record.lidars[0], record.cameras[0]
    xyz_lidar = lidar.scan.xyz_lidar_m.astype(np.float64)
    expected = camera.spec.ego_SE3_sensor.inverse().compose(lidar.spec.ego_SE3_sensor).transform_from(xyz_lidar)
    Tr = calib["Tr_velo_to_cam"].reshape(3, 4)
    np.testing.assert_allclose(xyz_lidar @ Tr[:, :3].T + Tr[:, 3], expected, atol=1e-9)
    sequence = kitti_calib(kitti / "calib.txt")
    np.testing.assert_array_equal(sequence["Tr"], calib["Tr_velo_to_cam"])
    poses = np.loadtxt(kitti / "poses.txt").reshape(-1, 3, 4)
    assert poses.shape == (len(records), 3, 4)
    np.testing.assert_allclose(poses[0], np.eye(4)[:3], atol=1e-12)
    # the ego drives 1 m along its x axis per record: along the camera's z (optical axis)
    np.testing.assert_allclose(poses[2][:, 3], [0.0, 0.0, 2.0], atol=1e-9)


def test_kitti_splits_frames_into_image_sets_with_the_test_frames_under_testing(records, written):
    kitti = written / "kitti"
    sets = {s: (kitti / "ImageSets" / f"{s}.txt").read_text().split() for s in ("train", "val", "test", "trainval")}
    assert sets == {"train": ["000000"], "val": ["000001"], "test": ["000002"], "trainval": ["000000", "000001"]}
    for folder, ext in (("image_2", "png"), ("velodyne", "bin"), ("calib", "txt"), ("planes", "txt")):
        assert sorted(p.name for p in (kitti / "testing" / folder).iterdir()) == [f"000002.{ext}"]
        assert (kitti / "testing" / folder / f"000002.{ext}").samefile(kitti / "training" / folder / f"000002.{ext}")
    assert not (kitti / "testing" / "label_2").exists()  # KITTI's test set has no labels
    for former in ("image_2", "velodyne", "label_2", "calib", "labels", "poses.txt", "calib.txt"):
        assert (kitti / former).resolve() == (kitti / "training" / former).resolve()
    assert (kitti / "label_2" / "000001.txt").read_text() == (kitti / "training/label_2/000001.txt").read_text()


def test_kitti_road_plane_holds_the_lidar_road_points_in_the_camera_frame(records, written):
    training = written / "kitti" / "training"
    for record in records:
        name, scan = f"{record.frame_index:06d}", record.lidars[0].scan
        lines = (training / "planes" / f"{name}.txt").read_text().splitlines()
        assert lines[:3] == ["# Matrix", "WIDTH 4", "HEIGHT 1"]
        a, b, c, d = (float(v) for v in lines[3].split())
        assert b < 0 and np.isclose(np.linalg.norm([a, b, c]), 1.0)  # normal up: KITTI's -y
        Tr = kitti_calib(training / "calib" / f"{name}.txt")["Tr_velo_to_cam"].reshape(3, 4)
        road = scan.xyz_lidar_m[scan.semantic_class == SemanticClass.ROAD].astype(np.float64)
        xyz_cam = road @ Tr[:, :3].T + Tr[:, 3]
        assert len(road) > 500 and np.abs(xyz_cam @ [a, b, c] + d).max() < 0.03


def test_a_kitti_frame_without_objects_gets_one_dont_care_line(record_maker, tmp_path):
    from sensors.agents import Agents

    with SinkGroup.open(SinkChoice(tmp_path, mcap=False, csv=False, yolo=False)) as sinks:
        sinks.write(record_maker(0, agents=Agents.empty()))
    rows = kitti_rows(tmp_path / "kitti" / "training" / "label_2" / "000000.txt")
    assert rows == [["DontCare", "-1", "-1", "-10", "0.00", "0.00", "0.00", "0.00", "-1", "-1", "-1", "-1000",
                     "-1000", "-1000", "-10"]]  # fmt: skip


def test_kitti_image_3_is_the_second_camera_and_p3_projects_the_lidar_into_it(record_maker, tmp_path):
    record = record_maker(0, second_camera=True)
    with SinkGroup.open(SinkChoice(tmp_path, mcap=False, csv=False, yolo=False, kitti_image_3=True)) as sinks:
        sinks.write(record)
    training = tmp_path / "kitti" / "training"
    right = record.cameras[1]
    image = cv2.imread(str(training / "image_3" / "000000.png"))
    np.testing.assert_array_equal(image, shade_frame(right.frame))
    calib = kitti_calib(training / "calib" / "000000.txt")
    P2, P3 = calib["P2"].reshape(3, 4), calib["P3"].reshape(3, 4)
    assert P3[0, 3] == pytest.approx(-0.53 * P3[0, 0]) and np.allclose(P3[:, :3], P2[:, :3])  # KITTI's stereo form
    scan = record.lidars[0].scan
    Tr = calib["Tr_velo_to_cam"].reshape(3, 4)
    on_cars = scan.instance_id > 0
    xyz_cam = scan.xyz_lidar_m[on_cars].astype(np.float64) @ Tr[:, :3].T + Tr[:, 3]
    uvw = np.column_stack([xyz_cam, np.ones(len(xyz_cam))]) @ P3.T
    u, v = np.round(uvw[:, 0] / uvw[:, 2]).astype(int), np.round(uvw[:, 1] / uvw[:, 2]).astype(int)
    inside = (uvw[:, 2] > 0) & (u >= 0) & (u < right.spec.width_px) & (v >= 0) & (v < right.spec.height_px)
    hits = right.frame.instance_id[v[inside], u[inside]] == scan.instance_id[on_cars][inside]
    assert inside.sum() > 20 and hits.mean() > 0.9  # with P2 instead of P3: 0.68


def test_yolo_labels_are_the_tight_boxes_of_the_visible_objects(records, written):
    yolo = written / "yolo"
    names = yaml.safe_load((yolo / "data.yaml").read_text())["names"]
    lights = [f"traffic_light_{s}" for s in ("red", "yellow", "green", "red_yellow", "off")]
    signs = ["traffic_sign_stop", "traffic_sign_yield", "traffic_sign_speed_limit"]
    later = ["trailer", "construction_vehicle", "traffic_cone", "barrier"]  # appended: earlier ids keep their meaning
    assert [names[i] for i in range(len(names))] == [c.label for c in YOLO_CLASSES] + lights + signs + later
    for record in records:
        name = f"{record.frame_index:06d}"
        rows = np.loadtxt(yolo / "labels" / f"{name}.txt", ndmin=2)
        cam, objects = record.labels.cameras[0], record.labels.objects
        visible = np.flatnonzero(cam.visibility.visible_px >= 25)
        assert rows.shape == (len(visible), 5) and len(visible) > 0
        w, h = record.cameras[0].spec.width_px, record.cameras[0].spec.height_px
        for row, i in zip(rows, visible, strict=True):
            assert YOLO_CLASSES[int(row[0])] == objects.semantic_class[i]
            left, top = (row[1] - row[3] / 2) * w, (row[2] - row[4] / 2) * h
            right, bottom = (row[1] + row[3] / 2) * w, (row[2] + row[4] / 2) * h
            # tight boxes hold pixel centres (OpenCV: pixel u spans u - 0.5 .. u + 0.5); YOLO, like
            # COCO, puts pixel edges at whole numbers (pixel u spans u .. u + 1, the image 0 .. W)
            modal = cam.visibility.modal_px[i]
            np.testing.assert_allclose([left, top, right, bottom], modal + np.array([0.0, 0.0, 1.0, 1.0]), atol=1e-3)
        image = cv2.imread(str(yolo / "images" / f"{name}.jpg"))
        assert image.shape == (h, w, 3)


def test_mcap_messages_read_back_as_the_records(records, written):
    by_time: dict[int, dict[str, object]] = {}
    for topic, log_time, message in iter_messages(written / "run.mcap"):
        by_time.setdefault(log_time, {})[topic] = message
    assert sorted(by_time) == [r.timestamp_ns for r in records]
    for record in records:
        messages = by_time[record.timestamp_ns]
        cloud = lidar_points(messages["/lidar"])
        scan = record.lidars[0].scan
        np.testing.assert_array_equal(np.column_stack([cloud["x"], cloud["y"], cloud["z"]]), scan.xyz_lidar_m)
        np.testing.assert_array_equal(cloud["instance"], scan.instance_id)
        np.testing.assert_array_equal(
            radar_points(messages["/radar"])["radial_velocity"], record.radars[0].scan.radial_velocity_mps
        )
        ego = messages["/tf"].transforms[0]
        q, t = ego.rotation, ego.translation
        np.testing.assert_allclose(
            rotation_from_quaternion_xyzw(q.x, q.y, q.z, q.w), record.map_SE3_ego.rotation, atol=1e-12
        )
        np.testing.assert_allclose([t.x, t.y, t.z], record.map_SE3_ego.translation)
        labels = messages["/gt/labels"]
        assert [o["id"] for o in labels["objects"]] == record.labels.objects.track_id.tolist()
        np.testing.assert_allclose(
            [o["x"] for o in labels["objects"]], record.labels.objects.center_ego_m[:, 0], atol=6e-6
        )
        boxes = messages["/gt/boxes"]
        assert [e.id for e in boxes.entities] == [str(i) for i in record.labels.objects.track_id]
        calibration = messages["/camera/calibration"]
        np.testing.assert_allclose(np.reshape(calibration.K, (3, 3)), record.cameras[0].spec.pinhole.K)
        jpeg = cv2.imdecode(np.frombuffer(messages["/camera/image"].data, np.uint8), cv2.IMREAD_COLOR)
        assert np.abs(jpeg.astype(int) - shade_frame(record.cameras[0].frame)).mean() < 4.0
    assert (written / "foxglove_layout.json").exists()


def test_sinks_leave_nothing_when_the_with_block_raises(records, tmp_path):
    with pytest.raises(RuntimeError, match="stop"), SinkGroup.open(SinkChoice(tmp_path)) as sinks:
        sinks.write(records[0])
        raise RuntimeError("stop")
    assert sorted(p.name for p in tmp_path.iterdir()) == []


def test_static_furniture_classes_map_to_semantic_kitti_nuscenes_and_occ3d():
    from gtgen.nuscenes_lidarseg import LIDARSEG_CATEGORIES, LIDARSEG_LUT
    from gtgen.occupancy import OCC3D_OF_CLASS
    from networks.classes import SemanticClass

    assert SEMANTIC_KITTI_LUT[SemanticClass.FENCE] == 51  # fence: fences, guard rails, crash barriers
    assert SEMANTIC_KITTI_LUT[SemanticClass.OTHER_OBJECT] == 99  # other-object: benches, bins, shelters
    for cls in (SemanticClass.FENCE, SemanticClass.OTHER_OBJECT):
        assert LIDARSEG_CATEGORIES[LIDARSEG_LUT[cls]] == "static.manmade"
        assert OCC3D_OF_CLASS[cls] == "manmade"


def test_work_zone_objects_and_trailers_are_dontcare_regions_and_misc_in_kitti_and_have_yolo_classes(
    record_maker, tmp_path
):
    S = SemanticClass
    cone, barrier, trailer, work = (int(c) for c in (S.TRAFFIC_CONE, S.BARRIER, S.TRAILER, S.CONSTRUCTION_VEHICLE))
    agents = Agents.standing([4, 6, 7, 11], [cone, barrier, trailer, work],
                             [[9.0, -2.0, 0.375], [14.0, 2.5, 0.5], [30.0, 4.0, 1.7], [22.0, -4.0, 1.6]],
                             [[0.4, 0.4, 0.75], [2.0, 0.5, 1.0], [7.0, 2.5, 3.4], [7.0, 2.5, 3.2]],
                             [0.0, 1.57, 0.1, 0.0])  # fmt: skip
    record = record_maker(0, agents=agents)
    with SinkGroup.open(SinkChoice(tmp_path)) as sinks:
        sinks.write(record)
    rows = kitti_rows(tmp_path / "kitti" / "training" / "label_2" / "000000.txt")
    objects, cam = record.labels.objects, record.labels.cameras[0]
    in_image = np.flatnonzero(record.labels.seen & np.isfinite(cam.boxes.clipped_px[:, 0]))
    assert len(rows) == len(in_image) == 4
    for row, i in zip(rows, in_image, strict=True):
        cls = int(objects.semantic_class[i])
        assert row[0] == ("DontCare" if cls in (cone, barrier) else "Misc")
        np.testing.assert_allclose([float(v) for v in row[4:8]], cam.boxes.clipped_px[i], atol=0.006)
        if row[0] == "DontCare":  # a region: no 3D box, as KITTI's own DontCare lines
            assert row[8:15] == ["-1", "-1", "-1", "-1000", "-1000", "-1000", "-10"]
    yolo = np.loadtxt(tmp_path / "yolo" / "labels" / "000000.txt", ndmin=2)
    names = yaml.safe_load((tmp_path / "yolo" / "data.yaml").read_text())["names"]
    visible = np.flatnonzero(cam.visibility.visible_px >= 25)
    assert [names[int(r[0])] for r in yolo] == [SemanticClass(int(objects.semantic_class[i])).label for i in visible]
    assert len(visible) >= 3  # the cone is under 25 pixels in this 160x90 camera


def test_every_object_class_has_its_place_in_every_output():
    from gtgen.colours import CLASS_RGB
    from gtgen.nuscenes import CATEGORIES
    from gtgen.nuscenes_lidarseg import LIDARSEG_LUT
    from gtgen.sinks.kitti_sink import SEMANTIC_KITTI_IDS
    from gtgen.sinks.yolo_sink import YOLO_NAMES
    from networks.classes import AGENT_CLASSES
    from sensors.materials import ALBEDO_BGR_BY_CLASS, RADAR_REFLECTIVITY_BY_CLASS, REFLECTIVITY_BY_CLASS

    for c in AGENT_CLASSES:
        assert c in KITTI_TYPES and c in SEMANTIC_KITTI_IDS and c in CATEGORIES and c in CLASS_RGB, c
        assert c.label in YOLO_NAMES.values() and LIDARSEG_LUT[int(c)] > 0, c
        assert REFLECTIVITY_BY_CLASS[int(c)] > 0 and RADAR_REFLECTIVITY_BY_CLASS[int(c)] > 0, c
        assert ALBEDO_BGR_BY_CLASS[int(c)].tolist() != [0.5, 0.5, 0.5], c


def test_nuscenes_categories_and_attributes_of_the_work_zone_and_trailers():
    from gtgen.nuscenes import attribute_of, category_of

    S = SemanticClass
    assert [category_of(int(c)) for c in (S.TRAILER, S.CONSTRUCTION_VEHICLE, S.TRAFFIC_CONE, S.BARRIER)] == [
        "vehicle.trailer", "vehicle.construction", "movable_object.trafficcone", "movable_object.barrier"]  # fmt: skip
    assert attribute_of("vehicle.trailer", False, 8.0) == "vehicle.moving"
    assert attribute_of("vehicle.construction", True, 0.0) == "vehicle.parked"
    assert attribute_of("movable_object.trafficcone", False, 0.0) == ""  # nuScenes gives cones and barriers none
    assert attribute_of("movable_object.barrier", False, 0.0) == ""


def test_police_cars_and_ambulances_are_nuscenes_emergency_vehicles_boxes_and_points():
    from gtgen.nuscenes import category_of
    from gtgen.nuscenes_lidarseg import LIDARSEG_CATEGORIES, lidarseg_of_objects, panoptic_labels

    assert category_of(int(SemanticClass.CAR), "police") == "vehicle.emergency.police"
    assert category_of(int(SemanticClass.CAR), "ambulance") == "vehicle.emergency.ambulance"
    assert category_of(int(SemanticClass.CAR), "sedan") == "vehicle.car"
    cls = np.array([10, 10, 10, 1], np.uint8)
    ids = np.array([4, 7, 7, 0], np.uint32)
    special = {7: "vehicle.emergency.police"}
    seg = lidarseg_of_objects(cls, ids, special)
    assert [LIDARSEG_CATEGORIES[k] for k in seg] == ["vehicle.car", *["vehicle.emergency.police"] * 2,
                                                      "flat.driveable_surface"]  # fmt: skip
    pan = panoptic_labels(cls, ids, {4: 1, 7: 2}, special)
    s = seg.astype(int)
    assert pan.tolist() == [s[0] * 1000 + 1, s[1] * 1000 + 2, s[2] * 1000 + 2, s[3] * 1000]


def test_semantic_kitti_instance_ids_stay_under_2_to_the_15() -> None:
    # SemanticKITTI's panoptic evaluation multiplies a label by 2^32 in int64: labels must stay under 2^31
    from gtgen.sinks.kitti_sink import semantic_kitti_labels

    ids = np.array([1, 32767, 32768, 61496, 4_000_000_000], np.uint32)
    labels = semantic_kitti_labels(np.full(5, int(SemanticClass.CAR), np.uint8), ids)
    assert labels.max() < 2**31
    np.testing.assert_array_equal(labels >> 16, ids % 32768)
    assert np.all(labels & 0xFFFF == 10)
