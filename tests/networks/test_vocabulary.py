"""The shared words (networks.vocabulary) and every table keyed by them: each covers its whole set."""

from enum import Enum

import pytest

from cosim.sumo.hazards.controller import LEADS_S, PREPARED_AT_ONCE
from gtgen.colours import CLASS_RGB
from gtgen.nuscenes import CATEGORIES
from gtgen.nuscenes_lidarseg import _CATEGORY_OF
from gtgen.signals import STATE_RGB
from gtgen.sinks import group
from gtgen.sinks.kitti_sink import KITTI_TYPES, SEMANTIC_KITTI_IDS
from gtgen.sinks.yolo_sink import LIGHT_CLASSES, SIGN_CLASSES, YOLO_NAMES
from gtgen.static_map import MAP_RGBA
from networks.classes import AGENT_CLASSES, SemanticClass
from networks.hdmap import ROLE_TYPE
from networks.street import SIGN_LWH_M
from networks.vocabulary import (
    LAMP_OF_STATE,
    HazardKind,
    Lamp,
    LinePattern,
    LineRole,
    SensorKind,
    SignalState,
    SignKind,
    SinkKind,
    parse,
    sign_kind,
    speed_limit_subtype,
)
from sensors.bodies import BODIES
from sensors.materials import _REFLECTIVITY
from sensors.shading import LIT_LAMPS, SIGN_FACES

STATIC_CLASSES = [c for c in SemanticClass if not c.is_agent and c is not SemanticClass.NONE]
TABLES: list[tuple[str, object, list[Enum]]] = [
    ("SignalState -> Lamp", LAMP_OF_STATE, list(SignalState)),
    ("hazard leads", LEADS_S, list(HazardKind)),
    ("hazard events prepared at once", PREPARED_AT_ONCE, list(HazardKind)),
    ("sink chosen", group._CHOSEN, list(SinkKind)),
    ("sink output names", group.OUTPUT_NAMES, list(SinkKind)),
    ("sink openers", group._OPEN, list(SinkKind)),
    ("lit lamps", LIT_LAMPS, list(Lamp)),
    ("state colours", STATE_RGB, list(Lamp)),
    ("YOLO light classes", LIGHT_CLASSES, list(Lamp)),
    ("YOLO sign classes", SIGN_CLASSES, list(SignKind)),
    ("sign sizes", SIGN_LWH_M, list(SignKind)),
    ("sign faces", SIGN_FACES, list(SignKind)),
    ("map element of a line role", ROLE_TYPE, list(LineRole)),
    ("class colours", CLASS_RGB, [c for c in SemanticClass if c is not SemanticClass.NONE]),
    ("static map colours", MAP_RGBA, STATIC_CLASSES),
    ("nuScenes categories", CATEGORIES, list(AGENT_CLASSES)),
    ("KITTI types", KITTI_TYPES, list(AGENT_CLASSES)),
    ("agent bodies", BODIES, list(AGENT_CLASSES)),
    ("SemanticKITTI ids", SEMANTIC_KITTI_IDS, list(SemanticClass)),
    ("lidarseg categories", _CATEGORY_OF, list(SemanticClass)),
    ("LiDAR reflectivity", _REFLECTIVITY, list(SemanticClass)),
]


@pytest.mark.parametrize(("name", "table", "members"), TABLES, ids=[t[0] for t in TABLES])
def test_every_table_covers_every_member_of_its_set(name: str, table: dict[object, object], members: list[Enum]):
    missing = [m for m in members if m not in table]
    assert not missing, f"{name}: no entry for {missing}"


def test_members_write_the_words_they_stand_for():
    assert [str(k) for k in SensorKind] == ["lidar", "camera", "radar"]
    assert f"{HazardKind.CUT_IN}-3" == "cut_in-3"
    assert LinePattern.BOTTS_DOTS == "botts dots"
    assert [str(lamp) for lamp in Lamp] == ["red", "yellow", "green", "red_yellow", "off"]


def test_yolo_class_ids_keep_their_numbers():
    names = [YOLO_NAMES[i] for i in range(6, 14)]
    assert names[:5] == [f"traffic_light_{s}" for s in ("red", "yellow", "green", "red_yellow", "off")]
    assert names[5:] == ["traffic_sign_stop", "traffic_sign_yield", "traffic_sign_speed_limit"]


def test_a_word_outside_the_set_names_the_set_and_its_words():
    assert parse(SensorKind, "radar") is SensorKind.RADAR
    with pytest.raises(
        ValueError, match=r"'sonar' is not a sensor kind \(expected one of 'lidar', 'camera', 'radar'\)"
    ):
        parse(SensorKind, "sonar")


def test_a_plates_subtype_names_its_sign_kind():
    assert speed_limit_subtype(50) == "speed_limit_50"
    assert [sign_kind(s) for s in ("stop", "yield", "speed_limit_30")] == list(SignKind)
    with pytest.raises(ValueError, match="sign kind"):
        sign_kind("signal_head")


def test_signal_letters_decode_to_states_and_lamps():
    states = SignalState.decode("GgsryYuoO")
    assert len(set(states)) == len(SignalState)
    assert [s.lamp for s in SignalState.decode("Gryu")] == [Lamp.GREEN, Lamp.RED, Lamp.YELLOW, Lamp.RED_YELLOW]
    assert SignalState.of("x") is SignalState.OFF
