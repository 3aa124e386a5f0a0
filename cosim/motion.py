"""The traffic of scenes without sensors: how much of the time the ego stands, and the road
users around it (within 50 m, whether a sensor would see them or not).

``python -m cosim.motion SCENARIO [SCENARIO ...] [--frames N] [--set key=value]`` simulates
each scenario's traffic for its frames (about a hundred frames a second) and prints one row per
scenario; a run with sensors says what they saw (``python -m gtgen.content``).
"""

from __future__ import annotations

import argparse
import sys
from collections import Counter
from dataclasses import dataclass

import numpy as np

from cosim.errors import CosimError
from cosim.scenario import Scenario, load_scenario
from gtgen.content import RADIUS_M, STOPPED_MPS
from networks.classes import SemanticClass

SHOWN = ("pedestrian", "bicycle", "car", "truck", "bus", "motorcycle")


@dataclass(frozen=True, slots=True)
class Motion:
    frames: int
    stopped_share: float  # frames with the ego slower than STOPPED_MPS
    longest_stop_s: float
    scene_cuts: int
    near_per_frame: dict[str, float]  # road users within RADIUS_M, by class (parked ones under "parked")


def simulate(scenario: Scenario) -> Motion:
    """Step the scenario's traffic for its frames and count."""
    from cosim.traffic_feed import TrafficInline
    from cosim.world_setup import prepare_network

    prepared = prepare_network(scenario)
    near: Counter[str] = Counter()
    stopped, run_s, longest_s, cuts = 0, 0.0, 0.0, 0
    with TrafficInline(prepared.net_path, scenario, RADIUS_M) as traffic:
        traffic.warm_up()
        for _ in range(scenario.frames):
            state = traffic.next()
            cuts += state.scene_cut
            if float(np.linalg.norm(state.ego.velocity_map_mps)) < STOPPED_MPS:
                stopped += 1
                run_s += scenario.step_s
                longest_s = max(longest_s, run_s)
            else:
                run_s = 0.0
            agents = state.agents
            near["parked"] += int(agents.parked.sum())
            near.update(SemanticClass(int(c)).label for c in agents.semantic_class[~agents.parked])
    n = max(scenario.frames, 1)
    return Motion(scenario.frames, stopped / n, longest_s, cuts, {k: v / n for k, v in near.items()})


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m cosim.motion", description=__doc__.split("\n\n")[0])
    parser.add_argument("scenarios", nargs="+", help="built-in scenario names or paths to scenario .yaml files")
    parser.add_argument("--frames", type=int, help="frames per scenario (default: each scenario's own)")
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE")
    args = parser.parse_args(argv)
    head = ["scenario", "frames", "ego stopped %", "longest stop s", "scene cuts", *SHOWN, "parked"]
    print(
        f"road users within {RADIUS_M:g} m of the ego per frame (seen or not); the ego stopped below "
        f"{STOPPED_MPS:g} m/s"
    )
    print("| " + " | ".join(head) + " |\n|" + "---|" * len(head))
    for spec in args.scenarios:
        overrides = [*args.overrides, *([f"frames={args.frames}"] if args.frames else [])]
        try:
            scenario = load_scenario(spec, overrides)
            m = simulate(scenario)
        except CosimError as err:
            print(f"error: {err}", file=sys.stderr)
            return 2
        cells = [scenario.name, str(m.frames), f"{100 * m.stopped_share:.0f}", f"{m.longest_stop_s:.1f}",
                 str(m.scene_cuts), *(f"{m.near_per_frame.get(k, 0.0):.2f}" for k in (*SHOWN, "parked"))]  # fmt: skip
        print("| " + " | ".join(cells) + " |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
