"""Write the OpenDRIVE maps of ``tests/data/xodr/motorway/``: small maps with roads of type
``motorway`` shaped like the files map editors export (sidewalks and bicycle lanes on motorway
roads, exit and entry lane types, speeds in km/h and mph that change along a road, speed-limit
signs, left-hand traffic).

Each map is designed as a SUMO plain network, written as OpenDRIVE by netconvert, then edited
as an exporter would have written it. Roads are told apart by their lane speed (each design
speed below marks one kind of road). Run from the repository root:
``python tests/make_motorway_maps.py``.
"""

from __future__ import annotations

import math
import sys
import tempfile
from pathlib import Path
from xml.etree import ElementTree

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from networks.plain import PlainEdge, PlainNetwork, PlainNode, write_opendrive

OUT = Path(__file__).resolve().parent / "data" / "xodr" / "motorway"

# Design speeds (m/s) that mark the kind of each road in the written file.
MOTORWAY = 30.0  # motorway road with sidewalks on both sides
BARE_MOTORWAY = 29.0  # motorway road without sidewalks
RAMP = 20.0  # exit or entry ramp
SLOW_MOTORWAY = 13.0  # typed motorway, 50 km/h, no sidewalks: netconvert would guess some
BIKE_MOTORWAY = 12.5  # typed motorway with a bicycle lane where the sidewalk was
STREET = 13.5  # a town street


def _two_way(a: str, b: str, speed_mps: float, sidewalk_m: float = 2.5) -> tuple[PlainEdge, PlainEdge]:
    return (
        PlainEdge(f"{a}_{b}", a, b, speed_mps=speed_mps, sidewalk_width_m=sidewalk_m),
        PlainEdge(f"{b}_{a}", b, a, speed_mps=speed_mps, sidewalk_width_m=sidewalk_m),
    )


def _motorway(a: str, b: str, lanes: int = 2, sidewalk: bool = True, spread: str = "right") -> PlainEdge:
    return PlainEdge(f"{a}_{b}", a, b, num_lanes=lanes, speed_mps=MOTORWAY if sidewalk else BARE_MOTORWAY,
                     lane_width_m=3.5, sidewalk_width_m=2.0 if sidewalk else 0.0, spread=spread)  # fmt: skip


def _motorway_both_ways(a: str, b: str, lanes: int = 2) -> tuple[PlainEdge, PlainEdge]:
    return _motorway(a, b, lanes), _motorway(b, a, lanes)


def designs() -> dict[str, tuple[PlainNetwork, dict[float, dict[str, str]]]]:
    """Each map's plain network and, per design speed, how its roads are written."""
    n = PlainNode
    motorway = {"type": "motorway", "speed": "110", "unit": "km/h"}
    ramp = {"type": "motorway", "speed": "45", "unit": "mph", "lanes": "offRamp"}
    street = {"type": "town", "speed": "50", "unit": "km/h"}
    arms = [(400.0 * math.cos(a), 400.0 * math.sin(a)) for a in (math.pi / 2, 7 * math.pi / 6, 11 * math.pi / 6)]
    exit_nodes = (n("a", 0, 0), n("m", 400, 0), n("b", 900, 0), n("r", 650, -90), n("s", 850, -90))
    exit_ramp = PlainEdge("m_r", "m", "r", speed_mps=RAMP, sidewalk_width_m=0.0, spread="center")
    exit_edges = (
        *_motorway_both_ways("a", "m"),
        *_motorway_both_ways("m", "b"),
        exit_ramp,
        *_two_way("r", "s", STREET),
    )
    split_edges = (_motorway("a", "m", 3, sidewalk=False, spread="center"), _motorway("m", "b", spread="center"),
                   _motorway("m", "c", sidewalk=False, spread="center"))  # fmt: skip
    crossing = (n("c", 0, 0, kind="traffic_light"), n("w", -300, 0), n("e", 300, 0), n("s", 0, -300), n("n", 0, 300))
    crossing_edges = (*_two_way("w", "c", SLOW_MOTORWAY, sidewalk_m=0.0), *_two_way("c", "e", BIKE_MOTORWAY),
                      *_two_way("s", "c", STREET), *_motorway_both_ways("c", "n", 1))  # fmt: skip
    crossing_kinds = {
        SLOW_MOTORWAY: {"type": "motorway", "speed": "50", "unit": "km/h", "lane_speeds": "50 80"},
        BIKE_MOTORWAY: {"type": "motorway", "speed": "45", "unit": "km/h", "bike": "yes"},
        STREET: {**street, "lane_speeds": "30 50"},
        MOTORWAY: {**motorway, "lane_speeds": "100 80"},
    }
    return {
        "exit": (
            PlainNetwork(exit_nodes, exit_edges),
            {MOTORWAY: motorway, RAMP: ramp, STREET: street},
        ),
        "split": (
            PlainNetwork((n("a", 0, 0), n("m", 400, 0), n("b", 900, 150), n("c", 900, -150)), split_edges),
            {MOTORWAY: motorway, BARE_MOTORWAY: {**motorway, "unit": "mph", "speed": "70"}},
        ),
        "three_way": (
            PlainNetwork(
                (n("c", 0, 0), *(n(f"e{k}", x, y) for k, (x, y) in enumerate(arms))),
                tuple(e for k in range(3) for e in _motorway_both_ways("c", f"e{k}")),
            ),
            {MOTORWAY: motorway},
        ),
        "left_hand_signs": (
            PlainNetwork(
                (n("a", 0, 0), n("m", 500, 0), n("b", 1000, 60)),
                (*_motorway_both_ways("a", "m"), *_motorway_both_ways("m", "b")),
                netconvert_options=("--lefthand", "true"),
            ),
            {MOTORWAY: {**motorway, "signs": "100", "rule": "LHT"}},
        ),
        "changed_speeds": (PlainNetwork(crossing, crossing_edges), crossing_kinds),
    }


def _design_speed(road: ElementTree.Element) -> float:
    speeds = [float(s.get("max", "0")) for s in road.iter("speed") if s.get("max")]
    return round(max(speeds), 1) if speeds else 0.0


def _rewrite(road: ElementTree.Element, how: dict[str, str]) -> None:
    """Write one road as a map editor would: its type and speed with a unit, lane speeds
    that change along it, lane types, signs, its traffic rule."""
    road_type = road.find("type")
    if road_type is None:
        road_type = ElementTree.Element("type", {"s": "0"})
        road.insert(1, road_type)
    road_type.set("type", how["type"])
    for child in list(road_type):
        road_type.remove(child)
    ElementTree.SubElement(road_type, "speed", {"max": how["speed"], "unit": how["unit"]})
    if "rule" in how:
        road.set("rule", how["rule"])
    length = float(road.get("length", "0"))
    for lane in road.iter("lane"):
        for record in lane.findall("speed"):
            lane.remove(record)
        if lane.get("type") == "driving":
            speeds = how.get("lane_speeds", how["speed"]).split()
            anchor = next((k for k, c in enumerate(lane) if c.tag not in ("link", "width", "roadMark")), len(lane))
            for k, value in enumerate(speeds):
                record = ElementTree.Element(
                    "speed", {"sOffset": f"{k * length / len(speeds):.2f}", "max": value, "unit": how["unit"]}
                )
                lane.insert(anchor + k, record)
            if "lanes" in how:
                lane.set("type", how["lanes"])
        elif lane.get("type") == "sidewalk" and "bike" in how and int(lane.get("id", "0")) < 0:
            lane.set("type", "biking")
    if "signs" in how and road.get("junction", "-1") == "-1" and length > 60.0:
        signals = road.find("signals")
        if signals is None:
            signals = ElementTree.SubElement(road, "signals")
        for k, (s, t, orientation) in enumerate(((30.0, -9.5, "+"), (length - 30.0, 9.5, "-"))):
            ElementTree.SubElement(signals, "signal", {
                "s": f"{s:.2f}", "t": f"{t:.2f}", "id": f"{road.get('id')}_limit{k}", "name": "", "dynamic": "no",
                "orientation": orientation, "zOffset": "1.8", "country": "DEU", "type": "274", "subtype": "-1",
                "value": how["signs"], "unit": "km/h", "height": "0.6", "width": "0.6",
            })  # fmt: skip


def write_map(name: str, network: PlainNetwork, kinds: dict[float, dict[str, str]], out: Path) -> Path:
    with tempfile.TemporaryDirectory() as work:
        xodr = write_opendrive(network, Path(work), Path(work) / f"{name}.xodr")
        tree = ElementTree.parse(xodr)
    header = tree.getroot().find("header")
    if header is not None:
        header.set("date", "")
    for road in tree.getroot().iter("road"):
        how = kinds.get(_design_speed(road))
        if how is not None:
            _rewrite(road, how)
    ElementTree.indent(tree)
    target = out / f"motorway_{name}.xodr"
    tree.write(target, encoding="utf-8", xml_declaration=True)
    return target


def main() -> None:
    OUT.mkdir(parents=True, exist_ok=True)
    for name, (network, kinds) in designs().items():
        print(write_map(name, network, kinds, OUT))


if __name__ == "__main__":
    main()
