"""Traffic lights and signs along the streets, each on a pole by the road, on the right (the
left in left-hand traffic).

Traffic lights: every SUMO traffic light (``tlLogic``) controls links from incoming lanes; the
lanes of one incoming edge that it controls form an approach and get one signal head by the
stop line: a housing 0.35 m wide, 1 m tall and 0.3 m deep whose centre stands 3 m above the
road, facing the traffic, with three lamps (red on top, yellow, green). A head shows the state
of the link straight ahead from its lanes (the first controlled link where none goes straight).

Signs, from the junction rules and lane speeds: a stop sign (0.75 m octagon, Vienna
Convention B2) at an approach whose links must stop (SUMO link states ``s``, ``w``); a give-way
sign (0.9 m triangle, B1) at an approach all of whose links yield (``m``: the minor road of a
priority junction, a roundabout entry); a speed-limit sign (0.6 m disc, C14) where a road's
speed differs from that of every road leading into it, with the new limit rounded to 10 km/h.
Plates stand 2.2 m high (centre), 5 m into the road for speed limits, by the stop line
otherwise.

Poles are part of the static world (class POLE); heads and plates are labelled objects
(TRAFFIC_LIGHT, TRAFFIC_SIGN) with ids of their own from :data:`STREET_ID_BASE` on, stable for
the network.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from xml.etree import ElementTree

import numpy as np
import sumolib
from shapely.geometry import Point

from networks.classes import SemanticClass
from networks.geometry import arc_lengths, point_and_heading
from networks.markings import section_start
from networks.mesh import ClassedMesh, merge, prism
from networks.opendrive import opendrive_root
from networks.vocabulary import SIGNAL_HEAD, Lamp, SignalState, SignKind, sign_kind, speed_limit_subtype

STREET_VERSION = "4"  # part of the world cache key: change it when poles move
STREET_ID_BASE = 61440  # 0xF000: ids fit the 16-bit instance ids of PNG masks and SemanticKITTI labels
HEAD_LWH_M = (0.3, 0.35, 1.0)  # depth, width, height of a signal head's housing
HEAD_CENTRE_HEIGHT_M = 3.0  # above the road at the stop line
SIGN_LWH_M = {
    SignKind.STOP: (0.05, 0.75, 0.75),
    SignKind.YIELD: (0.05, 0.9, 0.8),
    SignKind.SPEED_LIMIT: (0.05, 0.6, 0.6),
}
SIGN_CENTRE_HEIGHT_M = 2.2
POLE_RADIUS_M = 0.08
POLE_BEHIND_SIDEWALK_M = 0.3  # beyond the sidewalk's outer edge: pedestrians walk the whole sidewalk
POLE_OFF_ROAD_M = 0.8  # beyond the road's edge where there is no sidewalk
BACK_FROM_LANE_END_M = 1.0
SPEED_SIGN_INTO_ROAD_M = 5.0


_STOP_STATES = frozenset("sw")


@dataclass(frozen=True, slots=True)
class StreetObject:
    """A signal head or a sign plate: ``subtype`` is ``signal_head``, ``stop``, ``yield`` or
    ``speed_limit_<km/h>``; ``tls_id`` and ``shown_link`` (the index into the traffic light's
    state string) only for heads; ``lanes``: the vehicle lanes it governs."""

    object_id: int
    semantic_class: SemanticClass
    subtype: str
    edge_id: str
    lanes: tuple[str, ...]
    centre_map_m: tuple[float, float, float]
    yaw_map_rad: float  # the front (+x) faces the approaching traffic
    lwh_m: tuple[float, float, float]
    pole_xyz_m: tuple[float, float, float]  # the pole's foot
    pole_height_m: float
    tls_id: str = ""
    shown_link: int = -1

    @property
    def is_light(self) -> bool:
        return self.semantic_class == SemanticClass.TRAFFIC_LIGHT

    def state(self, signal_states: Mapping[str, Sequence[SignalState]]) -> str:
        """The lamp a head shows, from its traffic light's states (off if unknown; '' for a
        sign)."""
        if not self.is_light:
            return ""
        states = signal_states.get(self.tls_id, ())
        return states[self.shown_link].lamp if 0 <= self.shown_link < len(states) else Lamp.OFF


def street_objects(
    net: sumolib.net.Net, left_hand: bool, lights: bool = True, signs: bool = True, xodr_path: Path | None = None
) -> tuple[StreetObject, ...]:
    """The network's signal heads (with ``lights``) and signs (with ``signs``: the static
    stop, give-way and speed-limit ``signal`` records of ``xodr_path``, the OpenDRIVE file the
    network was converted from, where it has any; else from the rules), ids in a stable
    order: heads first."""
    found: list[tuple[SemanticClass, str, str, tuple[str, ...], float, str, int]] = []
    approaches = _approaches(net)
    from_file = read_signs(xodr_path).signs if signs and xodr_path is not None else ()
    placed = [_file_sign(net, sign, left_hand) for sign in from_file]
    if lights:
        for (edge_id, tls), links in sorted(approaches.items()):
            if not tls:
                continue
            straight = [c for c in links if c.getDirection() == "s"] or sorted(links, key=lambda c: c.getTLLinkIndex())
            found.append((SemanticClass.TRAFFIC_LIGHT, SIGNAL_HEAD, edge_id, _lanes(links), -1.0, tls,
                          int(straight[0].getTLLinkIndex())))  # fmt: skip
    if signs and not from_file:
        for (edge_id, tls), links in sorted(approaches.items()):
            states = {c.getState() for c in links}
            if tls:
                continue
            if states & _STOP_STATES:
                found.append((SemanticClass.TRAFFIC_SIGN, SignKind.STOP.value, edge_id, _lanes(links), -1.0, "", -1))
            elif states == {"m"}:
                found.append((SemanticClass.TRAFFIC_SIGN, SignKind.YIELD.value, edge_id, _lanes(links), -1.0, "", -1))
        for edge_id, kmh in _speed_changes(net):
            lanes = tuple(sorted(lane.getID() for lane in net.getEdge(edge_id).getLanes() if _drives(lane)))
            found.append(
                (SemanticClass.TRAFFIC_SIGN, speed_limit_subtype(kmh), edge_id, lanes, SPEED_SIGN_INTO_ROAD_M, "", -1)
            )
    out = []
    for k, (cls, subtype, edge_id, lanes, from_start, tls, link) in enumerate(found):
        light = cls == SemanticClass.TRAFFIC_LIGHT
        lwh = HEAD_LWH_M if light else SIGN_LWH_M[sign_kind(subtype)]
        height = HEAD_CENTRE_HEIGHT_M if light else SIGN_CENTRE_HEIGHT_M
        centre, yaw, foot = _placement(net.getEdge(edge_id), left_hand, from_start, height, lwh[0])
        out.append(StreetObject(STREET_ID_BASE + k, cls, subtype, edge_id, lanes, centre, yaw, lwh, foot,
                                height + lwh[2] / 2.0 + 0.1, tls, link))  # fmt: skip
    for obj in placed:
        if obj is not None:
            out.append(replace(obj, object_id=STREET_ID_BASE + len(out)))
    return tuple(out)


def _drives(lane: sumolib.net.lane.Lane) -> bool:
    return bool(lane.getPermissions() - {"pedestrian"})


def _lanes(links: list[sumolib.net.connection.Connection]) -> tuple[str, ...]:
    return tuple(sorted({c.getFromLane().getID() for c in links}))


def _approaches(net: sumolib.net.Net) -> dict[tuple[str, str], list[sumolib.net.connection.Connection]]:
    """The vehicle links into each junction, by (incoming edge, traffic light id or '')."""
    out: dict[tuple[str, str], list[sumolib.net.connection.Connection]] = {}
    for edge in net.getEdges(withInternal=False):
        if edge.getFunction():
            continue
        for lane in edge.getLanes():
            if not _drives(lane):
                continue
            for link in lane.getOutgoing():
                if link.getToLane() is None or link.getToLane().getEdge().getFunction():
                    continue
                tls = link.getTLSID() if link.getTLLinkIndex() >= 0 else ""
                out.setdefault((edge.getID(), tls), []).append(link)
    return out


def _speed_changes(net: sumolib.net.Net) -> list[tuple[str, int]]:
    """Roads whose speed limit (rounded to 10 km/h) differs from that of every road leading
    into them, with the new limit."""

    def limit(edge: sumolib.net.edge.Edge) -> int:
        speeds = [lane.getSpeed() for lane in edge.getLanes() if _drives(lane)]
        return int(round(max(speeds) * 3.6 / 10.0) * 10) if speeds else 0

    out = []
    for edge in sorted(net.getEdges(withInternal=False), key=lambda e: e.getID()):
        if edge.getFunction() or not limit(edge) or edge.getLength() < 2 * SPEED_SIGN_INTO_ROAD_M:
            continue
        before = {limit(e) for e in edge.getIncoming() if not e.getFunction()}
        if before and limit(edge) not in before:
            out.append((edge.getID(), limit(edge)))
    return out


def _placement(
    edge: sumolib.net.edge.Edge, left_hand: bool, from_start_m: float, height_m: float, depth_m: float
) -> tuple[tuple[float, float, float], float, tuple[float, float, float]]:
    """The object's centre and yaw and its pole's foot, beside the edge's outermost lane:
    ``from_start_m`` into the edge, or (negative) by its end. The object is centred on its
    pole, on the side the traffic comes from."""
    outer_lane = min(edge.getLanes(), key=lambda lane: lane.getIndex())
    shape = np.asarray(outer_lane.getShape3D(), np.float64)
    end = float(arc_lengths(shape)[-1])
    (x, y, z), heading = point_and_heading(
        shape, from_start_m if from_start_m >= 0 else max(end - BACK_FROM_LANE_END_M, 0.0)
    )
    outward = np.array([-heading[1], heading[0]]) if left_hand else np.array([heading[1], -heading[0]])
    half = outer_lane.getWidth() / 2.0
    on_sidewalk = outer_lane.getPermissions() == {"pedestrian"}
    offset = half + (POLE_BEHIND_SIDEWALK_M if on_sidewalk else POLE_OFF_ROAD_M)
    foot = np.array([x, y]) + outward * offset
    hung = foot - heading * (POLE_RADIUS_M + depth_m / 2.0 + 0.01)
    yaw = float(np.arctan2(-heading[1], -heading[0]))
    return (float(hung[0]), float(hung[1]), z + height_m), yaw, (float(foot[0]), float(foot[1]), z)


def pole_mesh(objects: tuple[StreetObject, ...]) -> ClassedMesh:
    """The objects' poles (class POLE), from a little below the road to above the head or plate."""
    return merge([
        prism(Point(o.pole_xyz_m[0], o.pole_xyz_m[1]).buffer(POLE_RADIUS_M, quad_segs=2), o.pole_xyz_m[2] - 0.2,
              o.pole_height_m + 0.2, SemanticClass.POLE)
        for o in objects
    ])  # fmt: skip


# OpenDRIVE static signal types (German StVO catalogue numbers, US MUTCD codes) -> our subtypes.
_FILE_SIGN_TYPES = {"206": SignKind.STOP, "R1-1": SignKind.STOP, "205": SignKind.YIELD, "R1-2": SignKind.YIELD,
                    "274": SignKind.SPEED_LIMIT, "R2-1": SignKind.SPEED_LIMIT}  # fmt: skip
MPH_TO_KMH = 1.609344


@dataclass(frozen=True, slots=True)
class FileSign:
    """A static ``signal`` record of a known kind: its road, ``s`` and ``t`` on the road's
    reference line, the height of its bottom above the road, whether it faces traffic driving
    along ``s`` (orientation ``+``), its subtype, and the lane section holding it."""

    road_id: str
    s_m: float
    t_m: float
    z_offset_m: float
    along_s: bool
    subtype: str
    section_s_m: float
    section_length_m: float


@dataclass(frozen=True, slots=True)
class FileSigns:
    signs: tuple[FileSign, ...]
    problem: str = ""  # the records left out as unreadable, and the first of them ('' if none)


def read_signs(xodr_path: Path | None) -> FileSigns:
    """The static stop, give-way and speed-limit ``signal`` records of an OpenDRIVE file
    (dynamic signals are traffic lights, taken from SUMO; other types are left out)."""
    if xodr_path is None:
        return FileSigns(())
    try:
        root = opendrive_root(xodr_path)
    except (ElementTree.ParseError, OSError):
        return FileSigns(())  # the markings' notice names an unreadable file
    signs, bad = [], []
    for road in root.iter("road"):
        starts = sorted(_float(sec.get("s"), 0.0) for sec in road.findall("lanes/laneSection")) or [0.0]
        length = _float(road.get("length"), 0.0)
        for record in road.findall("signals/signal"):
            kind = _FILE_SIGN_TYPES.get((record.get("type") or "").strip())
            if kind is None or (record.get("dynamic") or "no").lower() == "yes":
                continue
            s, t = _float(record.get("s"), math.nan), _float(record.get("t"), math.nan)
            if not (math.isfinite(s) and math.isfinite(t)):
                bad.append(f"road {road.get('id')}: signal {record.get('id')!r} has no readable s and t")
                continue
            subtype = kind.value
            if kind is SignKind.SPEED_LIMIT:
                value = _float(record.get("value"), math.nan)
                if not math.isfinite(value) or value <= 0:
                    value = _float(record.get("subtype"), math.nan)  # some files keep the limit there
                if not math.isfinite(value) or value <= 0:
                    bad.append(f"road {road.get('id')}: speed-limit signal {record.get('id')!r} has no value")
                    continue
                kmh = value * MPH_TO_KMH if (record.get("unit") or "").lower() == "mph" else value
                subtype = speed_limit_subtype(round(kmh))
            start = max([v for v in starts if v <= s + 1e-6] or [0.0])
            end = min([v for v in starts if v > start + 1e-6] or [length])
            signs.append(FileSign(road.get("id", ""), s, t, _float(record.get("zOffset"), 0.0),
                                  (record.get("orientation") or "+").strip() != "-", subtype, start,
                                  max(end - start, 1e-6)))  # fmt: skip
    problem = f"{xodr_path}: {len(bad)} signal record(s) left out (first: {bad[0]})" if bad else ""
    return FileSigns(tuple(signs), problem)


def _float(text: str | None, default: float) -> float:
    if text is None or not text.strip():
        return default
    try:
        return float(text)
    except ValueError:
        return math.nan


def _file_sign(net: sumolib.net.Net, sign: FileSign, left_hand: bool) -> StreetObject | None:
    """A file's sign placed by the SUMO lanes of its road: the reference line is the inner
    side of the innermost lane of the road's lanes on either side."""
    sides: dict[bool, sumolib.net.edge.Edge] = {}  # True: the lanes that drive along s
    for edge in net.getEdges(withInternal=False):
        road, _, lane_id = (edge.getLanes()[0].getParam("origId", "") or "").rpartition("_")
        if (
            road != sign.road_id
            or edge.getFunction()
            or abs(section_start(edge.getID(), road) - sign.section_s_m) > 0.01
        ):
            continue
        try:
            sides[(int(lane_id) < 0) != left_hand] = edge
        except ValueError:
            continue
    edge = sides.get(sign.along_s) or next(iter(sides.values()), None)
    if edge is None:
        return None
    along = edge is sides.get(True)
    inner = max(edge.getLanes(), key=lambda lane: lane.getIndex())
    shape = np.asarray(inner.getShape3D(), np.float64)
    fraction = min(max((sign.s_m - sign.section_s_m) / sign.section_length_m, 0.0), 1.0)
    (x, y, z), lane_dir = point_and_heading(
        shape, (fraction if along else 1.0 - fraction) * float(arc_lengths(shape)[-1])
    )
    lane_left = np.array([-lane_dir[1], lane_dir[0]])
    reference = np.array([x, y]) + (-lane_left if left_hand else lane_left) * inner.getWidth() / 2.0
    road_dir = lane_dir if along else -lane_dir
    xy = reference + np.array([-road_dir[1], road_dir[0]]) * sign.t_m
    facing = -road_dir if sign.along_s else road_dir  # towards the traffic the sign is for
    lwh = SIGN_LWH_M[sign_kind(sign.subtype)]
    height = sign.z_offset_m + lwh[2] / 2.0 if sign.z_offset_m >= 1.0 else SIGN_CENTRE_HEIGHT_M
    foot = xy - facing * (POLE_RADIUS_M + lwh[0] / 2.0 + 0.01)
    lanes = tuple(sorted(lane.getID() for lane in edge.getLanes() if _drives(lane)))
    return StreetObject(0, SemanticClass.TRAFFIC_SIGN, sign.subtype, edge.getID(), lanes,
                        (float(xy[0]), float(xy[1]), z + height), float(np.arctan2(facing[1], facing[0])), lwh,
                        (float(foot[0]), float(foot[1]), z), height + lwh[2] / 2.0 + 0.1)  # fmt: skip
