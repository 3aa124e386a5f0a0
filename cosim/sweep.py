"""Sweeps: one scenario over traffic densities (or vehicle counts) and seeds.

Each run is a separate process (libsumo runs one simulation per process): local processes
by default, or the workers of a Dask cluster given its scheduler address. Every run writes a
complete dataset under ``<out>/<run name>/``; ``<out>/sweep.csv`` gets one row per run (its
settings, frames, objects per frame, seconds, the frames kept from an earlier attempt, the
attempts, and the error if it failed), rewritten as runs finish.

A sweep started again over the same folder skips the runs that are complete, continues the
ones that were stopped (``--resume`` of each), and runs the rest. A run whose process dies
(killed, out of memory) is tried once more, continuing from what it kept, before its row says
it failed. Ctrl-C or SIGTERM to the sweep reaches each running run once (they run in sessions
of their own), which stops and keeps its frames; their rows join ``sweep.csv``.
"""

from __future__ import annotations

import contextlib
import csv
import itertools
import json
import multiprocessing
import os
import signal
import time
from collections.abc import Callable, Iterable
from dataclasses import asdict, dataclass
from multiprocessing.connection import Connection, wait
from multiprocessing.process import BaseProcess
from pathlib import Path
from typing import Any

from cosim.errors import CosimError, RunStoppedError, ScenarioError, Terminated
from cosim.interrupts import interrupt_behind
from cosim.scenario import load_scenario
from gtgen.errors import GtgenError
from networks.errors import NetworkError
from sensors.errors import SensorError

STOP_WAIT_S = 60.0  # for a stopped run to close its files and report


@dataclass(frozen=True, slots=True)
class SweepJob:
    name: str
    scenario: str
    overrides: tuple[str, ...]
    out_dir: str
    density: float | None
    vehicles: int | None
    seed: int
    hazard_scale: float | None = None


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
    kept_frames: int = 0  # frames kept from an earlier attempt (all of them: complete before)
    attempts: int = 1


def plan(
    scenario: str,
    out_root: Path,
    densities: Iterable[float] = (),
    vehicle_counts: Iterable[int] = (),
    seeds: Iterable[int] = (0,),
    overrides: Iterable[str] = (),
    hazard_scales: Iterable[float] = (),
) -> list[SweepJob]:
    """The runs of a sweep, validated: a bad key or value fails here, before any run starts.
    ``hazard_scales`` multiply the rate of every hazard of the scenario (``per_minute``)."""
    densities, vehicle_counts, seeds = list(densities), list(vehicle_counts), list(seeds)
    if densities and vehicle_counts:
        raise ScenarioError("sweep: give densities or vehicle counts, not both")
    levels: list[tuple[float | None, int | None]] = [(d, None) for d in densities] + [(None, v) for v in vehicle_counts]
    jobs = []
    base = load_scenario(scenario, list(overrides))
    scales: list[float | None] = list(hazard_scales) or [None]
    if scales != [None] and not base.hazards:
        raise ScenarioError(f"sweep: --hazard-scale: the scenario {base.name} has no hazards to scale")
    for (density, vehicles), scale, seed in itertools.product(levels or [(None, None)], scales, seeds):
        extra = [f"seed={seed}"]
        label = f"s{seed}"
        if scale is not None:
            if scale <= 0:
                raise ScenarioError(f"sweep: --hazard-scale: expected factors > 0, got {scale:g}")
            scaled = [{**asdict(h), "per_minute": h.per_minute * scale} for h in base.hazards]
            extra.append("hazards=" + json.dumps(scaled))
            label = f"h{scale:g}-{label}"
        if density is not None:
            extra.append(f"traffic.vehicles_per_lane_km={density}")
            label = f"d{density:g}-{label}"
        if vehicles is not None:
            extra.append(f"traffic.vehicles={vehicles}")
            label = f"v{vehicles}-{label}"
        all_overrides = (*overrides, *extra)
        load_scenario(scenario, list(all_overrides))  # validates every run's settings up front
        name = f"{base.name}-{label}"
        jobs.append(SweepJob(name, scenario, all_overrides, str(out_root / name), density, vehicles, seed, scale))
    return jobs


def run_job(job: SweepJob, attempt: int = 1) -> SweepResult:
    """Run one dataset (in a worker process), or continue it, or report it complete; failures
    come back as a one-line error."""
    from cosim.loop import run  # imported in the worker: libsumo and Open3D start there
    from cosim.resume import AlreadyCompleteError, complete_run, resume_point

    start, out = time.perf_counter(), Path(job.out_dir)
    kept = 0
    try:
        scenario = load_scenario(job.scenario, list(job.overrides))
        if complete_run(out, scenario) is not None:
            return _done_before(job, time.perf_counter() - start)
        resume = (out / ".resume").exists()
        if resume:
            point = resume_point(out, scenario)
            kept = 0 if point is None else point.frames
        summary = run(scenario, out, progress=False, resume=resume, summary=True)
    except AlreadyCompleteError:
        return _done_before(job, time.perf_counter() - start)
    except (Exception, KeyboardInterrupt, Terminated) as err:  # the sweep goes on; the row records what failed
        frames = err.kept if isinstance(err, RunStoppedError) else 0
        return SweepResult(job.name, job.density, job.vehicles, job.seed, frames, 0.0, 0.0,
                           time.perf_counter() - start, _error_line(err), kept, attempt)  # fmt: skip
    n = max(summary.frames, 1)
    return SweepResult(job.name, job.density, job.vehicles, job.seed, summary.frames, summary.objects / n,
                       summary.seen / n, time.perf_counter() - start, "", kept, attempt)  # fmt: skip


def _done_before(job: SweepJob, seconds: float) -> SweepResult:
    manifest = json.loads((Path(job.out_dir) / "manifest.json").read_text())
    frames = int(manifest["frames"])
    return SweepResult(job.name, job.density, job.vehicles, job.seed, frames, float(manifest["objects_per_frame"]),
                       float(manifest.get("seen_per_frame", 0.0)), seconds, "", frames, 0)  # fmt: skip


def _error_line(err: BaseException) -> str:
    from gtgen.crash import internal_error_line

    if interrupt_behind(err) is not None:
        return "interrupted before its first frame; it kept nothing"
    if isinstance(err, CosimError | NetworkError | SensorError | GtgenError):
        return str(err).splitlines()[0]
    return internal_error_line(err, "the run")


def _terminate(signum: int, frame: object) -> None:
    raise Terminated


def _work(job: SweepJob, attempt: int, conn: Connection) -> None:  # runs in a worker process
    """Run the job in a session of its own (a terminal's Ctrl-C reaches the sweep, which passes
    it on once) and send its result; SIGTERM stops the run as Ctrl-C does."""
    os.setsid()
    signal.signal(signal.SIGTERM, _terminate)
    result = run_job(job, attempt)
    with contextlib.suppress(OSError):  # the sweep has gone: nobody is left to tell
        conn.send(result)


@dataclass(slots=True)
class _Running:
    job: SweepJob
    attempt: int
    process: BaseProcess
    conn: Connection


def run_local(jobs: list[SweepJob], workers: int, on_result: Callable[[SweepResult], None]) -> list[SweepResult]:
    """Up to ``workers`` runs at once, each in a new process; a run whose process dies without
    a result is tried once more. Ctrl-C or SIGTERM stops the runs (each keeps its frames and
    reports, through ``on_result``) and then the sweep (the signal's exception is raised again)."""
    context = multiprocessing.get_context("spawn")
    queue = [(job, 1) for job in jobs]
    running: list[_Running] = []
    results: dict[str, SweepResult] = {}
    try:
        while queue or running:
            while queue and len(running) < workers:
                job, attempt = queue.pop(0)
                parent, child = context.Pipe(duplex=False)
                process = context.Process(target=_work, args=(job, attempt, child), name=f"sweep-{job.name}")
                process.start()
                child.close()
                running.append(_Running(job, attempt, process, parent))
            ready = wait([r.process.sentinel for r in running] + [r.conn for r in running])
            for r in [r for r in running if r.process.sentinel in ready or r.conn in ready]:
                result = _collect(r)
                running.remove(r)
                if result is None and r.attempt == 1:
                    queue.insert(0, (r.job, 2))  # died: once more, continuing from what it kept
                    continue
                result = result or _died(r)
                results[r.job.name] = result
                on_result(result)
    except (KeyboardInterrupt, Terminated) as err:
        _stop(running, signal.SIGINT if isinstance(err, KeyboardInterrupt) else signal.SIGTERM, on_result)
        raise
    return [results[job.name] for job in jobs if job.name in results]


def _collect(r: _Running) -> SweepResult | None:
    """The run's result, once its process has sent it and ended (None: it died without one)."""
    result: SweepResult | None = None
    try:
        if r.conn.poll(5.0):
            result = r.conn.recv()
    except (EOFError, OSError):
        result = None
    r.process.join()
    r.conn.close()
    return result


def _died(r: _Running) -> SweepResult:
    code = r.process.exitcode
    line = f"the run's process died twice (last exit code {code}); it keeps what it wrote: sweep again to continue"
    return SweepResult(r.job.name, r.job.density, r.job.vehicles, r.job.seed, 0, 0.0, 0.0, 0.0, line, 0, r.attempt)


def _stop(running: list[_Running], signum: int, on_result: Callable[[SweepResult], None]) -> None:
    """Pass the sweep's Ctrl-C or SIGTERM on to the runs: each closes its files with its frames
    and its result goes to ``on_result``."""
    for r in running:
        if r.process.pid is not None and r.process.is_alive():
            os.kill(r.process.pid, signum)
    for r in running:
        if r.conn.poll(STOP_WAIT_S):
            result = _collect(r)
            if result is not None:
                on_result(result)
        r.process.join(5.0)
        if r.process.is_alive():
            r.process.kill()
            r.process.join()


def run_dask(jobs: list[SweepJob], scheduler: str, on_result: Callable[[SweepResult], None]) -> list[SweepResult]:
    try:
        from distributed import Client, as_completed
    except ImportError as err:
        raise CosimError("sweep --scheduler needs Dask: pip install 'sumo-dataset-factory[dask]'") from err
    with Client(scheduler) as client:
        futures = client.map(run_job, jobs, pure=False, retries=1)
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
