"""Sweeps: one process per run, locally or on a Dask cluster."""

import csv
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
