"""People along the ego's way: pedestrians on the sidewalks and crossings near its route
(denser near junctions, some in groups, some children, some standing at the kerb before they
cross) and cyclists on its roads, kept around it as it drives.

The scene's other pedestrians walk anywhere in the town (``traffic.pedestrians``); these are
``traffic.street_pedestrians`` and ``traffic.street_cyclists`` more, kept within
``KEEP_M`` of the ego: once a second, those farther away leave the simulation and new ones
enter at a point within ``NEAR_ROUTE_M`` of the ego's route ahead (cyclists on the route
itself where bicycles may ride it: half riding along it, half on the road's other side riding
towards the ego, so that an ego standing in a queue still meets some), at least ``ENTER_MIN_M``
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
from networks.geometry import arc_lengths
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
ROAD_CLEAR_END_M = 15.0  # cyclists enter no nearer the end of a road than this
RETRY_BAND_M = 15.0  # a cyclist that found no gap enters again this near its first distance from the ego
ONCOMING_SHARE = 0.5  # of the cyclists entering: on the route's other side, riding towards the ego


@dataclass(frozen=True, slots=True)
class _Points:
    """Points along edges: ``xy (K, 2)``, the edge of each, its position on the edge (m), and
    its weight (higher near the edge's ends)."""

    xy: npt.NDArray[np.float64]
    edge: list[str]
    pos_m: npt.NDArray[np.float64]
    weight: npt.NDArray[np.float64]


def _points(index: NetIndex, edges: list[str], clear_end_m: float = 0.0) -> _Points:
    """``clear_end_m``: leave out the points this close to an edge's end (a vehicle entering
    there could not stop for the junction: SUMO holds it back)."""
    xy, names, pos, weight = [], [], [], []
    for edge in edges:
        shape = index.edge_shape_xy[edge]
        along = arc_lengths(shape)
        total = float(along[-1])
        length = index.edge_length_m[edge]
        if total <= 1.0 or length <= 2.0:
            continue
        s = np.arange(SAMPLE_M / 2, total - clear_end_m * total / length, SAMPLE_M)
        if not len(s):
            continue
        xy.append(np.stack([np.interp(s, along, shape[:, 0]), np.interp(s, along, shape[:, 1])], axis=1))
        names += [edge] * len(s)
        p = np.clip(s / total * length, 0.5, length - 0.5)
        pos.append(p)
        weight.append(np.where(np.minimum(p, length - p) <= JUNCTION_M, JUNCTION_WEIGHT, 1.0))
    if not names:
        return _Points(np.zeros((0, 2)), [], np.zeros(0), np.zeros(0))
    return _Points(np.concatenate(xy), names, np.concatenate(pos), np.concatenate(weight))


def _opposite_edges(edges: list[str]) -> dict[str, str]:
    """Each edge's other side: the edge between the same two junctions the other way."""
    by_ends = {(libsumo.edge.getFromJunction(e), libsumo.edge.getToJunction(e)): e for e in edges}
    return {e: by_ends[(b, a)] for (a, b), e in by_ends.items() if (b, a) in by_ends}


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
        roads = index.edges_by_vclass.get("bicycle", []) if self._cyclists else []
        self._roads = _points(index, roads, ROAD_CLEAR_END_M)
        self._opposite = _opposite_edges(roads)
        self._serial = 0
        self._settling = 0  # calls left in which cyclists may still enter near the ego
        self._entries: dict[str, tuple[float, bool]] = {}  # cyclists entering at once: distance from the ego, oncoming

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
        retry = []  # cyclists that entered at once and found no gap: again as far from the ego, elsewhere
        for v in libsumo.simulation.getPendingVehicles():  # found no gap in the traffic: enter elsewhere
            if v.startswith(CYCLIST):
                libsumo.vehicle.remove(v)
                if self._settling and v in self._entries:
                    retry.append(self._entries[v])
        if not self._settling:
            self._entries.clear()
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
            back = route_ahead and self._opposite.get(route_ahead[0])
            across = {self._opposite[e] for e in route_ahead if e in self._opposite} if back else set()
            ahead = np.asarray([k for k in candidates if self._roads.edge[k] in on_route], np.intp)
            towards = np.asarray([k for k in candidates if self._roads.edge[k] in across], np.intp)
            along = ahead if len(ahead) else candidates
            retry = retry[:missing] if not at_once else []
            picks = self._pick_cyclists(missing - len(retry), along, towards, ego, spread=at_once)
            picks += [self._pick_near(along, towards, ego, *entry) for entry in retry]
            self._add_cyclists(picks, candidates, route_ahead, ego, record=bool(self._settling))

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

    def _pick_cyclists(
        self,
        count: int,
        along: npt.NDArray[np.intp],
        towards: npt.NDArray[np.intp],
        ego: npt.NDArray[np.float64],
        spread: bool,
    ) -> list[tuple[int, bool]]:
        """Entry points (and whether the cyclist rides towards the ego): ``ONCOMING_SHARE`` of
        the weight on ``towards``, the rest on ``along``. ``spread``: one draw stratified over
        the points ordered by distance from the ego (the k-th of n from the k-th n-th of the
        weight), so that a few cyclists entering at once lie near and far as they would over
        many draws, not all far by chance; else each drawn on its own."""
        parts = [(along, 1.0 - ONCOMING_SHARE, False), (towards, ONCOMING_SHARE, True)]
        parts = [p for p in parts if len(p[0])]
        if not parts or count <= 0:
            return []
        index = np.concatenate([p[0] for p in parts])
        weight = np.concatenate([self._roads.weight[p[0]] / self._roads.weight[p[0]].sum() * p[1] for p in parts])
        weight /= weight.sum()
        oncoming = np.concatenate([np.full(len(p[0]), p[2]) for p in parts])
        if spread:
            order = np.argsort(np.linalg.norm(self._roads.xy[index] - ego, axis=1), kind="stable")
            cumulative = np.cumsum(weight[order])
            u = (np.arange(count) + self._rng.random()) / count * cumulative[-1]
            picks = order[np.minimum(np.searchsorted(cumulative, u), len(order) - 1)]
        else:
            picks = self._rng.choice(len(index), size=count, p=weight)
        return [(int(index[j]), bool(oncoming[j])) for j in picks]

    def _pick_near(
        self, along: npt.NDArray[np.intp], towards: npt.NDArray[np.intp], ego: npt.NDArray[np.float64],
        distance_m: float, oncoming: bool,
    ) -> tuple[int, bool]:  # fmt: skip
        """An entry point about ``distance_m`` from the ego (within ``RETRY_BAND_M``, else the
        nearest to it) on the same side as before."""
        pool = towards if oncoming and len(towards) else along
        if not len(pool):
            pool, oncoming = (towards, True) if len(towards) else (along, False)
        gap = np.abs(np.linalg.norm(self._roads.xy[pool] - ego, axis=1) - distance_m)
        band = pool[gap <= RETRY_BAND_M]
        k = self._draw(self._roads, band) if len(band) else int(pool[int(np.argmin(gap))])
        return k, oncoming and pool is towards

    def _add_cyclists(
        self,
        picks: list[tuple[int, bool]],
        candidates: npt.NDArray[np.intp],
        route_ahead: list[str],
        ego: npt.NDArray[np.float64],
        record: bool,
    ) -> None:
        """Cyclists entering at ``picks``: on the ego's route ahead where they can ride it (else
        near it), riding along it to its end (the ego comes up behind them); or on the other
        side of its road, riding back along the route past the ego (they meet it even while it
        stands)."""
        if not self._bicycles:
            return
        back = self._opposite.get(route_ahead[0], "") if route_ahead else ""
        for k, oncoming in picks:
            edge, pos = self._roads.edge[k], float(self._roads.pos_m[k])
            if oncoming:
                goal = back
            elif edge in route_ahead:
                goal = route_ahead[-1]
            else:
                goal = self._roads.edge[self._draw(self._roads, candidates)]
            variant = self._bicycles[int(self._rng.integers(0, len(self._bicycles)))]
            route = libsumo.simulation.findRoute(edge, goal, vType=variant.type_id) if goal != edge else None
            edges = list(route.edges) if route is not None and route.edges else [edge]
            self._serial += 1
            vid = f"{CYCLIST}_{self._serial}"
            libsumo.route.add(f"{vid}_route", edges)
            libsumo.vehicle.add(vid, f"{vid}_route", typeID=variant.type_id, depart="now", departLane="best",
                                departPos=f"{pos:.2f}", departSpeed="max")  # fmt: skip
            if record:
                self._entries[vid] = (float(np.linalg.norm(self._roads.xy[k] - ego)), oncoming)
