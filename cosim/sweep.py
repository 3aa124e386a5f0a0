"""Sweeps: one scenario over traffic densities (or vehicle counts) and seeds.

Each run is a separate process (libsumo runs one simulation per process): a local process
pool by default, or the workers of a Dask cluster given its scheduler address. Every run
writes a complete dataset under ``<out>/<run name>/``; ``<out>/sweep.csv`` gets one row per
run (its settings, frames, objects per frame, seconds, and the error if it failed).
"""

from __future__ import annotations

import csv
import itertools
import multiprocessing
import time
from collections.abc import Callable, Iterable
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from cosim.errors import CosimError, ScenarioError
from cosim.scenario import load_scenario


@dataclass(frozen=True, slots=True)
class SweepJob:
    name: str
    scenario: str
    overrides: tuple[str, ...]
    out_dir: str
    density: float | None
    vehicles: int | None
    seed: int


@dataclass(frozen=True, slots=True)
class SweepResult:
    name: str
    density: float | None
    vehicles: int | None
    seed: int
    frames: int
    objects_per_frame: float
    seen_per_frame: float
    seconds: float
    error: str


def plan(
    scenario: str,
    out_root: Path,
    densities: Iterable[float] = (),
    vehicle_counts: Iterable[int] = (),
    seeds: Iterable[int] = (0,),
    overrides: Iterable[str] = (),
) -> list[SweepJob]:
    """The runs of a sweep, validated: a bad key or value fails here, before any run starts."""
    densities, vehicle_counts, seeds = list(densities), list(vehicle_counts), list(seeds)
    if densities and vehicle_counts:
        raise ScenarioError("sweep: give densities or vehicle counts, not both")
    levels: list[tuple[float | None, int | None]] = [(d, None) for d in densities] + [(None, v) for v in vehicle_counts]
    jobs = []
    base = load_scenario(scenario, list(overrides))
    for (density, vehicles), seed in itertools.product(levels or [(None, None)], seeds):
        extra = [f"seed={seed}"]
        label = f"s{seed}"
        if density is not None:
            extra.append(f"traffic.vehicles_per_lane_km={density}")
            label = f"d{density:g}-{label}"
        if vehicles is not None:
            extra.append(f"traffic.vehicles={vehicles}")
            label = f"v{vehicles}-{label}"
        all_overrides = (*overrides, *extra)
        load_scenario(scenario, list(all_overrides))  # validates every run's settings up front
        name = f"{base.name}-{label}"
        jobs.append(SweepJob(name, scenario, all_overrides, str(out_root / name), density, vehicles, seed))
    return jobs


def run_job(job: SweepJob) -> SweepResult:
    """Run one dataset (in a worker process); failures come back as a one-line error."""
    from cosim.loop import run  # imported in the worker: libsumo and Open3D start there
    from gtgen.summary import write_summary

    start = time.perf_counter()
    try:
        summary = run(load_scenario(job.scenario, list(job.overrides)), Path(job.out_dir), progress=False)
        write_summary(Path(job.out_dir))
    except Exception as err:  # the sweep goes on; the row records what failed
        return SweepResult(job.name, job.density, job.vehicles, job.seed, 0, 0.0, 0.0,
                           time.perf_counter() - start, f"{type(err).__name__}: {err}".splitlines()[0])  # fmt: skip
    n = max(summary.frames, 1)
    return SweepResult(job.name, job.density, job.vehicles, job.seed, summary.frames, summary.objects / n,
                       summary.seen / n, time.perf_counter() - start, "")  # fmt: skip


def run_local(jobs: list[SweepJob], workers: int, on_result: Callable[[SweepResult], None]) -> list[SweepResult]:
    context = multiprocessing.get_context("spawn")
    results = []
    with ProcessPoolExecutor(max_workers=workers, mp_context=context, max_tasks_per_child=1) as pool:
        for result in pool.map(run_job, jobs):
            on_result(result)
            results.append(result)
    return results


def run_dask(jobs: list[SweepJob], scheduler: str, on_result: Callable[[SweepResult], None]) -> list[SweepResult]:
    try:
        from distributed import Client, as_completed
    except ImportError as err:
        raise CosimError("sweep --scheduler needs Dask: pip install 'sumo-dataset-factory[dask]'") from err
    with Client(scheduler) as client:
        futures = client.map(run_job, jobs, pure=False)
        results = []
        for future in as_completed(futures):
            result = future.result()
            on_result(result)
            results.append(result)
    order = {job.name: i for i, job in enumerate(jobs)}
    return sorted(results, key=lambda r: order[r.name])


def write_table(results: list[SweepResult], path: Path) -> None:
    rows: list[dict[str, Any]] = [asdict(r) for r in results]
    with path.open("w", newline="", encoding="utf-8") as f:
        writer = csv.DictWriter(f, fieldnames=list(SweepResult.__dataclass_fields__))
        writer.writeheader()
        writer.writerows(rows)
