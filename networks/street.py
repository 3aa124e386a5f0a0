"""Traffic lights along the streets: one signal head per signalised approach, on a pole by the
stop line, on the right of the road (the left in left-hand traffic).

Every SUMO traffic light (``tlLogic``) controls links from incoming lanes; the lanes of one
incoming edge that it controls form an approach and get one head: a housing 0.35 m wide, 1 m
tall and 0.3 m deep whose centre stands 3 m above the road, facing the traffic, with three
lamps (red on top, yellow, green). A head shows the state of the link straight ahead from its
lanes (the first controlled link where none goes straight). The pole is part of the static
world (class POLE); the head is a labelled object (class TRAFFIC_LIGHT) with an id of its own
from :data:`HEAD_ID_BASE` on, stable for the network.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import sumolib
from shapely.geometry import Point

from networks.classes import SemanticClass
from networks.mesh import ClassedMesh, merge, prism

STREET_VERSION = "1"  # part of the world cache key: change it when poles move
HEAD_ID_BASE = 61440  # 0xF000: head ids fit the 16-bit instance ids of PNG masks and SemanticKITTI labels
HEAD_LWH_M = (0.3, 0.35, 1.0)  # depth, width, height of the housing
HEAD_CENTRE_HEIGHT_M = 3.0  # above the road at the stop line
POLE_RADIUS_M = 0.08
POLE_HEIGHT_M = 3.6
POLE_FROM_KERB_M = 0.6  # on the sidewalk, this far from the kerb
POLE_OFF_ROAD_M = 0.8  # beyond the road's edge where the approach has no sidewalk
HEAD_TOWARDS_ROAD_M = 0.25  # the head hangs on the pole's road side
BACK_FROM_LANE_END_M = 1.0

# SUMO signal state letters (libsumo.trafficlight.getRedYellowGreenState) -> the lamp shown.
STATE_NAMES = {"r": "red", "y": "yellow", "G": "green", "g": "green", "s": "green", "u": "red_yellow",
               "o": "off", "O": "off"}  # fmt: skip
STATES = ("red", "yellow", "green", "red_yellow", "off")


@dataclass(frozen=True, slots=True)
class SignalHead:
    head_id: int
    tls_id: str
    edge_id: str
    lanes: tuple[str, ...]  # the vehicle lanes of the approach it governs
    shown_link: int  # index into the traffic light's state string
    centre_map_m: tuple[float, float, float]
    yaw_map_rad: float  # the housing's front (+x) faces the approaching traffic
    pole_xyz_m: tuple[float, float, float]  # the pole's foot

    def state(self, signal_states: dict[str, str]) -> str:
        """The lamp this head shows, from its traffic light's state string ('off' if unknown)."""
        text = signal_states.get(self.tls_id, "")
        return STATE_NAMES.get(text[self.shown_link], "off") if self.shown_link < len(text) else "off"


def signal_heads(net: sumolib.net.Net, left_hand: bool) -> tuple[SignalHead, ...]:
    """One head per signalised approach of the network, in a stable order."""
    approaches: dict[tuple[str, str], list[sumolib.net.connection.Connection]] = {}
    for edge in net.getEdges(withInternal=False):
        if edge.getFunction():
            continue
        for lane in edge.getLanes():
            if not lane.getPermissions() - {"pedestrian"}:
                continue
            for link in lane.getOutgoing():
                if link.getTLSID() and link.getTLLinkIndex() >= 0:
                    approaches.setdefault((link.getTLSID(), edge.getID()), []).append(link)
    heads = []
    for k, ((tls, edge_id), links) in enumerate(sorted(approaches.items())):
        edge = net.getEdge(edge_id)
        straight = [c for c in links if c.getDirection() == "s"] or sorted(links, key=lambda c: c.getTLLinkIndex())
        lanes = tuple(sorted({c.getFromLane().getID() for c in links}))
        centre, yaw, foot = _placement(edge, left_hand)
        heads.append(SignalHead(HEAD_ID_BASE + k, tls, edge_id, lanes, int(straight[0].getTLLinkIndex()),
                                centre, yaw, foot))  # fmt: skip
    return tuple(heads)


def _placement(
    edge: sumolib.net.edge.Edge, left_hand: bool
) -> tuple[tuple[float, float, float], float, tuple[float, float, float]]:
    """The head's centre and yaw and the pole's foot, by the end of the edge's outermost lane."""
    outer_lane = min(edge.getLanes(), key=lambda lane: lane.getIndex())
    shape = np.asarray(outer_lane.getShape3D(), np.float64)
    along = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(shape[:, :2], axis=0), axis=1))]
    s = max(float(along[-1]) - BACK_FROM_LANE_END_M, 0.0)
    x, y, z = (float(np.interp(s, along, shape[:, k])) for k in range(3))
    i = int(np.clip(np.searchsorted(along, s) - 1, 0, len(shape) - 2))
    heading = shape[i + 1, :2] - shape[i, :2]
    heading /= max(float(np.linalg.norm(heading)), 1e-9)
    outward = np.array([-heading[1], heading[0]]) if left_hand else np.array([heading[1], -heading[0]])
    half = outer_lane.getWidth() / 2.0
    on_sidewalk = outer_lane.getPermissions() == {"pedestrian"}  # then near the kerb, its inner side
    offset = -half + POLE_FROM_KERB_M if on_sidewalk else half + POLE_OFF_ROAD_M
    foot = np.array([x, y]) + outward * offset
    head_xy = foot - outward * HEAD_TOWARDS_ROAD_M
    yaw = float(np.arctan2(-heading[1], -heading[0]))
    return (float(head_xy[0]), float(head_xy[1]), z + HEAD_CENTRE_HEIGHT_M), yaw, (float(foot[0]), float(foot[1]), z)


def pole_mesh(heads: tuple[SignalHead, ...]) -> ClassedMesh:
    """The heads' poles (class POLE), from a little below the road to above the housing."""
    return merge([
        prism(Point(h.pole_xyz_m[0], h.pole_xyz_m[1]).buffer(POLE_RADIUS_M, quad_segs=2), h.pole_xyz_m[2] - 0.2,
              POLE_HEIGHT_M + 0.2, SemanticClass.POLE)
        for h in heads
    ])  # fmt: skip


@dataclass(frozen=True, slots=True)
class SignalTable:
    """The heads as arrays (row k = head ``HEAD_ID_BASE + k``), for placing them every frame."""

    heads: tuple[SignalHead, ...]

    @property
    def centres_m(self) -> np.ndarray:
        return np.array([h.centre_map_m for h in self.heads], np.float64).reshape(-1, 3)

    @property
    def yaws_rad(self) -> np.ndarray:
        return np.array([h.yaw_map_rad for h in self.heads], np.float64)

    def head(self, head_id: int) -> SignalHead:
        return self.heads[head_id - HEAD_ID_BASE]
