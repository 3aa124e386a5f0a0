"""Sweeps: one process per run, locally or on a Dask cluster."""

import csv
import json
import subprocess
import sys
from pathlib import Path

import pytest

from cosim.errors import ScenarioError
from cosim.sweep import plan, run_dask

ROOT = Path(__file__).resolve().parents[2]
TINY = str(ROOT / "tests" / "data" / "tiny.yaml")
FAST = ["frames=4", "outputs.kitti=false", "outputs.yolo=false", "sensors.cameras=[]"]


def test_plan_crosses_levels_and_seeds_and_validates_up_front(tmp_path):
    jobs = plan(TINY, tmp_path, densities=[5, 10], seeds=[1, 2, 3], overrides=FAST)
    assert len(jobs) == 6 and len({j.out_dir for j in jobs}) == 6
    assert "traffic.vehicles_per_lane_km=10" in jobs[-1].overrides and "seed=3" in jobs[-1].overrides
    with pytest.raises(ScenarioError, match="frames"):
        plan(TINY, tmp_path, seeds=[1], overrides=["frames=0"])


@pytest.mark.slow
def test_local_sweep_writes_a_dataset_per_run_and_a_table(tmp_path):
    cmd = [sys.executable, "-m", "cosim", "sweep", TINY, "--vehicles", "10", "60", "--seed", "4", "--workers", "2",
           "--out", str(tmp_path)] + [a for o in FAST for a in ("--set", o)]  # fmt: skip
    proc = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT, check=False)
    assert proc.returncode == 0, proc.stderr
    rows = list(csv.DictReader((tmp_path / "sweep.csv").open()))
    assert [r["name"] for r in rows] == ["tiny-v10-s4", "tiny-v60-s4"]
    assert all(r["error"] == "" and r["frames"] == "4" for r in rows)
    assert float(rows[1]["objects_per_frame"]) > float(rows[0]["objects_per_frame"])
    for r in rows:
        assert (tmp_path / r["name"] / "manifest.json").exists()


@pytest.mark.slow
def test_dask_sweep_runs_on_the_cluster_workers(tmp_path):
    from distributed import LocalCluster

    jobs = plan(TINY, tmp_path, vehicle_counts=[15], seeds=[2], overrides=FAST)
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        results = run_dask(jobs, cluster.scheduler_address, lambda r: None)
    assert results[0].error == "" and results[0].frames == 4
    assert (tmp_path / jobs[0].name / "labels.csv").exists()


def sweep_cmd(out: Path, seeds: list[int], frames: int = 40) -> list[str]:
    overrides = [f"frames={frames}", "outputs.kitti=false", "outputs.yolo=false", "sensors.cameras=[]"]
    return [sys.executable, "-m", "cosim", "sweep", TINY, "--seed", *map(str, seeds), "--workers", "1", "--out",
            str(out)] + [a for o in overrides for a in ("--set", o)]  # fmt: skip


def wait_for_frames(out: Path, frames: int, proc: subprocess.Popen) -> None:
    import time

    states = out / ".resume" / "states.jsonl"
    deadline = time.monotonic() + 240
    while proc.poll() is None and time.monotonic() < deadline:
        if states.exists() and states.read_text().count("\n") >= frames:
            return
        time.sleep(0.05)
    raise AssertionError(f"{out}: no {frames} frames written")


@pytest.mark.slow
def test_a_sweep_stopped_in_its_second_run_and_started_again_redoes_only_the_second(tmp_path):
    """The run before is complete and skipped, the stopped one continued, the one after made.
    Each run long enough (160 frames) that the stop, sent once 10 frames are recorded, lands
    before the loop's end (with 40 a fast machine had finished them all by then)."""
    import signal

    frames = 160
    cmd = sweep_cmd(tmp_path, [1, 2, 3], frames)
    proc = subprocess.Popen(cmd, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    wait_for_frames(tmp_path / "tiny-s2", 10, proc)
    proc.send_signal(signal.SIGINT)
    proc.communicate(timeout=120)
    assert proc.returncode == 130
    first = (tmp_path / "tiny-s1" / "labels.csv").stat().st_mtime_ns
    again = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, check=False)
    assert again.returncode == 0, again.stderr
    rows = {r["name"]: r for r in csv.DictReader((tmp_path / "sweep.csv").open())}
    assert [rows[f"tiny-s{s}"]["error"] for s in (1, 2, 3)] == [""] * 3
    assert rows["tiny-s1"]["kept_frames"] == str(frames)  # complete: skipped
    assert 0 < int(rows["tiny-s2"]["kept_frames"]) < frames and rows["tiny-s3"]["kept_frames"] == "0"
    assert (tmp_path / "tiny-s1" / "labels.csv").stat().st_mtime_ns == first
    for s in (1, 2, 3):
        manifest = json.loads((tmp_path / f"tiny-s{s}" / "manifest.json").read_text())
        assert manifest["complete"] is True and manifest["frames"] == frames


@pytest.mark.slow
def test_a_run_whose_process_dies_is_tried_once_more_and_continues(tmp_path):
    import os
    import signal

    proc = subprocess.Popen(
        sweep_cmd(tmp_path, [5], frames=60), cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE
    )
    wait_for_frames(tmp_path / "tiny-s5", 20, proc)
    workers = [int(p) for t in Path(f"/proc/{proc.pid}/task").glob("*/children") for p in t.read_text().split()]
    worker = next(p for p in workers if b"spawn_main" in Path(f"/proc/{p}/cmdline").read_bytes())
    os.kill(worker, signal.SIGKILL)
    proc.communicate(timeout=240)
    assert proc.returncode == 0
    (row,) = csv.DictReader((tmp_path / "sweep.csv").open())
    assert row["error"] == "" and row["attempts"] == "2" and int(row["kept_frames"]) >= 20
    assert json.loads((tmp_path / "tiny-s5" / "manifest.json").read_text())["frames"] == 60


def test_a_sweep_scales_the_rates_of_the_scenarios_hazards(tmp_path):
    from cosim.scenario import load_scenario
    from cosim.sweep import plan

    jobs = plan("town06_cut_ins", tmp_path, seeds=[1], hazard_scales=[0.5, 2])
    assert [j.name for j in jobs] == ["town06_cut_ins-h0.5-s1", "town06_cut_ins-h2-s1"]
    rates = [load_scenario(j.scenario, list(j.overrides)).hazards[0].per_minute for j in jobs]
    assert rates == [1.5, 6.0]  # the catalog asks 3 a minute
    with pytest.raises(ScenarioError, match="has no hazards to scale"):
        plan("town05_crowded", tmp_path, hazard_scales=[2])
