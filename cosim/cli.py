"""Command line: ``python -m cosim run|list``."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from cosim.errors import CosimError
from gtgen.errors import GtgenError
from networks.errors import NetworkError
from sensors.errors import SensorError

USER_ERRORS = (CosimError, NetworkError, SensorError, GtgenError)


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="python -m cosim", description="SUMO-driven perception dataset factory")
    sub = parser.add_subparsers(dest="command", required=True, metavar="{run,list}")
    run = sub.add_parser("run", help="simulate a scenario and write its dataset")
    run.add_argument("scenario", help="a built-in scenario name (see `list`) or a path to a scenario .yaml")
    run.add_argument("--frames", type=int, help="number of frames (overrides the scenario)")
    run.add_argument("--seed", type=int, help="random seed (overrides the scenario)")
    run.add_argument("--out", type=Path, help="output folder (default: out/<scenario>)")
    run.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                     help="override any scenario key, e.g. --set traffic.pedestrians=50 (repeatable)")  # fmt: skip
    run.add_argument("--no-progress", action="store_true", help="no progress bar")
    run.add_argument("--no-summary", action="store_true", help="skip the summary/ statistics and pictures")
    sub.add_parser("list", help="list the built-in scenarios")
    return parser


def _cmd_list() -> int:
    from cosim.scenario import catalog_description, catalog_names

    for name in catalog_names():
        print(f"{name:18s} {catalog_description(name)}")
    return 0


def _cmd_run(args: argparse.Namespace) -> int:
    from cosim.loop import run
    from cosim.scenario import load_scenario
    from gtgen.summary import write_summary

    overrides = list(args.overrides)
    if args.frames is not None:
        overrides.append(f"frames={args.frames}")
    if args.seed is not None:
        overrides.append(f"seed={args.seed}")
    scenario = load_scenario(args.scenario, overrides)
    out_dir = args.out if args.out is not None else Path("out") / scenario.name
    summary = run(scenario, out_dir, progress=not args.no_progress)
    if not args.no_summary:
        write_summary(out_dir)
    print(f"wrote {out_dir}/")
    for line in summary.lines():
        print(line)
    return 0


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    try:
        return _cmd_list() if args.command == "list" else _cmd_run(args)
    except USER_ERRORS as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("interrupted; no dataset was completed", file=sys.stderr)
        return 130
