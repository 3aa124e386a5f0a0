"""Scenario network -> SUMO net and static world (through the networks package)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import sumolib

from cosim.errors import ScenarioError
from cosim.scenario import Scenario
from networks.cache import take_notices
from networks.convert import conversion_notice, import_opendrive
from networks.errors import quoted
from networks.towns import TOWNS, town_names, town_opendrive
from networks.world import StaticWorld, build_world, load_net


@dataclass(frozen=True, slots=True)
class PreparedNetwork:
    xodr_path: Path
    net_path: Path
    world: StaticWorld
    notice: str  # shown to the user, e.g. when a stand-in town is used

    @property
    def net(self) -> sumolib.net.Net:
        """The SUMO network, read on each access: the frame loop's traffic process reads its own."""
        return load_net(self.net_path)


def prepare_network(scenario: Scenario) -> PreparedNetwork:
    user_path = scenario.network_path()
    notice = ""
    if user_path is not None:
        xodr = user_path
    elif scenario.network in TOWNS:
        info = TOWNS[scenario.network]
        if info.stand_in:
            notice = f"note: town {info.name!r} is not generated yet; running the skeleton network in its place"
        xodr = town_opendrive(scenario.network)
    else:
        known = ", ".join(town_names())
        source = f"{scenario.source_dir}/{scenario.name}.yaml"
        msg = f"{source}: network: unknown town {quoted(scenario.network)} (known: {known}; or a path to an .xodr file)"
        raise ScenarioError(msg)
    net_path = import_opendrive(xodr)
    street = scenario.street
    world = build_world(
        net_path, markings=street.markings, xodr_path=xodr, traffic_lights=street.traffic_lights, signs=street.signs
    )
    notices = [notice, *take_notices(), conversion_notice(net_path), world.notice]
    return PreparedNetwork(xodr, net_path, world, "\n".join(n for n in notices if n))
