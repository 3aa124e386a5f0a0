"""The nuScenes export read by the official nuscenes-devkit (in .venv-nuscenes, made by
``make nuscenes-devkit``): two runs of the nuScenes rig, one alone and both merged into one
dataroot, loaded, rendered (radar, lidarseg and panoptic too) and scored by the devkit's own
detection and tracking evaluations; scene names checked against the devkit's split lists."""

import json
import subprocess
from collections import Counter
from pathlib import Path

import cv2
import numpy as np
import pytest

from cosim.loop import run
from cosim.scenario import load_scenario
from gtgen import nuscenes, nuscenes_names
from gtgen.load import load_labels
from gtgen.objects import EXPORT_MARGIN_M

ROOT = Path(__file__).resolve().parents[2]
DATA = ROOT / "tests" / "data"
DEVKIT = ROOT / ".venv-nuscenes" / "bin" / "python"
KEYFRAME_EVERY = 10  # frames of 0.05 s in 0.5 s
NATIVE = {"car": "vehicle.car", "truck": "vehicle.truck", "bus": "vehicle.bus.rigid",
          "motorcycle": "vehicle.motorcycle", "bicycle": "vehicle.bicycle",
          "pedestrian": "human.pedestrian.adult"}  # fmt: skip
# The export's tables, files and calibration do not depend on the look of the images: the six
# cameras shade flat here (the realistic camera has its own tests).
FLAT_CAMERAS = (
    "sensors.cameras=["
    + ", ".join(
        f"{{name: {name}, shading: flat}}"
        for name in ("CAM_FRONT", "CAM_FRONT_RIGHT", "CAM_BACK_RIGHT", "CAM_BACK", "CAM_BACK_LEFT", "CAM_FRONT_LEFT")
    )
    + "]"
)
NUSCENES_ONLY = ("outputs.kitti=false", "outputs.yolo=false", "outputs.mcap=false")  # the tests read labels.csv too
pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def export(tmp_path_factory: pytest.TempPathFactory) -> tuple[list[Path], Path, dict]:
    if not DEVKIT.exists():
        pytest.fail("the nuScenes devkit's environment is missing: run `make nuscenes-devkit` (make test does)")
    root = tmp_path_factory.mktemp("nuscenes")
    runs = []
    for seed in (3, 4):
        out = root / f"tiny-s{seed}"
        options = ["rig=nuscenes", f"seed={seed}", "frames=41", FLAT_CAMERAS, *NUSCENES_ONLY]
        run(load_scenario(str(DATA / "tiny.yaml"), options), out, progress=False)
        runs.append(out)
    merged = root / "merged"
    assert nuscenes.main(["merge", str(merged), *(str(r) for r in runs)]) == 0
    return (
        runs,
        merged,
        devkit_check(merged, root / "devkit", "--eval", "sim_all", "--lists", "--margin", str(EXPORT_MARGIN_M)),
    )


def devkit_check(dataroot: Path, out: Path, *options: str) -> dict:
    command = [str(DEVKIT), str(ROOT / "tests" / "nuscenes_devkit_check.py"), str(dataroot), str(out), *options]
    check = subprocess.run(command, capture_output=True, text=True, check=False)
    assert check.returncode == 0, check.stderr[-3000:]
    return json.loads(check.stdout)


def names(split: str, numbers: range) -> list[str]:
    return [f"scene-{getattr(nuscenes_names, split.upper())[k]:04d}" for k in numbers]


def test_the_scene_names_are_those_of_the_devkits_official_split_lists(export):
    lists = export[2]["lists"]
    assert lists == {s: list(getattr(nuscenes_names, s.upper())) for s in ("train", "val", "test")}


def test_a_single_run_gives_train_val_and_test_scenes_by_their_official_names(export, tmp_path):
    runs = export[0]
    report = devkit_check(runs[0] / "nuscenes", tmp_path, "--no-render")
    # 41 frames: 5 keyframes, in 3 scenes of 2, 2 and 1 (a run under a minute still gives three splits)
    assert report["official_splits"] == {
        nuscenes.VERSION: {"train": names("train", range(1)), "val": names("val", range(1)), "test": []},
        nuscenes.TEST_VERSION: {"train": [], "val": [], "test": names("test", range(1))},
    }
    assert report["unresolved"] == report["test_unresolved"] == [] and report["samples"] == 4


def test_the_devkit_loads_the_merged_scenes_and_every_reference_resolves(export):
    _, merged, report = export
    # each run keeps its own splits: 1 train, 1 val, 1 test scene; the merge renames them
    assert report["official_splits"] == {
        nuscenes.VERSION: {"train": names("train", range(2)), "val": names("val", range(2)), "test": []},
        nuscenes.TEST_VERSION: {"train": [], "val": [], "test": names("test", range(2))},
    }
    assert report["samples"] == 8 and report["unresolved"] == report["test_unresolved"] == []
    splits = json.loads((merged / nuscenes.VERSION / "splits.json").read_text())
    assert splits["sim_train"] == names("train", range(2)) and splits["sim_val"] == names("val", range(2))
    assert json.loads((merged / nuscenes.TEST_VERSION / "splits.json").read_text())["sim_test"] == names(
        "test", range(2)
    )


def test_a_merge_by_whole_runs_puts_every_scene_of_a_run_in_one_split(export, tmp_path):
    runs = export[0]
    assert nuscenes.main(["merge", str(tmp_path / "m"), str(runs[0]), str(runs[1]), "--val", str(runs[1])]) == 0
    splits = json.loads((tmp_path / "m" / nuscenes.VERSION / "splits.json").read_text())
    assert splits["sim_train"] == names("train", range(3)) and splits["sim_val"] == names("val", range(3))
    assert not (tmp_path / "m" / nuscenes.TEST_VERSION).exists()
    lidarseg = json.loads((tmp_path / "m" / nuscenes.VERSION / "lidarseg.json").read_text())
    assert len(lidarseg) == 10 and all((tmp_path / "m" / r["filename"]).is_file() for r in lidarseg)


def test_the_devkit_reads_every_radar_sweep_and_the_point_labels(export):
    _, merged, report = export
    data = json.loads((merged / nuscenes.VERSION / "sample_data.json").read_text())
    radar_files = sum(1 for d in data if "/RADAR_" in d["filename"])
    assert report["radar"]["files"] == radar_files > 0 and report["radar"]["points"] > 0
    labels = report["point_labels"]
    assert labels["sweeps"] == 8 and labels["panoptic_semantics_equal"] == labels["points"] > 10_000
    assert {"flat.driveable_surface", "vehicle.car", "static.manmade"} <= set(labels["per_category"])
    assert labels["instances"] > 5 and labels["devkit_panoptic_agreement"] > 0.99
    # the devkit's points-in-box labelling finds every point of a standing object (the boxes'
    # margin); moving objects' points lie off their boxes as in nuScenes (its sweeps are
    # corrected for the ego's motion only)
    assert labels["devkit_panoptic_standing_differ"] == 0
    assert report["test_point_labels"] == 2  # one keyframe in each run's test scene


def test_the_devkits_own_scores_of_the_ground_truth_are_perfect(export):
    scores = export[2]["eval"]
    assert scores["mAP"] >= 0.99 and scores["NDS"] >= 0.99 and scores["AMOTA"] >= 0.99, scores
    assert {"car", "pedestrian"} <= set(scores["detection_classes"]) and scores["gt_boxes"] > 50


def test_annotations_per_category_equal_the_labels_at_the_keyframes(export):
    runs, _, report = export
    expected: Counter[str] = Counter()
    for out in runs:
        labels = load_labels(out / "labels.csv")
        at_keyframes = labels[(labels["frame"] % KEYFRAME_EVERY == 0) & labels["type"].isin(list(NATIVE))]
        expected.update(NATIVE[t] for t in at_keyframes["type"])
    assert Counter(report["per_category"]) + Counter(report["test_per_category"]) == expected


def test_devkit_boxes_in_each_camera_land_on_the_labels_2d_boxes(export):
    runs, _, report = export
    frame_of_instance = {}
    labels_of = {}
    for days, out in enumerate(runs):  # the merge moves the k-th run k days later
        labels = load_labels(out / "labels.csv")
        labels_of[out.name] = labels
        for track in labels["id"].unique():
            for scene in range(3):  # 3 scenes per run
                instance = nuscenes.token(out.name, "instance", scene, int(track))
                frame_of_instance[instance] = (out.name, int(track), days)
    compared = 0
    for box in report["camera_boxes"]:
        left, top, right, bottom = box["box"]
        if left < 0 or top < 0 or right > 1599 or bottom > 899:
            continue  # cut by the image edge: the labels hold the clipped box
        name, track, days = frame_of_instance[box["instance"]]
        labels = labels_of[name]
        seconds = (box["timestamp"] - days * nuscenes.DAY_US) / 1e6
        row = labels[(labels["id"] == track) & (np.isclose(labels["timestamp"], seconds, atol=5e-4))]
        prefix = "" if box["channel"] == "CAM_FRONT" else f"{box['channel']}_"
        ours = row[[f"{prefix}{c}" for c in ("left", "top", "right", "bottom")]].to_numpy(float)
        assert ours.shape == (1, 4)
        assert np.abs(ours[0] - [left, top, right, bottom]).max() <= 1.0, (box, ours)
        compared += 1
    assert compared > 40
    channels = {b["channel"] for b in report["camera_boxes"]}
    assert {"CAM_FRONT", "CAM_BACK"} <= channels


def test_the_rendered_sample_shows_every_channel_and_the_lidars_point_labels(export):
    rendered = export[2]["rendered"]
    cameras = ["CAM_FRONT", "CAM_FRONT_LEFT", "CAM_FRONT_RIGHT", "CAM_BACK", "CAM_BACK_LEFT", "CAM_BACK_RIGHT"]
    radars = ["RADAR_FRONT", "RADAR_FRONT_LEFT", "RADAR_FRONT_RIGHT", "RADAR_BACK_LEFT", "RADAR_BACK_RIGHT"]
    lidar = ["LIDAR_TOP", "LIDAR_TOP_lidarseg", "LIDAR_TOP_panoptic"]
    assert sorted(Path(p).stem for p in rendered) == sorted(["sample", *cameras, *radars, *lidar])
    assert all(cv2.imread(p) is not None for p in rendered)


def test_sensors_fire_at_their_own_rates_and_files_sit_where_the_tables_say(export):
    _, merged, _ = export
    data = [d for v in (nuscenes.VERSION, nuscenes.TEST_VERSION)
            for d in json.loads((merged / v / "sample_data.json").read_text())]  # fmt: skip
    sensors = {s["token"]: s["channel"] for s in json.loads((merged / nuscenes.VERSION / "sensor.json").read_text())}
    calibrated = json.loads((merged / nuscenes.VERSION / "calibrated_sensor.json").read_text())
    channel_of = {c["token"]: sensors[c["sensor_token"]] for c in calibrated}
    per_channel = Counter(channel_of[d["calibrated_sensor_token"]] for d in data)
    # 41 frames of 0.05 s per run: LiDAR 20 Hz -> 41, cameras 12 Hz -> 25, radars 13 Hz -> 27
    assert per_channel["LIDAR_TOP"] == 82 and per_channel["CAM_FRONT"] == 50 and per_channel["RADAR_FRONT"] == 54
    assert all((merged / d["filename"]).is_file() for d in data)
    keys = [d for d in data if d["is_key_frame"]]
    assert all(d["filename"].startswith("samples/") for d in keys) and len(keys) == 10 * 12
    points = np.fromfile(
        merged / next(d["filename"] for d in keys if d["fileformat"] == "pcd" and d["filename"].endswith(".bin")), "<f4"
    ).reshape(-1, 5)
    assert len(np.unique(points[:, 4])) > 16 and points[:, 4].max() <= 31  # HDL-32E rings


def test_the_kitti_preset_writes_kitti_sized_images_and_a_64_ring_cloud(tmp_path):
    from gtgen.load import iter_messages, lidar_points

    out = tmp_path / "kitti"
    run(load_scenario(str(DATA / "tiny.yaml"), ["rig=kitti", "frames=3"]), out, progress=False)
    training = out / "kitti" / "training"
    image = cv2.imread(str(training / "image_2" / "000000.png"))
    assert image.shape == (375, 1242, 3) and len(list((training / "velodyne").iterdir())) == 3
    assert_timed_object_points_lie_in_their_boxes(out)
    again = tmp_path / "again"  # the timed sweep with its drop by received power: same seed, same bytes
    run(load_scenario(str(DATA / "tiny.yaml"), ["rig=kitti", "frames=3"]), again, progress=False)
    assert (again / "labels.csv").read_bytes() == (out / "labels.csv").read_bytes()
    clouds = [m.data for *_, m in iter_raw(out / "run.mcap")]
    assert len(clouds) == 3 and [m.data for *_, m in iter_raw(again / "run.mcap")] == clouds
    assert cv2.imread(str(training / "image_3" / "000002.png")).shape == (375, 1242, 3)  # cam3
    calib = dict(line.split(": ", 1) for line in (training / "calib" / "000000.txt").read_text().splitlines())
    P2, P3 = (np.array(calib[k].split(), float).reshape(3, 4) for k in ("P2", "P3"))
    np.testing.assert_allclose(P3[:, :3], P2[:, :3])
    assert P3[0, 3] == pytest.approx(-0.53 * P3[0, 0], rel=1e-9) and P2[0, 3] == 0  # cam3 0.53 m right of cam2
    cloud = next(message for _, _, message in iter_messages(out / "run.mcap", ["/lidar"]))
    rings = np.unique(lidar_points(cloud)["ring"])
    assert rings.max() == 63 and len(rings) >= 60


def iter_raw(path: Path) -> list:
    from mcap.reader import make_reader

    with path.open("rb") as stream:
        return [(channel.topic, message) for _, channel, message in make_reader(stream).iter_messages()
                if channel.topic == "/lidar"]  # fmt: skip


def assert_timed_object_points_lie_in_their_boxes(out: Path) -> None:
    """The kitti preset's timed sweep: point times span the 10 Hz period, rising clockwise from
    behind, and every object point moved back by its object's motion relative to the ego over
    ``t - t_ref`` (t_ref: the sweep's middle, the frame's time) lies in its box within 2 cm."""
    from gtgen.load import iter_messages, lidar_points, objects_from_table
    from gtgen.objects import points_in_boxes

    labels = load_labels(out / "labels.csv")
    tagged_total, moved = 0, 0.0
    for frame, (_, _, cloud) in enumerate(iter_messages(out / "run.mcap", ["/lidar"])):
        pts = lidar_points(cloud)
        assert 0.0 <= pts["t"].min() < 0.002 and 0.098 < pts["t"].max() < 0.1
        turned = np.mod(np.pi - np.arctan2(pts["y"], pts["x"]), 2 * np.pi)
        column = np.round(turned / (2 * np.pi) * 2048) % 2048  # 2048 columns over 0.1 s, clockwise
        offset = pts["t"] - column * (0.1 / 2048)
        assert np.all((offset > -1e-6) & (offset < 0.1 / 2048))
        boxes, _ = objects_from_table(labels[labels["frame"] == frame])
        tagged = pts[pts["instance"] > 0]
        index = np.argsort(boxes.track_id)[
            np.searchsorted(boxes.track_id, tagged["instance"], sorter=np.argsort(boxes.track_id))
        ]
        dt = tagged["t"].astype(np.float64) - 0.05
        xyz = np.column_stack([tagged["x"], tagged["y"], tagged["z"] + 1.73])  # mount 1.73 m above the ego origin
        back = xyz - boxes.velocity_ego_mps[index] * dt[:, None]
        assert np.all(points_in_boxes(back, boxes, index, tolerance_m=0.02))
        tagged_total += len(tagged)
        moved = max(moved, float(np.abs(boxes.velocity_ego_mps[index] * dt[:, None]).max(initial=0.0)))
    assert tagged_total > 200 and moved > 0.1  # objects moved relative to the ego during sweeps
