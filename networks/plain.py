"""SUMO plain-XML road networks (nodes and edges) and their conversion to OpenDRIVE.

The built-in towns are designed as plain networks here, written as OpenDRIVE by
netconvert, and then imported back through the same path as a user's ``.xodr``.
"""

from __future__ import annotations

import subprocess
from dataclasses import dataclass, field
from pathlib import Path
from xml.sax.saxutils import quoteattr

from networks.errors import NetconvertError
from networks.sumo_tools import sumo_binary


@dataclass(frozen=True, slots=True)
class PlainNode:
    node_id: str
    x_m: float
    y_m: float
    z_m: float = 0.0
    kind: str = "priority"  # SUMO node type: priority, traffic_light, right_before_left, ...


@dataclass(frozen=True, slots=True)
class PlainEdge:
    edge_id: str
    from_node: str
    to_node: str
    num_lanes: int = 1
    speed_mps: float = 13.89
    sidewalk_width_m: float = 2.5
    lane_width_m: float = 3.2
    shape: tuple[tuple[float, float, float], ...] = ()


@dataclass(frozen=True, slots=True)
class PlainNetwork:
    nodes: tuple[PlainNode, ...]
    edges: tuple[PlainEdge, ...]
    netconvert_options: tuple[str, ...] = field(default=())

    def nodes_xml(self) -> str:
        rows = [
            f'  <node id={quoteattr(n.node_id)} x="{n.x_m:.2f}" y="{n.y_m:.2f}" z="{n.z_m:.2f}" type="{n.kind}"/>'
            for n in self.nodes
        ]
        return "<nodes>\n" + "\n".join(rows) + "\n</nodes>\n"

    def edges_xml(self) -> str:
        rows = []
        for e in self.edges:
            shape = ""
            if e.shape:
                shape = ' shape="' + " ".join(f"{x:.2f},{y:.2f},{z:.2f}" for x, y, z in e.shape) + '"'
            sidewalk = f' sidewalkWidth="{e.sidewalk_width_m:.2f}"' if e.sidewalk_width_m > 0 else ""
            rows.append(
                f"  <edge id={quoteattr(e.edge_id)} from={quoteattr(e.from_node)} to={quoteattr(e.to_node)}"
                f' numLanes="{e.num_lanes}" speed="{e.speed_mps:.2f}" width="{e.lane_width_m:.2f}"{sidewalk}{shape}/>'
            )
        return "<edges>\n" + "\n".join(rows) + "\n</edges>\n"


def write_opendrive(network: PlainNetwork, workdir: Path, xodr_path: Path) -> Path:
    """Write ``network`` as OpenDRIVE with netconvert (crossings and signals included)."""
    workdir.mkdir(parents=True, exist_ok=True)
    nod, edg = workdir / "plain.nod.xml", workdir / "plain.edg.xml"
    nod.write_text(network.nodes_xml())
    edg.write_text(network.edges_xml())
    cmd = [
        str(sumo_binary("netconvert")),
        "--node-files", str(nod),
        "--edge-files", str(edg),
        "--opendrive-output", str(xodr_path),
        "--no-turnarounds", "true",
        "--junctions.corner-detail", "8",
        *network.netconvert_options,
    ]  # fmt: skip
    proc = subprocess.run(cmd, capture_output=True, text=True, check=False)
    if proc.returncode != 0 or not xodr_path.exists():
        tail = " | ".join(proc.stderr.strip().splitlines()[-3:])
        raise NetconvertError(f"{edg}: netconvert could not write OpenDRIVE: {tail}")
    return xodr_path
