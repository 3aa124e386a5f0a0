"""Command line: ``python -m cosim run|list``."""

from __future__ import annotations

import argparse
import json
import os
import signal
import sys
import threading
from pathlib import Path

from cosim.errors import CosimError, RunStoppedError, Terminated
from cosim.interrupts import interrupt_behind
from cosim.sweep import SweepResult
from gtgen.crash import internal_error_line
from gtgen.errors import GtgenError
from networks.errors import NetworkError, clipped
from sensors.errors import SensorError

DEFAULT_WORKERS = max(1, (os.cpu_count() or 2) // 2)
USER_ERRORS = (CosimError, NetworkError, SensorError, GtgenError)


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="python -m cosim", description="SUMO-driven perception dataset factory")
    sub = parser.add_subparsers(dest="command", required=True, metavar="{run,list,sweep}")
    run = sub.add_parser("run", help="simulate a scenario and write its dataset")
    run.add_argument("scenario", help="a built-in scenario name (see `list`) or a path to a scenario .yaml")
    run.add_argument("--frames", type=int, help="number of frames (overrides the scenario)")
    run.add_argument("--seed", type=int, help="random seed (overrides the scenario)")
    run.add_argument("--out", type=Path, help="output folder (default: out/<scenario>)")
    run.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                     help="override any scenario key, e.g. --set traffic.pedestrians=50 (repeatable)")  # fmt: skip
    run.add_argument(
        "--resume",
        action="store_true",
        help="continue the interrupted run in --out from the last frame it kept (the same scenario)",
    )
    run.add_argument("--no-progress", action="store_true", help="no progress bar")
    run.add_argument("--no-summary", action="store_true", help="skip the summary/ statistics and pictures")
    run.add_argument("--live", nargs="?", const="127.0.0.1:8765", metavar="[HOST:]PORT",
                     help="also serve the frames to Foxglove over a WebSocket (default 127.0.0.1:8765)")  # fmt: skip
    sub.add_parser("list", help="list the built-in scenarios")
    sweep = sub.add_parser("sweep", help="run a scenario over traffic densities and seeds, one process per run")
    sweep.add_argument("scenario", help="a built-in scenario name or a path to a scenario .yaml")
    sweep.add_argument("--density", type=float, nargs="+", default=[], metavar="VEH_PER_LANE_KM")
    sweep.add_argument("--vehicles", type=int, nargs="+", default=[], metavar="COUNT")
    sweep.add_argument("--seed", type=int, nargs="+", default=[0], metavar="SEED")
    sweep.add_argument("--hazard-scale", type=float, nargs="+", default=[], metavar="FACTOR",
                       help="multiply the rate of the scenario's hazards by each factor")  # fmt: skip
    sweep.add_argument("--frames", type=int, help="frames per run (overrides the scenario)")
    sweep.add_argument("--out", type=Path, help="output folder (default: out/<scenario>-sweep)")
    workers_help = f"runs at once on this machine (default {DEFAULT_WORKERS}: a run keeps about two cores busy)"
    sweep.add_argument("--workers", type=int, default=DEFAULT_WORKERS, help=workers_help)
    sweep.add_argument("--scheduler", help="a Dask scheduler address (tcp://host:8786) instead of local processes")
    sweep.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE")
    return parser


def _cmd_list() -> int:
    from cosim.scenario import catalog_description, catalog_names

    for name in catalog_names():
        print(f"{name:18s} {catalog_description(name)}")
    return 0


def _cmd_run(args: argparse.Namespace) -> int:
    from cosim.loop import run
    from cosim.resume import AlreadyCompleteError
    from cosim.scenario import load_scenario
    from gtgen.summary import hazard_lines

    overrides = list(args.overrides)
    if args.frames is not None:
        overrides.append(f"frames={args.frames}")
    if args.seed is not None:
        overrides.append(f"seed={args.seed}")
    if args.live is not None:
        overrides.append(f"outputs.live={json.dumps(args.live)}")  # a YAML string, whatever it holds
    scenario = load_scenario(args.scenario, overrides)
    out_dir = args.out if args.out is not None else Path("out") / scenario.name
    try:
        summary = run(scenario, out_dir, progress=not args.no_progress, resume=args.resume, summary=not args.no_summary)
    except AlreadyCompleteError as done:
        print(f"nothing to do: {done}")
        return 0
    print(f"wrote {out_dir}/")
    for line in [*summary.lines(), *hazard_lines(out_dir)]:
        print(line)
    return 0


def _cmd_sweep(args: argparse.Namespace) -> int:
    from cosim.errors import ScenarioError
    from cosim.scenario import resolve
    from cosim.sweep import plan, run_dask, run_local, write_table

    if args.workers < 1:
        raise ScenarioError(f"sweep: --workers: expected a whole number >= 1, got {args.workers}")
    overrides = list(args.overrides) + ([f"frames={args.frames}"] if args.frames is not None else [])
    out_root = args.out if args.out is not None else Path("out") / f"{resolve(args.scenario).stem}-sweep"
    jobs = plan(args.scenario, out_root, args.density, args.vehicles, args.seed, overrides, args.hazard_scale)
    out_root.mkdir(parents=True, exist_ok=True)

    print(f"sweep: {len(jobs)} runs into {out_root}/", flush=True)
    done: list[SweepResult] = []

    def report(result: SweepResult) -> None:
        done.append(result)
        write_table(done, out_root / "sweep.csv")  # the table so far: a stopped sweep has one too
        status = f"error: {result.error}" if result.error else f"{result.seen_per_frame:.1f} seen objects/frame"
        if not result.error and result.kept_frames == result.frames:
            status = "complete before, skipped"
        elif not result.error and result.kept_frames:
            status += f", continued from frame {result.kept_frames}"
        print(f"{result.name}: {result.frames} frames in {result.seconds:.0f} s, {status}", flush=True)

    try:
        results = run_dask(jobs, args.scheduler, report) if args.scheduler else run_local(jobs, args.workers, report)
    except (KeyboardInterrupt, Terminated) as err:
        write_table(done, out_root / "sweep.csv")
        word, code = ("interrupted", 130) if isinstance(err, KeyboardInterrupt) else ("stopped (SIGTERM)", 143)
        runs = f"{len(done)} run{'' if len(done) == 1 else 's'}"
        print(f"{word}; {out_root}/sweep.csv lists the {runs} that ended ({_tally(done)}); "
              "start the same sweep again to continue", file=sys.stderr)  # fmt: skip
        return code
    write_table(results, out_root / "sweep.csv")
    failed = [r for r in results if r.error]
    print(f"wrote {out_root}/sweep.csv ({len(results) - len(failed)} runs done, {len(failed)} failed)")
    return 1 if failed else 0


def _tally(results: list[SweepResult]) -> str:
    """How the runs of a stopped sweep ended, in words."""
    stopped = sum(1 for r in results if r.error.startswith(("interrupted", "stopped (SIGTERM)")))
    failed = sum(1 for r in results if r.error) - stopped
    return (
        f"{len(results) - stopped - failed} complete, {stopped} stopped part-way keeping the frames they "
        f"wrote, {failed} failed"
    )


def _terminate(signum: int, frame: object) -> None:
    raise Terminated


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGTERM, _terminate)  # a run stopped this way keeps its frames, as with Ctrl-C
    try:
        commands = {"list": lambda: _cmd_list(), "run": lambda: _cmd_run(args), "sweep": lambda: _cmd_sweep(args)}
        return commands[args.command]()
    except RunStoppedError as stopped:
        print(clipped(f"error: {stopped}" if stopped.exit_code == 2 else str(stopped)), file=sys.stderr)
        return stopped.exit_code
    except USER_ERRORS as err:
        print(clipped(f"error: {err}"), file=sys.stderr)
        return 2
    except (KeyboardInterrupt, Terminated, SystemError) as err:
        cause = interrupt_behind(err)
        if cause is None:
            return _internal_error(err, args.command)
        word, code = ("interrupted", 130) if isinstance(cause, KeyboardInterrupt) else ("stopped (SIGTERM)", 143)
        print(f"{word}; no dataset was completed", file=sys.stderr)
        return code
    except OSError as err:
        if err.filename is None or not err.strerror:
            return _internal_error(err, args.command)
        print(clipped(f"error: {err.filename}: {err.strerror}"), file=sys.stderr)
        return 2
    except Exception as err:
        return _internal_error(err, args.command)


def _internal_error(err: BaseException, command: str) -> int:
    """An unforeseen failure: one line, the traceback in a crash report, exit code 3."""
    print(f"error: {internal_error_line(err, f'cosim {command}')}", file=sys.stderr)
    return 3
