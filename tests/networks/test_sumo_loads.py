"""Every network the project writes loads in SUMO itself: the built-in towns, the user-map
quirks of ``tests/data/xodr`` and maps with motorway roads whose lanes are closed to bicycles
and pedestrians (``tests/data/xodr/motorway``, written by ``tests/make_motorway_maps.py``)."""

from pathlib import Path
from xml.etree import ElementTree

import pytest
import sumolib

import networks.convert
from networks.convert import MOTORWAY_BANNED, import_opendrive, motorway_roads
from networks.errors import SumoRefusedError
from networks.sumo_tools import sumo_refusal
from networks.towns import town_opendrive
from networks.world import load_net

XODR = Path(__file__).resolve().parents[1] / "data" / "xodr"
MOTORWAY_MAPS = sorted((XODR / "motorway").glob("*.xodr"))
USER_MAPS = sorted(p for p in XODR.glob("*.xodr") if p.name != "rejected_broken.xodr")
TOWNS = ["skeleton", "town03", "town05", "town06", "town07", "town10"]


@pytest.mark.parametrize("source", [*(p.name for p in USER_MAPS + MOTORWAY_MAPS), *TOWNS])
def test_every_network_the_project_writes_loads_in_sumo(source):
    xodr = town_opendrive(source) if source in TOWNS else next(p for p in USER_MAPS + MOTORWAY_MAPS if p.name == source)
    net_path = import_opendrive(xodr)
    assert sumo_refusal(["-n", str(net_path)]) == ""


def _lane_types(xodr: Path) -> dict[str, str]:
    """OpenDRIVE ``<road>_<lane>`` -> lane type (the form of a SUMO lane's ``origId``)."""
    out = {}
    for road in ElementTree.parse(xodr).getroot().iter("road"):
        for lane in road.iter("lane"):
            out[f"{road.get('id')}_{lane.get('id')}"] = lane.get("type", "")
    return out


def _road_lanes(net: sumolib.net.Net, roads: set[str]) -> list[tuple[sumolib.net.lane.Lane, str]]:
    """The lanes of normal edges that belong to one of the OpenDRIVE ``roads``, with their origId."""
    out = []
    for edge in net.getEdges(withInternal=False):
        for lane in edge.getLanes():
            origin = lane.getParam("origId") or ""
            if not edge.getFunction() and origin.rsplit("_", 1)[0] in roads:
                out.append((lane, origin))
    return out


@pytest.mark.parametrize("xodr", MOTORWAY_MAPS, ids=lambda p: p.stem)
def test_motorway_roads_keep_bicycles_and_pedestrians_off_their_driving_lanes_only(xodr):
    """Driving lanes of motorway roads are closed to bicycles, mopeds and pedestrians; the road's
    own sidewalks and bicycle lanes stay open to them; no sidewalk is guessed on a motorway."""
    lanes = _road_lanes(load_net(import_opendrive(xodr)), motorway_roads(xodr))
    types = _lane_types(xodr)
    driving = [lane for lane, _ in lanes if lane.allows("passenger")]
    assert driving
    assert not any(lane.allows(c) for lane in driving for c in MOTORWAY_BANNED)
    for lane, origin in lanes:
        if lane.getPermissions() == {"pedestrian"}:
            assert types[origin] == "sidewalk", f"{lane.getID()}: a sidewalk guessed on a motorway road"
        if lane.getPermissions() == {"bicycle"}:
            assert types[origin] == "biking"
    kinds = {frozenset(lane.getPermissions()) for lane, _ in lanes}
    if "sidewalk" in {types[o] for _, o in lanes}:
        assert frozenset({"pedestrian"}) in kinds


def test_a_network_sumo_refuses_stops_with_sumos_first_error_and_the_file(monkeypatch):
    """Should an edit after netconvert leave a network SUMO does not load, the conversion stops
    with one line: the OpenDRIVE file, the network file and SUMO's own first error."""
    xodr = MOTORWAY_MAPS[0]

    def empty_sidewalks(net_path: Path, roads: set[str]) -> None:
        net_path.write_text(net_path.read_text().replace('allow="pedestrian"', 'allow=""'))

    monkeypatch.setattr(networks.convert, "CONVERT_VERSION", "refused")
    monkeypatch.setattr(networks.convert, "_keep_off_motorways", empty_sidewalks)
    with pytest.raises(SumoRefusedError) as info:
        import_opendrive(xodr)
    message = str(info.value)
    assert "\n" not in message
    assert message.startswith(f"{xodr}: SUMO does not load the network converted from it (")
    refused = Path(message.split("(", 1)[1].split(")", 1)[0])
    assert refused.name == "net.refused.xml" and refused.exists()
    assert message.endswith(sumo_refusal(["-n", str(refused)]))
    assert "An unknown lane" in message
    assert not refused.with_name("net.net.xml").exists()  # nothing cached as good
