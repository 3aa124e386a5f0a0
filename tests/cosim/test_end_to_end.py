"""A short scene on the skeleton grid, written and read back."""

from collections import defaultdict
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader

from cosim.loop import run
from cosim.scenario import load_scenario
from gtgen.load import iter_messages, lidar_points, load_labels
from gtgen.objects import ObjectBoxes, points_in_boxes
from gtgen.table import REFERENCE_COLUMNS

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
    expected = {"/tf", "/lidar", "/radar", "/gt/boxes", "/gt/labels"} | {
        f"/camera/{k}" for k in ("image", "depth", "instance", "class", "calibration", "annotations")
    }
    assert all(topics == expected for topics in topics_per_time.values())


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
        boxes = ObjectBoxes(
            rows["id"].to_numpy(),
            rows["class_id"].to_numpy(),
            rows[["x", "y", "z"]].to_numpy(),
            rows[["l", "w", "h"]].to_numpy(),
            rows["rotation_z"].to_numpy(),
            rows[["vx", "vy", "vz"]].to_numpy(),
            rows["parked"].to_numpy().astype(bool),
        )
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
    run(load_scenario(str(DATA / "tiny.yaml")), tmp_path, progress=False)
    assert (tmp_path / "labels.csv").read_bytes() == (dataset / "labels.csv").read_bytes()
    assert raw_messages(tmp_path / "run.mcap") == raw_messages(dataset / "run.mcap")


def raw_messages(path: Path) -> list[tuple[str, int, bytes]]:
    with path.open("rb") as stream:
        return [(c.topic, m.log_time, m.data) for _, c, m in make_reader(stream).iter_messages()]
