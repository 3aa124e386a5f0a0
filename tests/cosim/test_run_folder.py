"""The run folder's lifecycle without SUMO: partial files, the disk check, the stop lines and
the counts a manifest and a resumed run read back."""

import shutil
from collections import namedtuple

import numpy as np
import pytest

from cosim.errors import CosimError, Terminated
from cosim.outputs import rig_specs, sink_choice
from cosim.run_folder import (
    RunSummary,
    check_disk_space,
    disk_check_frame,
    partials_removed_on_error,
    run_stopped,
)
from cosim.scenario import load_scenario
from gtgen.errors import OutputKeptError
from networks.vocabulary import SensorKind


def test_partials_go_when_the_block_fails_and_stay_when_the_outputs_are_kept(tmp_path):
    (tmp_path / "run.mcap.partial").write_bytes(b"x")
    (tmp_path / "kitti.partial").mkdir()
    with pytest.raises(OutputKeptError), partials_removed_on_error(tmp_path):
        raise OutputKeptError("disk full", disk_full=True)
    assert (tmp_path / "run.mcap.partial").exists()
    with pytest.raises(RuntimeError), partials_removed_on_error(tmp_path):
        raise RuntimeError("boom")
    assert not list(tmp_path.glob("*.partial"))


def test_a_run_that_will_not_fit_stops_with_one_line(tmp_path, monkeypatch):
    (tmp_path / "run.mcap.partial").write_bytes(b"x" * 1_000_000)
    usage = namedtuple("usage", "total used free")
    monkeypatch.setattr(shutil, "disk_usage", lambda path: usage(10**9, 10**9 - 10**6, 10**6))
    with pytest.raises(CosimError, match=r"about 33 MB in all \(from its first 30 frames\), 1 MB free"):
        check_disk_space(tmp_path, 33, 1000)
    assert disk_check_frame(1000) == 30 and disk_check_frame(7) == -1


def test_stop_lines_name_the_frames_kept_and_the_exit_code(tmp_path):
    line = run_stopped(KeyboardInterrupt(), tmp_path, 12)
    assert line.exit_code == 130 and "interrupted at frame 12" in str(line) and "frames 0 to 11" in str(line)
    assert run_stopped(Terminated(), tmp_path, 3, in_summary=True).exit_code == 143


def test_the_counts_read_back_as_they_were_written():
    counts = RunSummary(frames=3, objects=7, seen=5, scene_cuts=[2], ego_stopped=1)
    counts.per_class.update({"car": 4, "pedestrian": 1})
    assert RunSummary.from_dict(counts.to_dict()) == counts


def test_the_outputs_name_each_sensor_by_its_kind_and_the_deskewing_lidars(tmp_path):
    scenario = load_scenario("town05_crowded", overrides=["sensors.lidars=[{name: top, deskew: true}]"])
    kinds = [kind for kind, _ in rig_specs(scenario)]
    assert kinds[0] is SensorKind.LIDAR and set(kinds) <= set(SensorKind)
    choice = sink_choice(scenario, tmp_path)
    assert choice.deskewed == ("top",) and ("lidar", "top") in choice.sensors
    assert np.all([isinstance(k, SensorKind) for k, _ in choice.sensors])
