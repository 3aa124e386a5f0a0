"""The frame loop with its traffic and writer processes and its timing probe, on the tiny scene."""

import subprocess
import sys
from pathlib import Path

import pytest
from mcap.reader import make_reader

from cosim.errors import TrafficError
from cosim.loop import run
from cosim.scenario import load_scenario
from gtgen.timing import StageTimes

DATA = Path(__file__).resolve().parents[1] / "data"
pytestmark = pytest.mark.slow


def dataset_files(folder: Path) -> dict[str, bytes]:
    """Every output file's bytes (MCAP as its messages; YOLO's data.yaml names its folder)."""
    out = {}
    for path in sorted(folder.rglob("*")):
        name = str(path.relative_to(folder))
        if path.is_file() and path.name not in ("data.yaml", "manifest.json", "run.mcap"):
            out[name] = path.read_bytes()
    with (folder / "run.mcap").open("rb") as stream:
        messages = [(c.topic, m.log_time, m.data) for _, c, m in make_reader(stream).iter_messages()]
    out["run.mcap messages"] = repr(messages).encode()
    return out


def test_outputs_are_identical_with_and_without_the_traffic_and_writer_processes(tmp_path):
    scenario = load_scenario(str(DATA / "tiny.yaml"), ["frames=8"])
    run(scenario, tmp_path / "inline", progress=False, one_process=True)
    run(scenario, tmp_path / "process", progress=False)
    inline = dataset_files(tmp_path / "inline")
    assert any(name.startswith("kitti/training/image_2/") for name in inline)
    assert dataset_files(tmp_path / "process") == inline


class RecordingProbe(StageTimes):
    def __init__(self) -> None:
        super().__init__()
        self.scenes: list[int] = []
        self.done: list[int] = []

    def scene(self, frame_index, scene, map_SE3_ego):
        self.scenes.append(frame_index)

    def frame_done(self, frame_index):
        self.done.append(frame_index)


def test_the_probe_sees_every_stage_of_every_frame(tmp_path):
    probe = RecordingProbe()
    run(load_scenario(str(DATA / "tiny.yaml"), ["frames=5"]), tmp_path, progress=False, probe=probe)
    per_frame = ("sumo wait", "scene", "lidar", "camera", "radar", "labels", "handoff")
    assert all(probe.calls[name] == 5 for name in per_frame)
    from_helpers = ("writer encode", "writer write")  # added when they close
    assert all(probe.calls[name] == 5 for name in from_helpers) and probe.calls["close"] == 1
    assert probe.calls["sumo step"] == probe.calls["world state"] == 6  # the traffic reads one step ahead
    assert probe.scenes == [0, 1, 2, 3, 4] and probe.done == [-1, 0, 1, 2, 3, 4, 5]


def test_a_writer_failure_is_one_line_on_the_command_line_and_no_dataset_is_left(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / "kitti.partial").write_text("a file where the KITTI folder goes")
    cmd = [sys.executable, "-m", "cosim", "run", str(DATA / "tiny.yaml"), "--frames", "5", "--out", str(out),
           "--no-progress", "--no-summary"]  # fmt: skip
    result = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    assert result.returncode == 2
    assert result.stderr.strip().startswith("error: writer process: ")
    assert len(result.stderr.strip().splitlines()) == 1, result.stderr
    assert sorted(p.name for p in out.iterdir()) == []


def test_a_traffic_error_in_the_traffic_process_is_raised_here_and_no_dataset_is_left(tmp_path):
    scenario = load_scenario(str(DATA / "tiny.yaml"), ["frames=5", "ego.route=[no_such_edge]"])
    with pytest.raises(TrafficError, match=r"^ego\.route: SUMO refused the ego's route") as err:
        run(scenario, tmp_path, progress=False)
    assert "\n" not in str(err.value)
    assert sorted(p.name for p in tmp_path.iterdir()) == []
