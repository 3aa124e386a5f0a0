"""One OpenDRIVE parse a process: the readers share the tree until the file changes."""

import os
from xml.etree import ElementTree

import numpy as np
import pytest

from networks.geometry import arc_lengths, polyline_length
from networks.markings import read_road_marks
from networks.opendrive import opendrive_root
from networks.street import read_signs

ROAD = '<OpenDRIVE><road id="{id}" length="10"><lanes><laneSection s="0"/></lanes></road></OpenDRIVE>'


def test_the_tree_is_parsed_once_and_again_when_the_file_changes(tmp_path):
    path = tmp_path / "town.xodr"
    path.write_text(ROAD.format(id="1"))
    first = opendrive_root(path)
    assert opendrive_root(path) is first
    path.write_text(ROAD.format(id="22"))
    os.utime(path, ns=(path.stat().st_atime_ns, path.stat().st_mtime_ns + 1_000_000))
    again = opendrive_root(path)
    assert again is not first and again.find("road").get("id") == "22"


def test_a_broken_or_missing_file_raises_on_every_read(tmp_path):
    broken = tmp_path / "broken.xodr"
    broken.write_text("<OpenDRIVE><road>")
    for _ in range(2):
        with pytest.raises(ElementTree.ParseError):
            opendrive_root(broken)
    with pytest.raises(OSError):
        opendrive_root(tmp_path / "none.xodr")
    assert "roadMark records not read" in read_road_marks(broken).problem
    assert read_signs(broken).signs == ()


def test_polyline_length_is_the_last_arc_length_to_the_metre():
    rng = np.random.default_rng(3)
    for _ in range(50):
        points = rng.normal(size=(int(rng.integers(2, 40)), 3)) * 30.0
        assert polyline_length(points) == pytest.approx(arc_lengths(points)[-1], rel=1e-12)
    assert polyline_length(np.zeros((1, 2))) == 0.0
