"""People along the ego's way: pedestrians on the sidewalks and crossings near its route
(denser near junctions, some in groups, some children, some standing at the kerb before they
cross) and cyclists on its roads, kept around it as it drives.

The scene's other pedestrians walk anywhere in the town (``traffic.pedestrians``); these are
``traffic.street_pedestrians`` and ``traffic.street_cyclists`` more, kept within
``KEEP_M`` of the ego: once a second, those farther away leave the simulation and new ones
enter at a point within ``NEAR_ROUTE_M`` of the ego's route ahead (cyclists on the route
itself where bicycles may ride it, riding along it), at least ``ENTER_MIN_M``
from the ego (out of the rig's clear sight: it comes to them), at most ``ENTER_MAX_M``. When
the ego is picked, and at a scene cut, the missing ones enter at once anywhere within
``ENTER_MAX_M`` (no frame before shows them appear).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from cosim.demand import TypeVariant
from cosim.net_index import NetIndex
from networks.sumo_tools import sumo_home

sumo_home()  # exports SUMO_HOME before libsumo loads
import libsumo  # noqa: E402

WALKER, CYCLIST = "walker", "cyclist"  # id prefixes
SAMPLE_M = 8.0  # points along every sidewalk and road where people may enter
NEAR_ROUTE_M = 25.0
ENTER_MIN_M, ENTER_MAX_M, KEEP_M = 90.0, 220.0, 260.0
ROUTE_AHEAD_M = 600.0  # how much of the ego's route people are placed along
JUNCTION_M, JUNCTION_WEIGHT = 20.0, 3.0  # points this close to an edge's end are this much likelier
GROUP_SHARE = 0.25  # of the pedestrians entering: a group of 2 or 3 walking together
CHILD_IN_GROUP, CHILD_ALONE = 0.4, 0.04  # chance that a group's second or third member, or one alone, is a child
WAIT_SHARE = 0.3  # of the pedestrians entering near a junction: they first stand 5-40 s at the kerb
WAIT_S = (5.0, 40.0)
GROUP_SPACING_M = 0.9


@dataclass(frozen=True, slots=True)
class _Points:
    """Points along edges: ``xy (K, 2)``, the edge of each, its position on the edge (m), and
    its weight (higher near the edge's ends)."""

    xy: npt.NDArray[np.float64]
    edge: list[str]
    pos_m: npt.NDArray[np.float64]
    weight: npt.NDArray[np.float64]


def _points(index: NetIndex, edges: list[str]) -> _Points:
    xy, names, pos, weight = [], [], [], []
    for edge in edges:
        shape = index.edge_shape_xy[edge]
        seg = np.linalg.norm(np.diff(shape, axis=0), axis=1)
        along = np.concatenate([[0.0], np.cumsum(seg)])
        total = float(along[-1])
        length = index.edge_length_m[edge]
        if total <= 1.0 or length <= 2.0:
            continue
        s = np.arange(SAMPLE_M / 2, total, SAMPLE_M)
        xy.append(np.stack([np.interp(s, along, shape[:, 0]), np.interp(s, along, shape[:, 1])], axis=1))
        names += [edge] * len(s)
        p = np.clip(s / total * length, 0.5, length - 0.5)
        pos.append(p)
        weight.append(np.where(np.minimum(p, length - p) <= JUNCTION_M, JUNCTION_WEIGHT, 1.0))
    if not names:
        return _Points(np.zeros((0, 2)), [], np.zeros(0), np.zeros(0))
    return _Points(np.concatenate(xy), names, np.concatenate(pos), np.concatenate(weight))


class StreetPeople:
    """Keeps ``pedestrians`` walkers and ``cyclists`` cyclists around the ego (see the module)."""

    def __init__(
        self,
        index: NetIndex,
        rng: np.random.Generator,
        pedestrians: int,
        cyclists: int,
        adults: list[TypeVariant],
        children: list[TypeVariant],
        bicycles: list[TypeVariant],
    ) -> None:
        self._index, self._rng = index, rng
        self._pedestrians = pedestrians if index.walk_edges else 0
        self._cyclists = cyclists if index.edges_by_vclass.get("bicycle") else 0
        self._adults, self._children, self._bicycles = adults, children, bicycles
        self._walk = _points(index, index.walk_edges) if self._pedestrians else _points(index, [])
        self._roads = _points(index, index.edges_by_vclass.get("bicycle", [])) if self._cyclists else _points(index, [])
        self._serial = 0
        self._settling = 0  # calls left in which cyclists may still enter near the ego

    def top_up(self, ego_xy: tuple[float, float], route_ahead: list[str], at_once: bool) -> None:
        """Remove the people left far behind and bring each count back (``at_once``: all the
        missing ones, anywhere within reach; else up to 5 a call, out of the ego's sight)."""
        if not (self._pedestrians or self._cyclists):
            return
        ego = np.asarray(ego_xy, np.float64)
        walkers = [p for p in libsumo.person.getIDList() if p.startswith(WALKER)]
        walkers = self._keep_near(walkers, libsumo.person, ego)
        cyclists = [v for v in libsumo.vehicle.getIDList() if v.startswith(CYCLIST)]
        cyclists = self._keep_near(cyclists, libsumo.vehicle, ego)
        self._settling = 5 if at_once else max(self._settling - 1, 0)
        for v in libsumo.simulation.getPendingVehicles():  # found no gap in the traffic: enter elsewhere
            if v.startswith(CYCLIST):
                libsumo.vehicle.remove(v)
        route_xy = self._route_points(route_ahead, ego)
        budget = 10_000 if at_once else 5
        lo = 0.0 if at_once else ENTER_MIN_M
        missing = min(self._pedestrians - len(walkers), budget)
        if missing > 0:
            self._add_walkers(missing, self._candidates(self._walk, route_xy, ego, lo))
        missing = min(self._cyclists - len(cyclists), budget)
        if missing > 0:
            # cyclists that found no gap when all entered at once try again near the ego for 5 s
            candidates = self._candidates(self._roads, route_xy, ego, 0.0 if self._settling else lo)
            on_route = set(route_ahead)
            ahead = np.asarray([k for k in candidates if self._roads.edge[k] in on_route], np.intp)
            self._add_cyclists(missing, ahead if len(ahead) else candidates, route_ahead)

    @staticmethod
    def _keep_near(ids: list[str], domain: object, ego: npt.NDArray[np.float64]) -> list[str]:
        kept = []
        for i in ids:
            x, y = domain.getPosition(i)  # type: ignore[attr-defined]
            if np.hypot(x - ego[0], y - ego[1]) > KEEP_M:
                domain.remove(i)  # type: ignore[attr-defined]
            else:
                kept.append(i)
        return kept

    def _route_points(self, route_ahead: list[str], ego: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
        """Points along the ego's route ahead (up to ``ROUTE_AHEAD_M``), the ego's own first."""
        out = [ego[None, :]]
        total = 0.0
        for edge in route_ahead:
            shape = self._index.edge_shape_xy.get(edge)
            if shape is None:
                continue
            seg = np.linalg.norm(np.diff(shape, axis=0), axis=1)
            along = np.concatenate([[0.0], np.cumsum(seg)])
            s = np.arange(0.0, along[-1] + 1e-9, SAMPLE_M)
            out.append(np.stack([np.interp(s, along, shape[:, 0]), np.interp(s, along, shape[:, 1])], axis=1))
            total += float(along[-1])
            if total >= ROUTE_AHEAD_M:
                break
        return np.concatenate(out)

    def _candidates(
        self, points: _Points, route_xy: npt.NDArray[np.float64], ego: npt.NDArray[np.float64], lo: float
    ) -> npt.NDArray[np.intp]:
        """Indices of the points near the route, ``lo`` to ``ENTER_MAX_M`` from the ego."""
        if not len(points.edge):
            return np.zeros(0, np.intp)
        from_ego = np.linalg.norm(points.xy - ego, axis=1)
        reach = np.flatnonzero((from_ego >= lo) & (from_ego <= ENTER_MAX_M))
        if not len(reach):
            return reach
        near = np.zeros(len(reach), bool)
        for chunk in range(0, len(route_xy), 256):
            d = np.linalg.norm(points.xy[reach, None, :] - route_xy[None, chunk : chunk + 256, :], axis=2)
            near |= d.min(axis=1) <= NEAR_ROUTE_M
        return reach[near]

    def _draw(self, points: _Points, candidates: npt.NDArray[np.intp]) -> int:
        w = points.weight[candidates]
        return int(candidates[int(self._rng.choice(len(candidates), p=w / w.sum()))])

    def _add_walkers(self, count: int, candidates: npt.NDArray[np.intp]) -> None:
        if not len(candidates):
            return
        added = 0
        while added < count:
            k = self._draw(self._walk, candidates)
            edge, pos = self._walk.edge[k], float(self._walk.pos_m[k])
            size = int(self._rng.integers(2, 4)) if self._rng.random() < GROUP_SHARE else 1
            size = min(size, count - added) or 1
            goal = self._walk.edge[self._draw(self._walk, candidates)]
            edges = [edge]
            if goal != edge:
                stages = libsumo.simulation.findIntermodalRoute(edge, goal, modes="")
                edges = [e for s in stages for e in s.edges] or [edge]
            length = self._index.edge_length_m.get(edge, pos + 1.0)
            near_junction = min(pos, length - pos) <= JUNCTION_M
            wait_s = float(self._rng.uniform(*WAIT_S)) if near_junction and self._rng.random() < WAIT_SHARE else 0.0
            arrival = float(self._rng.uniform(0.0, self._index.edge_length_m.get(edges[-1], 0.0)))
            for member in range(size):
                child = self._rng.random() < (CHILD_IN_GROUP if member else CHILD_ALONE)
                types = self._children if child and self._children else self._adults
                variant = types[int(self._rng.integers(0, len(types)))]
                self._serial += 1
                pid = f"{WALKER}_{self._serial}"
                at = float(np.clip(pos + member * GROUP_SPACING_M, 0.1, max(length - 0.1, 0.1)))
                libsumo.person.add(pid, edge, at, depart=-3, typeID=variant.type_id)  # -3: depart now
                if wait_s > 0:
                    libsumo.person.appendWaitingStage(pid, wait_s, "waiting to cross")
                libsumo.person.appendWalkingStage(pid, edges, arrivalPos=arrival)
            added += size

    def _add_cyclists(self, count: int, candidates: npt.NDArray[np.intp], route_ahead: list[str]) -> None:
        """Cyclists entering on the ego's route ahead where they can ride it (else near it), riding
        along it to its end: the ego comes up behind them or meets them."""
        if not len(candidates) or not self._bicycles:
            return
        for _ in range(count):
            k = self._draw(self._roads, candidates)
            edge, pos = self._roads.edge[k], float(self._roads.pos_m[k])
            goal = route_ahead[-1] if edge in route_ahead else self._roads.edge[self._draw(self._roads, candidates)]
            variant = self._bicycles[int(self._rng.integers(0, len(self._bicycles)))]
            route = libsumo.simulation.findRoute(edge, goal, vType=variant.type_id) if goal != edge else None
            edges = list(route.edges) if route is not None and route.edges else [edge]
            self._serial += 1
            vid = f"{CYCLIST}_{self._serial}"
            libsumo.route.add(f"{vid}_route", edges)
            libsumo.vehicle.add(vid, f"{vid}_route", typeID=variant.type_id, depart="now", departLane="best",
                                departPos=f"{pos:.2f}", departSpeed="max")  # fmt: skip
