"""Traffic lights and signs: where the rules put them, and a file's own sign records."""

import math
import re
from xml.etree import ElementTree

import numpy as np
import pytest

from networks.convert import import_opendrive
from networks.markings import is_left_hand
from networks.street import SIGN_CENTRE_HEIGHT_M, read_signs, street_objects
from networks.towns import town_opendrive
from networks.vocabulary import SignalState
from networks.world import build_world, load_net


@pytest.fixture(scope="module")
def town05():
    net_path = import_opendrive(town_opendrive("town05"))
    return load_net(net_path), street_objects(load_net(net_path), is_left_hand(net_path))


def test_every_signalised_approach_has_one_head_facing_its_traffic_on_the_right(town05):
    net, objects = town05
    heads = [o for o in objects if o.is_light]
    edges = [e for e in net.getEdges(withInternal=False) if not e.getFunction()]
    approaches = {(lane.getEdge().getID(), c.getTLSID()) for e in edges for lane in e.getLanes()
                  if lane.getPermissions() - {"pedestrian"} for c in lane.getOutgoing() if c.getTLSID()}  # fmt: skip
    assert len(heads) == len(approaches) > 50
    assert len({o.object_id for o in objects}) == len(objects)
    for head in heads:
        lane = net.getLane(head.lanes[0])
        shape = np.asarray(lane.getShape())
        heading = (shape[-1] - shape[-2]) / np.linalg.norm(shape[-1] - shape[-2])
        front = np.array([math.cos(head.yaw_map_rad), math.sin(head.yaw_map_rad)])
        assert front @ heading < -0.99  # faces the approaching traffic
        to_head = np.asarray(head.centre_map_m[:2]) - shape[-1]
        assert heading[0] * to_head[1] - heading[1] * to_head[0] < -1.0  # right of the lane (right-hand traffic)
        assert abs(to_head @ heading) < 3.0  # by the stop line
        assert head.state({head.tls_id: SignalState.decode("r" * 64)}) == "red" and head.state({}) == "off"


def test_village_roads_get_give_way_signs_and_speed_limits_from_the_rules():
    net_path = import_opendrive(town_opendrive("town07"))
    objects = street_objects(load_net(net_path), False)
    kinds = {o.subtype for o in objects}
    assert not any(o.is_light for o in objects)
    assert "yield" in kinds and any(k.startswith("speed_limit_") for k in kinds)


def _with_signals(tmp_path, records: str):
    """The skeleton town's file with ``records`` added to its first road; that road's start,
    heading and length."""
    source = town_opendrive("skeleton")
    text = source.read_text()
    first = re.search(r'<road [^>]*id="([^"]+)"[^>]*>.*?</road>', text, re.DOTALL)
    road = ElementTree.fromstring(first.group(0))
    geometry = road.find("planView/geometry")
    block = first.group(0).replace("</road>", f"<signals>{records}</signals></road>") if "<signals>" not in first.group(
        0) else first.group(0).replace("<signals>", f"<signals>{records}", 1)  # fmt: skip
    xodr = tmp_path / "signed.xodr"
    xodr.write_text(text.replace(first.group(0), block))
    start = (float(geometry.get("x")), float(geometry.get("y")), float(geometry.get("hdg")))
    return xodr, start, float(road.get("length"))


def test_a_files_sign_records_are_placed_where_the_file_says(tmp_path):
    common = 't="-9" orientation="+" dynamic="no"'
    records = (
        f'<signal id="s1" s="20" {common} zOffset="1.8" country="DE" type="206"/>'
        f'<signal id="s2" s="40" {common} country="DE" type="274" value="30"/>'
        f'<signal id="s3" s="60" {common} country="US" type="R2-1" value="25" unit="mph"/>'
        f'<signal id="s4" s="70" {common} country="DE" type="274" value=""/>'
    )
    xodr, (x0, y0, hdg), _ = _with_signals(tmp_path, records)
    assert "1 signal record(s) left out" in read_signs(xodr).problem
    net_path = import_opendrive(xodr)
    net = load_net(net_path)
    signs = [o for o in street_objects(net, False, xodr_path=xodr) if not o.is_light]
    assert [o.subtype for o in signs] == ["stop", "speed_limit_30", "speed_limit_40"]  # the file's, not the rules'
    dx, dy = net.getLocationOffset()
    for sign, s in zip(signs, (20.0, 40.0, 60.0), strict=True):
        expected = (x0 + s * math.cos(hdg) + 9 * math.sin(hdg) + dx, y0 + s * math.sin(hdg) - 9 * math.cos(hdg) + dy)
        assert np.hypot(sign.centre_map_m[0] - expected[0], sign.centre_map_m[1] - expected[1]) < 0.3
        assert abs(math.remainder(sign.yaw_map_rad - (hdg + math.pi), 2 * math.pi)) < 0.05  # faces traffic along s
    assert signs[0].centre_map_m[2] == pytest.approx(1.8 + 0.75 / 2, abs=0.05)  # its zOffset: the plate's bottom
    assert signs[1].centre_map_m[2] == pytest.approx(SIGN_CENTRE_HEIGHT_M, abs=0.05)
    world = build_world(net_path, xodr_path=xodr)
    assert "signal record(s) left out" in world.notice
