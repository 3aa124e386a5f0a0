"""The network as the traffic demand sees it: usable edges per vehicle class, their lengths
and weights, footpaths, entrance ramps, and where traffic enters and leaves the network."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
import sumolib

from cosim.demand import KINDS
from cosim.errors import CosimError
from cosim.scenario import HazardConfig
from networks.vocabulary import HazardKind


@dataclass(frozen=True, slots=True)
class NetIndex:
    """Edges usable for routes, per SUMO vehicle class, with their shapes and lengths.

    ``edge_weights`` (per vehicle class, in the order of ``edges_by_vclass``) are each
    edge's share of the lane length open to that class: trips start and end on an edge
    with that probability, so traffic spreads over the town as the density does (a
    motorway is not starved of trips because it has few, long edges).
    """

    edges_by_vclass: dict[str, list[str]]
    edge_weights: dict[str, npt.NDArray[np.float64]]
    walk_edges: list[str]
    walk_weights: npt.NDArray[np.float64]
    edge_shape_xy: dict[str, npt.NDArray[np.float64]]  # (K, 2) map frame
    edge_length_m: dict[str, float]
    vehicle_lane_km: float
    on_ramps: list[str]
    entries_by_vclass: dict[str, list[str]]  # edges nothing drives into: where traffic enters the network
    exits_by_vclass: dict[str, list[str]]  # edges that lead nowhere: where traffic leaves it

    def distance_m(self, edge_id: str, xy: tuple[float, float]) -> float:
        """Distance in the plane from ``xy`` to the edge's centre line."""
        shape = self.edge_shape_xy[edge_id]
        a, b = shape[:-1], shape[1:]
        ab = b - a
        t = np.clip(np.sum((np.asarray(xy) - a) * ab, axis=1) / np.maximum(np.sum(ab * ab, axis=1), 1e-9), 0.0, 1.0)
        return float(np.min(np.linalg.norm(a + ab * t[:, None] - np.asarray(xy), axis=1)))


def _on_ramps(net: sumolib.net.Net) -> list[str]:
    """Edges that merge into a faster road: the node joins two edges into one (>= 80 km/h),
    and this edge is the one with fewer lanes."""
    ramps = []
    for node in net.getNodes():
        incoming = [e for e in node.getIncoming() if not e.getFunction() and e.allows("passenger")]
        outgoing = [e for e in node.getOutgoing() if not e.getFunction() and e.allows("passenger")]
        if len(incoming) != 2 or len(outgoing) != 1 or outgoing[0].getSpeed() < 22.0:
            continue
        a, b = sorted(incoming, key=lambda e: (e.getLaneNumber(), e.getSpeed(), e.getID()))
        if (a.getLaneNumber(), a.getSpeed()) < (b.getLaneNumber(), b.getSpeed()):
            ramps.append(a.getID())
    return sorted(ramps)


def _normalised(weights: list[float]) -> npt.NDArray[np.float64]:
    w = np.asarray(weights, dtype=np.float64)
    return w / w.sum() if w.size and w.sum() > 0 else w


def index_net(net: sumolib.net.Net) -> NetIndex:
    by_class: dict[str, list[str]] = {}
    weights: dict[str, list[float]] = {}
    walk: list[str] = []
    walk_weights: list[float] = []
    shapes: dict[str, npt.NDArray[np.float64]] = {}
    lengths: dict[str, float] = {}
    lane_km = 0.0
    for edge in sorted(net.getEdges(withInternal=False), key=lambda e: e.getID()):
        if edge.getFunction():
            continue
        shapes[edge.getID()] = np.asarray(edge.getShape(), dtype=np.float64)[:, :2]
        lengths[edge.getID()] = edge.getLength()
        for vclass in sorted({k.sumo_vclass for k in KINDS.values()}):
            if edge.allows(vclass) and edge.getLength() > 5.0:
                by_class.setdefault(vclass, []).append(edge.getID())
                lanes = sum(1 for lane in edge.getLanes() if lane.allows(vclass))
                weights.setdefault(vclass, []).append(lanes * edge.getLength())
        if edge.allows("pedestrian"):
            walk.append(edge.getID())
            walk_weights.append(edge.getLength())
        lane_km += sum(lane.getLength() for lane in edge.getLanes() if lane.allows("passenger")) / 1000.0
    entries, exits = _fringe(net, by_class)
    return NetIndex(
        by_class, {k: _normalised(w) for k, w in weights.items()}, walk, _normalised(walk_weights), shapes, lengths,
        lane_km, _on_ramps(net), entries, exits,
    )  # fmt: skip


def _fringe(net: sumolib.net.Net, by_class: dict[str, list[str]]) -> tuple[dict[str, list[str]], dict[str, list[str]]]:
    """Per vehicle class, the usable edges no other edge open to the class leads into
    (entries) and those that lead to no such edge (exits)."""
    entries: dict[str, list[str]] = {}
    exits: dict[str, list[str]] = {}
    for vclass, edge_ids in by_class.items():
        for edge_id in edge_ids:
            edge = net.getEdge(edge_id)
            if not any(e.allows(vclass) for e in edge.getIncoming()):
                entries.setdefault(vclass, []).append(edge_id)
            if not any(e.allows(vclass) for e in edge.getOutgoing()):
                exits.setdefault(vclass, []).append(edge_id)
    return entries, exits


def check_hazards(hazards: tuple[HazardConfig, ...], net: sumolib.net.Net) -> None:
    """Refuse, before frame 0, a hazard kind the network cannot have."""
    kinds = {h.kind for h in hazards}
    if HazardKind.CUT_IN in kinds:
        wide = any(
            sum(1 for lane in edge.getLanes() if lane.allows("passenger")) >= 2
            for edge in net.getEdges()
            if edge.getFunction() != "internal"
        )
        if not wide:
            raise CosimError("hazards: cut_in needs a road with two lanes in one direction; this network has none")
    if HazardKind.RED_LIGHT in kinds and not net.getTrafficLights():
        raise CosimError("hazards: red_light needs signalised junctions; this network has no traffic lights")
    if HazardKind.JAYWALKER in kinds and not any(
        lane.allows("pedestrian") for edge in net.getEdges() for lane in edge.getLanes()
    ):
        raise CosimError("hazards: jaywalker needs a footpath or sidewalk to start from; this network has none")
