"""The signal labels of a frame, without SUMO: heads' lamps from their traffic light's states,
plates' kinds, the lanes each governs, whether it governs the ego's lane."""

from __future__ import annotations

from types import SimpleNamespace
from typing import Any

import numpy as np

from gtgen.signals import signal_labels
from networks.classes import SemanticClass
from networks.street import STREET_ID_BASE, StreetObject
from networks.vocabulary import Lamp, SignalState


def _object(
    k: int, cls: SemanticClass, subtype: str, lanes: tuple[str, ...], tls: str = "", link: int = -1
) -> StreetObject:
    return StreetObject(STREET_ID_BASE + k, cls, subtype, "e1", lanes, (0.0, 0.0, 3.0), 0.0, (0.3, 0.3, 1.0),
                        (0.0, 0.0, 0.0), 3.0, tls, link)  # fmt: skip


def test_heads_show_their_links_lamp_and_plates_their_kind_for_the_labelled_objects_only() -> None:
    objects = (
        _object(0, SemanticClass.TRAFFIC_LIGHT, "signal_head", ("e1_0",), "j1", 0),
        _object(1, SemanticClass.TRAFFIC_LIGHT, "signal_head", ("e1_1", "e1_2"), "j1", 2),
        _object(2, SemanticClass.TRAFFIC_LIGHT, "signal_head", ("e2_0",), "j9", 0),  # a light with no state
        _object(3, SemanticClass.TRAFFIC_SIGN, "speed_limit_50", ("e1_0", "e1_1")),
    )
    # a car and three of the four street objects in the frame (the second head is out of range)
    track = np.array([7, STREET_ID_BASE + 3, STREET_ID_BASE + 0, STREET_ID_BASE + 2], np.uint32)
    cls = np.array([SemanticClass.CAR, SemanticClass.TRAFFIC_SIGN, SemanticClass.TRAFFIC_LIGHT,
                    SemanticClass.TRAFFIC_LIGHT], np.uint8)  # fmt: skip
    labels: Any = SimpleNamespace(objects=SimpleNamespace(track_id=track, semantic_class=cls))
    states = {"j1": (SignalState.RED, SignalState.GREEN_MAJOR, SignalState.YELLOW)}
    got = signal_labels(labels, objects, states, "e1_1")
    assert got.track_id.tolist() == [STREET_ID_BASE + 3, STREET_ID_BASE, STREET_ID_BASE + 2]
    assert got.subtype == ("speed_limit_50", "signal_head", "signal_head")
    assert got.state == ("", Lamp.RED, Lamp.OFF)
    assert got.junction == ("", "j1", "j9")
    assert got.lanes == ("e1_0 e1_1", "e1_0", "e2_0")
    assert got.governs_ego_lane.tolist() == [True, False, False]
