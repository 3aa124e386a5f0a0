"""Traffic alone, no sensors: does SUMO carry a scene's demand without jams?

``python -m cosim.soak [SCENE ...] [--seconds 600] [--set key=value ...]`` runs each
scene's traffic (warm-up, ego, top-ups: the same code as a dataset run) headless for
the given simulated time and prints the vehicles that drove (inserted, parked ones
left out), teleports and the share of them that SUMO had to teleport (issue #3 asks
for less than 1 %).
"""

from __future__ import annotations

import argparse
import time
from dataclasses import dataclass

from cosim.scenario import catalog_names, load_scenario
from cosim.sumo.traffic import Traffic, TrafficCounts
from networks.convert import import_opendrive
from networks.towns import town_opendrive
from networks.world import load_net


@dataclass(frozen=True, slots=True)
class SoakResult:
    scene: str
    simulated_s: float
    vehicle_target: int
    counts: TrafficCounts
    wall_s: float

    def line(self) -> str:
        c = self.counts
        return (
            f"{self.scene:16s} {self.simulated_s:6.0f} s  target {self.vehicle_target:4d}  running {c.running:4d}"
            f"  drove {c.inserted - c.parked:5d}  teleports {c.teleports:4d}  teleported {len(c.teleported_ids):4d}"
            f"  ({100 * c.teleported_share:5.2f} %)  wall {self.wall_s:5.0f} s"
        )


def soak(scene: str, seconds: float, overrides: tuple[str, ...] = ()) -> SoakResult:
    """Run one scene's traffic for ``seconds`` of simulated time after its warm-up."""
    scenario = load_scenario(scene, overrides)
    xodr = scenario.network_path() or town_opendrive(scenario.network)
    net_path = import_opendrive(xodr)
    start = time.perf_counter()
    traffic = Traffic(net_path, load_net(net_path), scenario)
    try:
        traffic.warm_up()
        for _ in range(round(seconds / scenario.step_s)):
            traffic.step()
        return SoakResult(scene, seconds, traffic.vehicle_target, traffic.counts, time.perf_counter() - start)
    finally:
        traffic.close()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m cosim.soak", description=__doc__.splitlines()[0])
    parser.add_argument("scenes", nargs="*", help="catalog scenes or scenario files (default: the whole catalog)")
    parser.add_argument("--seconds", type=float, default=600.0, help="simulated time after the warm-up")
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE")
    args = parser.parse_args(argv)
    for scene in args.scenes or catalog_names():
        print(soak(scene, args.seconds, tuple(args.overrides)).line(), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
