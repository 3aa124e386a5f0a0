"""The closed sets of words the packages share: sensor kinds, hazard kinds, sink kinds, the
state of a traffic light's link and the lamp a head shows, sign kinds, and the roles and
patterns of painted lines.

Every member is a string (:class:`enum.StrEnum`) whose value is the word the outputs carry
(CSV columns, JSON, MCAP messages, file names), so writing a member writes the same bytes as
the word did. Words from outside (a scenario's YAML, an OpenDRIVE file) become members where
they are read; :func:`parse` names the set and the words it holds when one does not fit.

The module sits at the ground floor (it imports nothing of the project), so every package
reads the same words; the tables keyed by these sets live beside the code that uses them.
"""

from __future__ import annotations

from enum import Enum, StrEnum
from typing import TypeVar

E = TypeVar("E", bound=StrEnum)


class SensorKind(StrEnum):
    """What a sensor measures, in rig order."""

    LIDAR = "lidar"
    CAMERA = "camera"
    RADAR = "radar"


class HazardKind(StrEnum):
    """A kind of hazard event a scenario asks for."""

    CUT_IN = "cut_in"
    HARD_BRAKE = "hard_brake"
    JAYWALKER = "jaywalker"
    RED_LIGHT = "red_light"


class SinkKind(StrEnum):
    """One output of a run, in the order the sinks open (and see each frame)."""

    MCAP = "mcap"
    CSV = "csv"
    LIGHTS_CSV = "lights_csv"
    EVENTS = "events"
    KITTI = "kitti"
    YOLO = "yolo"
    MAP = "map"
    NUSCENES = "nuscenes"
    OCCUPANCY = "occupancy"
    LIVE = "live"
    RESUME = "resume"


class Lamp(StrEnum):
    """What a signal head shows (its lit lamps), in the order of the YOLO classes."""

    RED = "red"
    YELLOW = "yellow"
    GREEN = "green"
    RED_YELLOW = "red_yellow"
    OFF = "off"


class SignalState(Enum):
    """One letter of a SUMO traffic light's state string (one a controlled link, as
    ``libsumo.trafficlight.getRedYellowGreenState`` and ``getNextTLS`` give it), decoded."""

    GREEN_MAJOR = "G"  # green, with priority
    GREEN_MINOR = "g"  # green, giving way to links with priority
    GREEN_AFTER_STOP = "s"  # a green arrow after a stop (a right turn on red)
    RED = "r"
    YELLOW = "y"
    YELLOW_MAJOR = "Y"
    RED_YELLOW = "u"
    OFF_BLINKING = "o"
    OFF = "O"

    @classmethod
    def of(cls, letter: str) -> SignalState:
        """The state of a letter (a letter SUMO does not define: off)."""
        return _STATE_OF_LETTER.get(letter, cls.OFF)

    @classmethod
    def decode(cls, text: str) -> tuple[SignalState, ...]:
        """A light's state string, one state a link."""
        return tuple(cls.of(letter) for letter in text)

    @property
    def lamp(self) -> Lamp:
        """The lamp a head shows in this state."""
        return LAMP_OF_STATE[self]

    @property
    def is_green(self) -> bool:
        """Green (``G``, ``g``): a vehicle may go (the arrow after a stop is not)."""
        return self in (SignalState.GREEN_MAJOR, SignalState.GREEN_MINOR)

    @property
    def is_red(self) -> bool:
        return self is SignalState.RED

    @property
    def is_yellow(self) -> bool:
        return self in (SignalState.YELLOW, SignalState.YELLOW_MAJOR)


_STATE_OF_LETTER = {s.value: s for s in SignalState}
LAMP_OF_STATE: dict[SignalState, Lamp] = {
    SignalState.GREEN_MAJOR: Lamp.GREEN,
    SignalState.GREEN_MINOR: Lamp.GREEN,
    SignalState.GREEN_AFTER_STOP: Lamp.GREEN,
    SignalState.RED: Lamp.RED,
    SignalState.YELLOW: Lamp.YELLOW,
    SignalState.YELLOW_MAJOR: Lamp.YELLOW,
    SignalState.RED_YELLOW: Lamp.RED_YELLOW,
    SignalState.OFF_BLINKING: Lamp.OFF,
    SignalState.OFF: Lamp.OFF,
}


class SignKind(StrEnum):
    """What a sign plate says (a speed limit's value is the plate's own: ``speed_limit_<km/h>``)."""

    STOP = "stop"
    YIELD = "yield"
    SPEED_LIMIT = "speed_limit"


class LineRole(StrEnum):
    """Where a painted line stands: between lanes, at the road's edge, across a lane's end."""

    DIVIDER = "divider"
    EDGE = "edge"
    STOP = "stop"
    GIVE_WAY = "give_way"


class LinePattern(StrEnum):
    """How a painted line is drawn along its length."""

    SOLID = "solid"
    BROKEN = "broken"
    BOTTS_DOTS = "botts dots"


def parse(kind: type[E], word: str) -> E:
    """The member of ``kind`` whose value is ``word``; ``ValueError`` naming the words it holds
    otherwise."""
    try:
        return kind(word)
    except ValueError:
        known = ", ".join(repr(m.value) for m in kind)
        raise ValueError(f"{word!r} is not a {_words(kind)} (expected one of {known})") from None


def _words(kind: type[StrEnum]) -> str:
    """``SensorKind`` -> ``sensor kind``."""
    name = kind.__name__
    return "".join(f" {c.lower()}" if c.isupper() and k else c.lower() for k, c in enumerate(name))


SIGNAL_HEAD = "signal_head"  # a signal head's subtype (a plate's subtype is its sign's)


def speed_limit_subtype(kmh: int) -> str:
    """A speed-limit plate's subtype: ``speed_limit_<km/h>``."""
    return f"{SignKind.SPEED_LIMIT.value}_{kmh}"


def sign_kind(subtype: str) -> SignKind:
    """The kind of sign a plate's subtype names (``speed_limit_50``: a speed limit);
    ``ValueError`` for any other word (a signal head's)."""
    if subtype.startswith(f"{SignKind.SPEED_LIMIT.value}_"):
        return SignKind.SPEED_LIMIT
    return parse(SignKind, subtype)
