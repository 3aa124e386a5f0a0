"""Road markings as classed geometry: lane lines, edge lines, stop and give-way lines and zebra
stripes, thin strips a few millimetres above the road surface.

Lane lines come from the OpenDRIVE file's ``roadMark`` records (type, colour, width, where
along the lane each starts), placed on the SUMO lanes converted from that file (each SUMO lane
knows its OpenDRIVE road and lane through netconvert's ``origId``), so a user's map keeps its
own markings and they lie exactly on the world mesh's lanes. A road without readable
``roadMark`` records gets markings from rules on its SUMO lanes: broken lines between lanes of
one direction, a solid line between directions, solid edge lines where the road has no
sidewalk. Stop lines are painted where a lane enters a junction under a traffic light or a
stop rule, give-way lines where it must yield; crossings get zebra stripes; street-parking lanes
(OpenDRIVE lane type ``parking``) get a line across them between their spaces
(:func:`parking_space_centres`, where the traffic parks its vehicles).

White paint is :attr:`SemanticClass.LANE_MARKING`, yellow paint
:attr:`SemanticClass.LANE_MARKING_YELLOW`.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path
from xml.etree import ElementTree

import numpy as np
import numpy.typing as npt
import sumolib

from networks.classes import SemanticClass
from networks.geometry import arc_lengths, polyline_length
from networks.mesh import ClassedMesh, merge, polyline_normals, ribbon
from networks.opendrive import opendrive_root
from networks.vocabulary import LinePattern, LineRole

MARKINGS_VERSION = "6"  # part of the world cache key: change it when the markings change
PAINT_HEIGHT_M = 0.005  # above the lane surface
CROSSING_PAINT_HEIGHT_M = 0.013  # 3 mm above the crossing's own strip (1 cm above the road)
LINE_WIDTH_M = {"standard": 0.12, "bold": 0.25}
DOUBLE_GAP_M = 0.12  # between the two lines of a double line
EDGE_INSET_M = 0.1  # an edge line's outer side this far inside the road's edge
DASH_M = {"town": (3.0, 6.0), "fast": (6.0, 12.0)}  # dash and gap of broken lines (RMS 1980, Germany)
FAST_SPEED_MPS = 70.0 / 3.6
BOTTS_DOTS_M = (0.15, 1.0)
STOP_LINE_WIDTH_M = 0.3  # along the lane (UK 0.3 m; US MUTCD 12-24 in)
GIVE_WAY_WIDTH_M = 0.3
GIVE_WAY_DASH_M = (0.5, 0.25)
LINE_BACK_M = 0.3  # a stop line's far side this far before the lane's end
ZEBRA_STRIPE_M = 0.5  # along the walking direction (Germany and UK: 0.5 m bars, 0.5 m gaps)
ZEBRA_MARGIN_M = 0.25  # each end of a bar inside the crossing's width
PARKING_SPACE_M = 6.0  # a street-parking space's length along its lane, end to end with the next
PARKING_END_M = 4.0  # a parking lane's first and last space this far from its ends
BAY_LINE_WIDTH_M = 0.12  # the lines between parking spaces, along the lane
BAY_LINE_INSET_M = 0.05  # each end of a bay line inside the parking lane's width

PAINTED_TYPES = ("solid", "broken", "solid solid", "solid broken", "broken solid", "broken broken", "botts dots")
UNPAINTED_TYPES = ("none", "grass", "curb", "custom", "edge")
_YELLOW = ("yellow", "orange")
_STOP_STATES = frozenset("sw")  # SUMO link states: stop sign, all-way stop
_YIELD_STATES = frozenset("m")  # minor link: give way


@dataclass(frozen=True, slots=True)
class RoadMark:
    """One ``roadMark`` record: from ``s_offset_m`` of its lane section on."""

    s_offset_m: float
    kind: str  # one of PAINTED_TYPES or UNPAINTED_TYPES
    yellow: bool
    width_m: float


@dataclass(frozen=True, slots=True)
class LaneSection:
    s_m: float
    length_m: float
    marks: dict[int, tuple[RoadMark, ...]]  # OpenDRIVE lane id -> its marks, by s_offset


@dataclass(frozen=True, slots=True)
class RoadMarks:
    """The ``roadMark`` records of an OpenDRIVE file, by road id (roads with none or with
    unreadable ones are left out), and what could not be read (one line, '' if all could)."""

    roads: dict[str, tuple[LaneSection, ...]]
    problem: str = ""


def read_road_marks(xodr_path: Path | None) -> RoadMarks:
    """Every road's ``roadMark`` records; a road with an unreadable record is left out (its
    markings then come from the lane rules) and the first such record is named in ``problem``."""
    if xodr_path is None:
        return RoadMarks({})
    try:
        root = opendrive_root(xodr_path)
    except (ElementTree.ParseError, OSError) as err:
        return RoadMarks({}, f"{xodr_path}: roadMark records not read ({err})")
    roads: dict[str, tuple[LaneSection, ...]] = {}
    bad: list[str] = []
    for road in root.iter("road"):
        road_id = road.get("id", "")
        try:
            sections = _sections(road)
        except ValueError as err:
            bad.append(f"road {road_id}: {err}")
            continue
        if any(section.marks for section in sections):
            roads[road_id] = sections
    problem = ""
    if bad:
        problem = (
            f"{xodr_path}: {len(bad)} road(s) with unreadable roadMark records (first: {bad[0]}); "
            "their markings follow the lane rules instead"
        )
    return RoadMarks(roads, problem)


def _sections(road: ElementTree.Element) -> tuple[LaneSection, ...]:
    road_length = _number(road.get("length"), "length", 0.0)
    found = road.findall("lanes/laneSection")
    starts = [_number(sec.get("s"), "laneSection s", 0.0) for sec in found]
    sections = []
    for k, sec in enumerate(found):
        end = starts[k + 1] if k + 1 < len(found) else road_length
        marks: dict[int, tuple[RoadMark, ...]] = {}
        for lane in sec.iter("lane"):
            records = lane.findall("roadMark")
            if not records:
                continue
            lane_id = int(_number(lane.get("id"), "lane id", None))
            marks[lane_id] = tuple(sorted((_mark(r, lane_id) for r in records), key=lambda m: m.s_offset_m))
        sections.append(LaneSection(starts[k], max(end - starts[k], 1e-6), marks))
    return tuple(sections)


def _mark(record: ElementTree.Element, lane_id: int) -> RoadMark:
    kind = " ".join((record.get("type") or "none").split()).lower()
    if kind not in PAINTED_TYPES and kind not in UNPAINTED_TYPES:
        raise ValueError(
            f"lane {lane_id}: roadMark type {record.get('type')!r} (expected one of "
            f"{', '.join(PAINTED_TYPES + UNPAINTED_TYPES)})"
        )
    weight = (record.get("weight") or "standard").lower()
    width = _number(record.get("width"), f"lane {lane_id}: roadMark width", 0.0)
    if width <= 0.0 or width > 1.0:
        width = LINE_WIDTH_M.get(weight, LINE_WIDTH_M["standard"])
    s_offset = _number(record.get("sOffset"), f"lane {lane_id}: roadMark sOffset", 0.0)
    return RoadMark(max(s_offset, 0.0), kind, (record.get("color") or "").lower() in _YELLOW, width)


def _number(text: str | None, what: str, default: float | None) -> float:
    if text is None or not text.strip():
        if default is None:
            raise ValueError(f"{what} missing")
        return default
    try:
        value = float(text)
    except ValueError:
        raise ValueError(f"{what} {text!r} is not a number") from None
    if not math.isfinite(value):
        raise ValueError(f"{what} {text!r} is not finite")
    return value


def is_left_hand(net_path: Path) -> bool:
    """Whether a SUMO network drives on the left (its ``<net lefthand="true">``)."""
    with open(net_path, encoding="utf-8") as f:
        head = f.read(4096)
    match = re.search(r"<net\s[^>]*>", head)
    return bool(match and re.search(r'\slefthand="(true|1)"', match.group(0)))


@dataclass(frozen=True, slots=True)
class _Line:
    """A painted line along a lane: its lateral offset from the lane's centre line (left
    positive), the part of the lane it covers, how it is painted."""

    offset_m: float
    s0_m: float
    s1_m: float
    kind: str
    yellow: bool
    width_m: float
    role: LineRole = LineRole.DIVIDER  # between lanes (of one direction or of both), or at the road's edge


@dataclass(frozen=True, slots=True)
class PaintedLine:
    """One painted line, as the map knows it: ``role`` (``divider``: between lanes, of one
    direction or of both; ``edge``: the road's edge line; ``stop`` or ``give_way``: across a
    lane's end), ``pattern`` (``solid``, ``broken``, ``botts dots``), colour, width, the
    ``(K, 3)`` polyline of its middle (a double line is two lines), the SUMO lane it belongs to
    and, for a broken line, its dash and gap lengths along the polyline from its start."""

    role: LineRole
    pattern: LinePattern
    yellow: bool
    width_m: float
    polyline_m: npt.NDArray[np.float64]
    lane_id: str
    dash_m: tuple[float, float] | None


def painted_lines(net: sumolib.net.Net, marks: RoadMarks, left_hand: bool) -> list[PaintedLine]:
    """Every lane, edge, stop and give-way line of a network, in a stable order."""
    out: list[PaintedLine] = []
    centre_lines_seen: set[tuple[tuple[float, float], ...]] = set()
    outer = 1.0 if left_hand else -1.0  # the side of a lane away from the road's centre (left is +)
    for edge in sorted(net.getEdges(withInternal=False), key=lambda e: e.getID()):
        if edge.getFunction():
            continue
        lanes = sorted(edge.getLanes(), key=lambda lane: lane.getIndex())
        for lane in lanes:
            if not _paved_for_vehicles(lane) or len(lane.getShape()) < 2:
                continue
            for line in _lines_of(edge, lanes, lane, marks, outer, centre_lines_seen):
                out += _single_lines(lane, line, outer)
            stop = _stop_line(lane)
            if stop is not None:
                out.append(stop)
    return out


def crossing_lanes(net: sumolib.net.Net) -> list[sumolib.net.lane.Lane]:
    """The network's pedestrian crossings (painted as zebras), in a stable order."""
    edges = [e for e in net.getEdges(withInternal=True) if e.getFunction() == "crossing"]
    edges.sort(key=lambda e: e.getID())
    return [lane for edge in edges for lane in edge.getLanes()]


def marking_mesh(
    net: sumolib.net.Net, marks: RoadMarks, left_hand: bool, lane_types: dict[str, str] | None = None
) -> ClassedMesh:
    """All markings of a network: lane and edge lines, stop and give-way lines, zebra stripes,
    and the lines between the spaces of the lanes ``lane_types`` (lane id -> OpenDRIVE lane
    type) names ``parking``."""
    parts = [_paint(line) for line in painted_lines(net, marks, left_hand)]
    parts += [_zebra(lane) for lane in crossing_lanes(net)]
    types = lane_types or {}
    edges = sorted(net.getEdges(withInternal=False), key=lambda e: e.getID())
    parking = [lane for edge in edges for lane in edge.getLanes() if types.get(lane.getID()) == "parking"]
    return merge(parts + [_bay_lines(lane) for lane in parking])


def parking_space_centres(length_m: float) -> list[float]:
    """Where along a parking lane of ``length_m`` (its centre line's length in the plane) its
    spaces' centres lie: ``PARKING_SPACE_M`` long, end to end, the outer ones ``PARKING_END_M``
    clear of the lane's ends."""
    centres = []
    s = PARKING_END_M + PARKING_SPACE_M / 2
    while s <= length_m - PARKING_END_M - PARKING_SPACE_M / 2:
        centres.append(s)
        s += PARKING_SPACE_M
    return centres


def _bay_lines(lane: sumolib.net.lane.Lane) -> ClassedMesh:
    """A line across a parking lane at each end of each of its spaces."""
    raw = np.asarray(lane.getShape3D(), np.float64)
    shape = _clean(raw)
    centres = parking_space_centres(polyline_length(raw))
    if shape.shape[0] < 2 or not centres:
        return ClassedMesh.empty()
    half = lane.getWidth() / 2.0 - BAY_LINE_INSET_M
    lines = []
    for s in [c - PARKING_SPACE_M / 2 for c in centres] + [centres[-1] + PARKING_SPACE_M / 2]:
        across = _across(shape, s, s + 0.02, half)
        lines.append(ribbon(across, BAY_LINE_WIDTH_M, SemanticClass.LANE_MARKING, PAINT_HEIGHT_M))
    return merge(lines)


def _across(shape: npt.NDArray[np.float64], s0_m: float, s1_m: float, half_m: float) -> npt.NDArray[np.float64]:
    """The ``(2, 3)`` line across a lane whose centre line is ``shape``, through its point ``s0_m``
    along it, square to its direction from there to ``s1_m`` (a little further), reaching
    ``half_m`` to each side."""
    piece = _cut(shape, s0_m, s1_m)
    c, heading = piece[0], piece[-1, :2] - piece[0, :2]
    left = np.array([-heading[1], heading[0]]) / max(float(np.linalg.norm(heading)), 1e-9)
    return np.array([[*(c[:2] + left * half_m), c[2]], [*(c[:2] - left * half_m), c[2]]])


def _paint(line: PaintedLine) -> ClassedMesh:
    """The strips of one painted line (its dashes, if broken)."""
    cls = SemanticClass.LANE_MARKING_YELLOW if line.yellow else SemanticClass.LANE_MARKING
    p = line.polyline_m
    length = polyline_length(p)
    if line.dash_m is None:
        return ribbon(p, line.width_m, cls, PAINT_HEIGHT_M)
    on, off = line.dash_m
    return merge([ribbon(_cut(p, a, min(a + on, length)), line.width_m, cls, PAINT_HEIGHT_M)
                  for a in np.arange(0.0, length - 0.05, on + off)])  # fmt: skip


def _paved_for_vehicles(lane: sumolib.net.lane.Lane) -> bool:
    """A lane whose surface is road (driving, parking, shoulder...), not a sidewalk."""
    return bool(lane.getPermissions() != {"pedestrian"})


def _lines_of(
    edge: sumolib.net.edge.Edge, lanes: list[sumolib.net.lane.Lane], lane: sumolib.net.lane.Lane,
    marks: RoadMarks, outer: float, centre_lines_seen: set[tuple[tuple[float, float], ...]],
) -> list[_Line]:  # fmt: skip
    """The lines along ``lane``'s outer side, and along its inner side if it is the innermost."""
    i, width, length = lane.getIndex(), lane.getWidth(), lane.getLength()
    lines: list[_Line] = []
    neighbour = lanes[i - 1] if i > 0 else None
    if neighbour is None or _paved_for_vehicles(neighbour):  # beside a sidewalk: a kerb, no paint
        at_edge = neighbour is None
        for mark in _outer_marks(edge, lane, neighbour, marks):
            lines.append(
                _placed(mark, outer * width / 2.0, at_edge, outer, LineRole.EDGE if at_edge else LineRole.DIVIDER)
            )
    if i == len(lanes) - 1:
        key = _centre_key(lane, outer)
        if key not in centre_lines_seen:
            centre_lines_seen.add(key)
            for mark in _centre_marks(edge, lane, marks):
                one_way = _is_edge(edge)
                lines.append(
                    _placed(mark, -outer * width / 2.0, one_way, -outer, LineRole.EDGE if one_way else LineRole.DIVIDER)
                )
    return [_clipped(line, length) for line in lines]


def _clipped(line: _Line, length_m: float) -> _Line:
    """``line`` with its span clipped to the lane's length."""
    return _Line(
        line.offset_m, max(line.s0_m, 0.0), min(line.s1_m, length_m), line.kind, line.yellow, line.width_m, line.role
    )


def _placed(mark: _Line, boundary_m: float, at_edge: bool, side: float, role: LineRole) -> _Line:
    """A line on the lane boundary at ``boundary_m``; at the road's edge moved inside it."""
    offset = boundary_m - side * (_painted_width(mark) / 2.0 + EDGE_INSET_M) if at_edge else boundary_m
    return _Line(offset, mark.s0_m, mark.s1_m, mark.kind, mark.yellow, mark.width_m, role)


def _painted_width(line: _Line) -> float:
    return 2 * line.width_m + DOUBLE_GAP_M if " " in line.kind and line.kind != "botts dots" else line.width_m


def _is_edge(edge: sumolib.net.edge.Edge) -> bool:
    """Whether no road runs the other way between the same junctions: the inner side of a
    one-way road's innermost lane is then the road's edge."""
    back = edge.getFromNode()
    return not any(e.getToNode() is back for e in edge.getToNode().getOutgoing() if not e.getFunction())


def _centre_key(lane: sumolib.net.lane.Lane, outer: float) -> tuple[tuple[float, float], ...]:
    """The inner boundary's ends, rounded and unordered: both directions of a road share it."""
    shape = np.asarray(lane.getShape(), np.float64)
    normals = polyline_normals(shape[:, :2])
    inner = shape + normals * (-outer * lane.getWidth() / 2.0)
    ends = sorted((round(float(p[0]) * 2) / 2, round(float(p[1]) * 2) / 2) for p in (inner[0], inner[-1]))
    return tuple(ends)


def _od_lane(lane: sumolib.net.lane.Lane, marks: RoadMarks) -> tuple[LaneSection, int] | None:
    """The OpenDRIVE lane section and lane id a SUMO lane was converted from (None if unknown
    or if the road has no readable marks)."""
    orig = lane.getParam("origId", "") or ""
    road_id, _, lane_text = orig.rpartition("_")
    sections = marks.roads.get(road_id)
    if not sections:
        return None
    try:
        lane_id = int(lane_text)
    except ValueError:
        return None
    s_start = section_start(lane.getEdge().getID(), road_id)
    section = sections[0]
    for candidate in sections:
        if candidate.s_m <= s_start + 1e-3:
            section = candidate
    return section, lane_id


def section_start(edge_id: str, road_id: str) -> float:
    """Where the lane section of a SUMO edge converted from road ``road_id`` starts (netconvert
    names further sections ``<road>.<s>``; 0 for the first)."""
    rest = edge_id.lstrip("-")
    if rest.startswith(road_id + "."):
        try:
            return float(rest[len(road_id) + 1 :])
        except ValueError:
            return 0.0
    return 0.0


def _spans(records: tuple[RoadMark, ...], section: LaneSection, length_m: float, reversed_: bool) -> list[_Line]:
    """A lane section's marks as spans of a SUMO lane ``length_m`` long (against the road's
    direction if ``reversed_``)."""
    out = []
    for k, mark in enumerate(records):
        end = records[k + 1].s_offset_m if k + 1 < len(records) else section.length_m
        a, b = mark.s_offset_m / section.length_m, min(end / section.length_m, 1.0)
        if b <= a or mark.kind not in PAINTED_TYPES:
            continue
        if reversed_:
            a, b = 1.0 - b, 1.0 - a
        out.append(_Line(0.0, a * length_m, b * length_m, mark.kind, mark.yellow, mark.width_m))
    return out


def _outer_marks(
    edge: sumolib.net.edge.Edge,
    lane: sumolib.net.lane.Lane,
    neighbour: sumolib.net.lane.Lane | None,
    marks: RoadMarks,
) -> list[_Line]:
    found = _od_lane(lane, marks)
    if found is not None:
        section, lane_id = found
        return _spans(section.marks.get(lane_id, ()), section, lane.getLength(), reversed_=lane_id > 0)
    length = lane.getLength()
    if neighbour is not None and _drives(lane) and _drives(neighbour):
        return [_Line(0.0, 0.0, length, "broken", False, LINE_WIDTH_M["standard"])]
    if _drives(lane) or neighbour is not None:  # the road's edge, or beside a parking lane
        return [_Line(0.0, 0.0, length, "solid", False, LINE_WIDTH_M["standard"])]
    return []


def _centre_marks(edge: sumolib.net.edge.Edge, lane: sumolib.net.lane.Lane, marks: RoadMarks) -> list[_Line]:
    found = _od_lane(lane, marks)
    if found is not None:
        section, lane_id = found
        return _spans(section.marks.get(0, ()), section, lane.getLength(), reversed_=lane_id > 0)
    if not _drives(lane):
        return []
    return [_Line(0.0, 0.0, lane.getLength(), "solid", False, LINE_WIDTH_M["standard"])]


def _drives(lane: sumolib.net.lane.Lane) -> bool:
    return bool(lane.getPermissions() - {"pedestrian"})


def _clean(shape: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
    keep = np.concatenate([[True], np.linalg.norm(np.diff(shape[:, :2], axis=0), axis=1) > 1e-3])
    return np.asarray(shape[keep], np.float64)


def _cut(shape: npt.NDArray[np.float64], s0: float, s1: float) -> npt.NDArray[np.float64]:
    """The part of a ``(K, 3)`` polyline between arc lengths ``s0`` and ``s1``."""
    s = arc_lengths(shape)
    inside = shape[(s > s0) & (s < s1)]
    ends = [np.array([np.interp(v, s, shape[:, k]) for k in range(3)]) for v in (s0, s1)]
    return np.vstack([ends[0], inside, ends[1]])


def _single_lines(lane: sumolib.net.lane.Lane, line: _Line, outer: float) -> list[PaintedLine]:
    """A lane's line as single painted lines (two for a double line), cut to its span."""
    shape = _clean(np.asarray(lane.getShape3D(), np.float64))
    if shape.shape[0] < 2 or line.s1_m - line.s0_m < 0.05:
        return []
    kinds = line.kind.split() if line.kind != "botts dots" else ["botts dots"]
    half_gap = (line.width_m + DOUBLE_GAP_M) / 2.0  # of a double line: the first type nearer the road's centre
    offsets = [line.offset_m]
    if len(kinds) == 2:
        offsets = [line.offset_m - outer * half_gap, line.offset_m + outer * half_gap]
    dash = DASH_M["fast" if lane.getSpeed() > FAST_SPEED_MPS else "town"]
    out = []
    for kind, offset in zip(kinds, offsets, strict=True):
        moved = shape.copy()
        moved[:, :2] += polyline_normals(shape[:, :2]) * offset
        pattern = LinePattern(kind)
        pattern_dash = (
            None if pattern is LinePattern.SOLID else BOTTS_DOTS_M if pattern is LinePattern.BOTTS_DOTS else dash
        )
        out.append(PaintedLine(line.role, pattern, line.yellow, line.width_m, _cut(moved, line.s0_m, line.s1_m),
                               lane.getID(), pattern_dash))  # fmt: skip
    return out


def _stop_line(lane: sumolib.net.lane.Lane) -> PaintedLine | None:
    """A solid stop line across the lane's end under a traffic light or a stop rule, a broken
    give-way line where its links must yield; nothing where it has right of way."""
    links = [c for c in lane.getOutgoing() if c.getToLane() is not None]
    if not links or not _drives(lane):
        return None
    states = {c.getState() for c in links}
    signalled = any(c.getTLSID() for c in links)
    if signalled or states & _STOP_STATES:
        role, width, dashes = LineRole.STOP, STOP_LINE_WIDTH_M, None
    elif states & _YIELD_STATES:
        role, width, dashes = LineRole.GIVE_WAY, GIVE_WAY_WIDTH_M, GIVE_WAY_DASH_M
    else:
        return None
    shape = _clean(np.asarray(lane.getShape3D(), np.float64))
    length = polyline_length(shape)
    if shape.shape[0] < 2 or length < width + LINE_BACK_M + 0.5:
        return None
    s = length - LINE_BACK_M - width / 2.0
    across = _across(shape, s - 0.01, s + 0.01, lane.getWidth() / 2.0 - 0.05)
    pattern = LinePattern.SOLID if dashes is None else LinePattern.BROKEN
    return PaintedLine(role, pattern, False, width, across, lane.getID(), dashes)


def _zebra(lane: sumolib.net.lane.Lane) -> ClassedMesh:
    """Stripes across a crossing, parallel to the traffic, ``ZEBRA_STRIPE_M`` wide and apart."""
    shape = _clean(np.asarray(lane.getShape3D(), np.float64))
    if shape.shape[0] < 2:
        return ClassedMesh.empty()
    length = polyline_length(shape)
    bar = lane.getWidth() - 2 * ZEBRA_MARGIN_M
    if bar <= 0.2 or length < 2 * ZEBRA_STRIPE_M:
        return ClassedMesh.empty()
    count = int((length + ZEBRA_STRIPE_M) // (2 * ZEBRA_STRIPE_M))
    start = (length - (2 * count - 1) * ZEBRA_STRIPE_M) / 2.0  # stripes centred on the crossing
    return merge(
        [
            ribbon(_cut(shape, a, a + ZEBRA_STRIPE_M), bar, SemanticClass.LANE_MARKING, CROSSING_PAINT_HEIGHT_M)
            for a in start + 2 * ZEBRA_STRIPE_M * np.arange(count)
        ]
    )
