"""SUMO plain-XML road networks (nodes and edges) and their conversion to OpenDRIVE.

The built-in towns are designed as plain networks here, written as OpenDRIVE by
netconvert, and then imported back through the same path as a user's ``.xodr``.
"""

from __future__ import annotations

import subprocess
from dataclasses import dataclass, field
from pathlib import Path
from xml.etree import ElementTree
from xml.sax.saxutils import quoteattr

from networks.errors import NetconvertError
from networks.sumo_tools import sumo_binary

# Vehicle classes kept off motorways (no sidewalks, no cyclists, no pedestrians).
MOTORWAY_DISALLOW = "pedestrian bicycle moped"
# Roads faster than this are typed as motorways in OpenDRIVE (and get no guessed sidewalks).
URBAN_SPEED_LIMIT_MPS = 13.89


@dataclass(frozen=True, slots=True)
class PlainNode:
    node_id: str
    x_m: float
    y_m: float
    z_m: float = 0.0
    kind: str = "priority"  # SUMO node type: priority, traffic_light, right_before_left, ...


@dataclass(frozen=True, slots=True)
class PlainEdge:
    """One direction of travel. Two-way streets are two edges, one per direction.

    ``shape`` (x, y, z) points run from ``from_node`` to ``to_node`` (curves, ramps);
    ``left_sidewalk`` adds a sidewalk on the left too (one-way streets);
    ``spread`` is SUMO's spreadType: ``right`` for one half of a two-way street,
    ``center`` for a one-way street or a motorway carriageway on its own axis.
    """

    edge_id: str
    from_node: str
    to_node: str
    num_lanes: int = 1
    speed_mps: float = 13.89
    sidewalk_width_m: float = 2.5
    lane_width_m: float = 3.2
    shape: tuple[tuple[float, float, float], ...] = ()
    left_sidewalk: bool = False
    spread: str = "right"
    priority: int = -1  # -1: netconvert's default
    disallow: str = ""  # SUMO vehicle classes, space separated
    parking_width_m: float = 0.0  # > 0: a street-parking lane between the right sidewalk and the traffic

    def __post_init__(self) -> None:
        if self.num_lanes < 1:
            raise ValueError(f"PlainEdge {self.edge_id}: num_lanes must be >= 1, got {self.num_lanes}")
        if self.spread not in ("right", "center", "roadCenter"):
            raise ValueError(f"PlainEdge {self.edge_id}: unknown spread {self.spread!r}")

    def xml(self) -> str:
        attrs = (
            f"id={quoteattr(self.edge_id)} from={quoteattr(self.from_node)} to={quoteattr(self.to_node)}"
            f' speed="{self.speed_mps:.2f}" width="{self.lane_width_m:.2f}" spreadType="{self.spread}"'
        )
        if self.priority >= 0:
            attrs += f' priority="{self.priority}"'
        if self.shape:
            attrs += ' shape="' + " ".join(f"{x:.2f},{y:.2f},{z:.2f}" for x, y, z in self.shape) + '"'
        if not self.left_sidewalk and self.parking_width_m <= 0:
            sidewalk = f' sidewalkWidth="{self.sidewalk_width_m:.2f}"' if self.sidewalk_width_m > 0 else ""
            disallow = f" disallow={quoteattr(self.disallow)}" if self.disallow else ""
            return f'  <edge {attrs} numLanes="{self.num_lanes}"{sidewalk}{disallow}/>'
        return self._with_lane_elements(attrs)

    def _with_lane_elements(self, attrs: str) -> str:
        """Explicit lanes: right sidewalk (index 0), an optional parking lane (typed
        ``parking``, no traffic), the driving lanes, an optional left sidewalk (last)."""
        lanes: list[str] = []
        walk = f'allow="pedestrian" width="{self.sidewalk_width_m:.2f}"'
        if self.sidewalk_width_m > 0:
            lanes.append(walk)
        if self.parking_width_m > 0:
            lanes.append(f'type="parking" disallow="all" width="{self.parking_width_m:.2f}"')
        if self.left_sidewalk:
            lanes += [""] * self.num_lanes + [walk]
        else:
            lanes += [""] * self.num_lanes
        disallow = " ".join(sorted({"pedestrian", *self.disallow.split()}))
        rows = [f'    <lane index="{i}" {a}/>' for i, a in enumerate(lanes) if a]
        return f'  <edge {attrs} numLanes="{len(lanes)}" disallow="{disallow}">\n' + "\n".join(rows) + "\n  </edge>"


@dataclass(frozen=True, slots=True)
class PlainNetwork:
    """A town as SUMO plain XML. ``parking_edges``: edge ids with room for street parking
    on their right-hand side (data for whoever places SUMO parking areas)."""

    nodes: tuple[PlainNode, ...]
    edges: tuple[PlainEdge, ...]
    netconvert_options: tuple[str, ...] = field(default=())
    parking_edges: tuple[str, ...] = field(default=())

    def __post_init__(self) -> None:
        node_ids = {n.node_id for n in self.nodes}
        if len(node_ids) != len(self.nodes):
            raise ValueError("PlainNetwork: duplicate node ids")
        edge_ids = [e.edge_id for e in self.edges]
        if len(set(edge_ids)) != len(edge_ids):
            raise ValueError("PlainNetwork: duplicate edge ids")
        for e in self.edges:
            if e.from_node not in node_ids or e.to_node not in node_ids:
                raise ValueError(f"PlainNetwork: edge {e.edge_id} names an unknown node")

    def nodes_xml(self) -> str:
        rows = [
            f'  <node id={quoteattr(n.node_id)} x="{n.x_m:.2f}" y="{n.y_m:.2f}" z="{n.z_m:.2f}" type="{n.kind}"/>'
            for n in self.nodes
        ]
        return "<nodes>\n" + "\n".join(rows) + "\n</nodes>\n"

    def edges_xml(self) -> str:
        return "<edges>\n" + "\n".join(e.xml() for e in self.edges) + "\n</edges>\n"


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
        "--offset.disable-normalization", "true",
        *network.netconvert_options,
    ]  # fmt: skip
    proc = subprocess.run(cmd, capture_output=True, text=True, check=False)
    if proc.returncode != 0 or not xodr_path.exists():
        tail = " | ".join(proc.stderr.strip().splitlines()[-3:])
        raise NetconvertError(f"{edg}: netconvert could not write OpenDRIVE: {tail}")
    (workdir / "netconvert.log").write_text(proc.stderr)
    tree = ElementTree.parse(xodr_path)
    root = tree.getroot()
    _type_roads_by_speed(root)
    header = root.find("header")
    if header is not None:
        header.attrib.pop("date", None)  # netconvert's clock time: the same town is the same file
    tree.write(xodr_path, encoding="utf-8", xml_declaration=True)
    return xodr_path


def _type_roads_by_speed(root: ElementTree.Element) -> None:
    """Give every road a ``<type>`` with its top lane speed: netconvert writes speeds per
    lane only, and its importer takes a road's speed (which decides whether sidewalks are
    guessed) from the road type."""
    for road in root.iter("road"):
        speeds = [float(s.get("max", "0")) for s in road.iter("speed") if s.get("max")]
        road_type = road.find("type")
        if not speeds or road_type is None:
            continue
        top = max(speeds)
        road_type.set("type", "town" if top <= URBAN_SPEED_LIMIT_MPS else "motorway")
        for child in list(road_type):
            road_type.remove(child)
        ElementTree.SubElement(road_type, "speed", {"max": f"{top:.2f}", "unit": "m/s"})
