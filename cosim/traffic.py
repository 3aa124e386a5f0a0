"""The only module that talks to libsumo: start, demand, the ego, and world states.

libsumo runs one simulation per process; parallel runs use separate processes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from cosim.demand import KINDS, PEDESTRIAN, TypeVariant, sample_variants, split_by_mix, target_vehicle_count
from cosim.errors import TrafficError
from cosim.kinematics import front_bumper_to_center, heading_vectors, sumo_angle_to_yaw
from cosim.parking import ParkingArea, additional_xml, find_parking_areas, lane_types
from cosim.scenario import Scenario
from cosim.state import WorldState
from networks.cache import cache_dir, digest
from networks.sumo_tools import sumo_binary, sumo_home
from sensors.agents import AgentBoxes

sumo_home()  # exports SUMO_HOME before libsumo loads
import libsumo  # noqa: E402
import sumolib  # noqa: E402

EGO_ID = "ego"


@dataclass(frozen=True, slots=True)
class NetIndex:
    """Edges usable for routes, per SUMO vehicle class, with their mid points."""

    edges_by_vclass: dict[str, list[str]]
    walk_edges: list[str]
    edge_mid_xy: dict[str, tuple[float, float]]
    vehicle_lane_km: float
    on_ramps: list[str]


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


def index_net(net: sumolib.net.Net) -> NetIndex:
    by_class: dict[str, list[str]] = {}
    walk: list[str] = []
    mids: dict[str, tuple[float, float]] = {}
    lane_km = 0.0
    for edge in sorted(net.getEdges(withInternal=False), key=lambda e: e.getID()):
        if edge.getFunction():
            continue
        shape = edge.getShape()
        mids[edge.getID()] = shape[len(shape) // 2][:2]
        for vclass in {k.sumo_vclass for k in KINDS.values()}:
            if edge.allows(vclass) and edge.getLength() > 5.0:
                by_class.setdefault(vclass, []).append(edge.getID())
        if edge.allows("pedestrian"):
            walk.append(edge.getID())
        lane_km += sum(lane.getLength() for lane in edge.getLanes() if lane.allows("passenger")) / 1000.0
    return NetIndex(by_class, walk, mids, lane_km, _on_ramps(net))


class Traffic:
    """A running SUMO simulation stepped in lock-step with the frame loop."""

    def __init__(self, net_path: Path, net: sumolib.net.Net, scenario: Scenario) -> None:
        self._scenario = scenario
        self._rng = np.random.default_rng(scenario.seed)
        self._index = index_net(net)
        self._track_ids: dict[str, int] = {}
        self._alive: set[str] = set()
        self._serial = 0
        self._statics: dict[str, tuple[int, float, float, float]] = {}
        self._parking = find_parking_areas(net, lane_types(net_path)) if scenario.traffic.parked > 0 else []
        self._parked: set[str] = set()
        cmd = [
            str(sumo_binary("sumo")), "-n", str(net_path), "--step-length", f"{scenario.step_s}",
            "--seed", str(scenario.seed), "--no-step-log", "true", "--no-warnings", "true",
            "--time-to-teleport", "120", "--collision.action", "warn", "--begin", "0",
        ]  # fmt: skip
        if self._parking:
            cmd += ["--additional-files", str(_write_parking(net_path, self._parking))]
        try:
            libsumo.start(cmd)
        except libsumo.TraCIException as err:
            raise TrafficError(f"{net_path}: SUMO could not load the network: {err}") from err
        self._variants = self._define_types()
        traffic = scenario.traffic
        total = target_vehicle_count(traffic.vehicles_per_lane_km, self._index.vehicle_lane_km, traffic.vehicles)
        self._targets = {
            k: n
            for k, n in split_by_mix(total, traffic.mix).items()
            if KINDS[k].sumo_vclass in self._index.edges_by_vclass
        }
        self._ego_xy: tuple[float, float] | None = None
        self._ego = ""
        self.notices: list[str] = []

    # --- set-up --------------------------------------------------------------------------
    def _define_types(self) -> dict[str, list[TypeVariant]]:
        variants: dict[str, list[TypeVariant]] = {}
        for spec in [*KINDS.values(), PEDESTRIAN]:
            base = "DEFAULT_PEDTYPE" if spec is PEDESTRIAN else "DEFAULT_VEHTYPE"
            variants[spec.kind] = sample_variants(spec, self._rng)
            for v in variants[spec.kind]:
                libsumo.vehicletype.copy(base, v.type_id)
                if spec is not PEDESTRIAN:
                    libsumo.vehicletype.setVehicleClass(v.type_id, spec.sumo_vclass)
                    libsumo.vehicletype.setShapeClass(v.type_id, spec.shape_class)
                    libsumo.vehicletype.setAccel(v.type_id, v.accel_mps2)
                    libsumo.vehicletype.setDecel(v.type_id, spec.decel_mps2)
                libsumo.vehicletype.setLength(v.type_id, v.length_m)
                libsumo.vehicletype.setWidth(v.type_id, v.width_m)
                libsumo.vehicletype.setHeight(v.type_id, v.height_m)
                libsumo.vehicletype.setMaxSpeed(v.type_id, v.max_speed_mps)
        libsumo.vehicletype.copy("car_0", "ego_car")
        return variants

    # --- demand ----------------------------------------------------------------------------
    def _far_from_ego(self, edge_id: str, radius_m: float = 90.0) -> bool:
        if self._ego_xy is None:
            return True
        x, y = self._index.edge_mid_xy[edge_id]
        return math.hypot(x - self._ego_xy[0], y - self._ego_xy[1]) > radius_m

    def _random_route(self, vclass: str, type_id: str) -> list[str]:
        edges = self._index.edges_by_vclass[vclass]
        for _ in range(10):
            a, b = (edges[i] for i in self._rng.integers(0, len(edges), 2))
            if a == b or not self._far_from_ego(a):
                continue
            route = libsumo.simulation.findRoute(a, b, vType=type_id)
            if route.edges:
                return list(route.edges)
        return []

    def _add_vehicle(self, kind: str) -> None:
        variant = self._variants[kind][int(self._rng.integers(0, len(self._variants[kind])))]
        edges = self._random_route(KINDS[kind].sumo_vclass, variant.type_id)
        if not edges:
            return
        self._serial += 1
        vid, rid = f"{kind}_{self._serial}", f"r_{self._serial}"
        libsumo.route.add(rid, edges)
        libsumo.vehicle.add(vid, rid, typeID=variant.type_id, depart="now", departLane="best",
                            departPos="random_free", departSpeed="max")  # fmt: skip
        self._alive.add(vid)

    def _add_person(self) -> None:
        walk = self._index.walk_edges
        for _ in range(10):
            a, b = (walk[i] for i in self._rng.integers(0, len(walk), 2))
            if a == b or not self._far_from_ego(a):
                continue
            stages = libsumo.simulation.findIntermodalRoute(a, b, modes="")
            edges = [e for s in stages for e in s.edges]
            if not edges:
                continue
            variant = self._variants["pedestrian"][int(self._rng.integers(0, len(self._variants["pedestrian"])))]
            self._serial += 1
            pid = f"ped_{self._serial}"
            libsumo.person.add(pid, a, 0.0, depart=-3, typeID=variant.type_id)  # -3: depart now
            libsumo.person.appendWalkingStage(pid, edges, arrivalPos=-1)
            return

    def _top_up(self, max_new: int = 10) -> None:
        for vid in libsumo.simulation.getArrivedIDList():
            self._alive.discard(vid)
        counts: dict[str, int] = {}
        for vid in self._alive:
            kind = vid.rsplit("_", 1)[0]
            counts[kind] = counts.get(kind, 0) + 1
        added = 0
        for kind in sorted(self._targets):
            for _ in range(min(self._targets[kind] - counts.get(kind, 0), max_new - added)):
                self._add_vehicle(kind)
                added += 1
        for _ in range(min(self._scenario.traffic.pedestrians - libsumo.person.getIDCount(), 5)):
            self._add_person()

    def _add_parked(self) -> None:
        """Vehicles standing in street-parking spaces for the whole scene (inserted parked)."""
        slots = [(a, i) for a in self._parking for i in range(len(a.spaces))]
        count = min(self._scenario.traffic.parked, len(slots))
        per_area: dict[str, int] = {}
        for k in sorted(self._rng.choice(len(slots), size=count, replace=False).tolist()):
            area = slots[k][0]
            per_area[area.area_id] = per_area.get(area.area_id, 0) + 1
        by_id = {a.area_id: a for a in self._parking}
        for area_id, n in per_area.items():
            area = by_id[area_id]
            edge = area.lane_id.rsplit("_", 1)[0]
            libsumo.route.add(f"park_{area_id}", [edge])
            for _ in range(n):
                self._serial += 1
                vid = f"parked_{self._serial}"
                variant = self._variants["car"][int(self._rng.integers(0, len(self._variants["car"])))]
                lane_index = area.lane_id.rsplit("_", 1)[1]
                libsumo.vehicle.add(vid, f"park_{area_id}", typeID=variant.type_id, depart="now",
                                    departLane=lane_index, departPos="stop", departSpeed="0")  # fmt: skip
                libsumo.vehicle.setParkingAreaStop(vid, area_id, duration=1e7)
                self._parked.add(vid)

    # --- stepping --------------------------------------------------------------------------
    def warm_up(self) -> None:
        """Fill the town: run the warm-up, then pick (or insert) the ego."""
        steps = round(self._scenario.warmup_s / self._scenario.step_s)
        self._add_parked()
        for i in range(steps):
            if i % 10 == 0:
                self._top_up(max_new=40)
            libsumo.simulationStep()
        self._choose_ego()

    def _choose_ego(self) -> None:
        ego = self._scenario.ego
        if ego.route:
            self._insert_ego(list(ego.route), "ego.route")
        elif ego.start == "on_ramp":
            ramps = self._index.on_ramps
            if not ramps:
                self.notices.append("note: the network has no highway entrance ramp; the ego is a random car")
                self._pick_ego("any")
            else:
                ramp = ramps[int(self._rng.integers(0, len(ramps)))]
                self._insert_ego([ramp], f"entrance ramp {ramp}")
        else:
            self._pick_ego(ego.start)
        libsumo.vehicle.setColor(self._ego, (255, 0, 0, 255))
        self._keep_ego_going()

    def _insert_ego(self, route: list[str], what: str) -> None:
        try:
            libsumo.route.add("ego_route", route)
            libsumo.vehicle.add(EGO_ID, "ego_route", typeID="ego_car", depart="now", departSpeed="max")
        except libsumo.TraCIException as err:
            raise TrafficError(f"{what}: SUMO refused the ego's route {route}: {err}") from err
        self._ego = EGO_ID
        self._keep_ego_going()
        for _ in range(400):
            libsumo.simulationStep()
            if EGO_ID in libsumo.vehicle.getIDList():
                return
        raise TrafficError(f"{what}: the ego could not enter the network within 20 s")

    def _pick_ego(self, start: str) -> None:
        cars = sorted(v for v in libsumo.vehicle.getIDList() if v.startswith("car_"))
        if start != "any":

            def fits(v: str) -> bool:
                speed = libsumo.lane.getMaxSpeed(libsumo.vehicle.getLaneID(v)) if libsumo.vehicle.getLaneID(v) else 0
                return speed <= 16.7 if start == "urban" else speed >= 22.2

            matching = [v for v in cars if not libsumo.vehicle.getRoadID(v).startswith(":") and fits(v)]
            if not matching:
                self.notices.append(f"note: no car is on a {start} road after the warm-up; the ego is a random car")
            cars = matching or cars
        if not cars:
            msg = "no passenger car is driving after the warm-up to serve as the ego (raise the density or warmup_s)"
            raise TrafficError(msg)
        self._ego = cars[int(self._rng.integers(0, len(cars)))]
        self._alive.discard(self._ego)

    def _keep_ego_going(self) -> None:
        route = libsumo.vehicle.getRoute(self._ego)
        if libsumo.vehicle.getRouteIndex(self._ego) < len(route) - 2:
            return
        edges = self._index.edges_by_vclass["passenger"]
        for _ in range(20):
            target = edges[int(self._rng.integers(0, len(edges)))]
            try:
                libsumo.vehicle.changeTarget(self._ego, target)
            except libsumo.TraCIException:
                continue
            if len(libsumo.vehicle.getRoute(self._ego)) - libsumo.vehicle.getRouteIndex(self._ego) > 3:
                return

    def step(self) -> None:
        libsumo.simulationStep()
        if self._ego != EGO_ID and self._ego not in libsumo.vehicle.getIDList():
            raise TrafficError(
                f"the ego vehicle {self._ego} left the simulation at t={libsumo.simulation.getTime():.2f} s"
            )
        self._keep_ego_going()
        if round(libsumo.simulation.getTime() / self._scenario.step_s) % 20 == 0:
            self._top_up()

    def close(self) -> None:
        libsumo.close()

    # --- world state -------------------------------------------------------------------------
    def _track_id(self, sumo_id: str) -> int:
        tid = self._track_ids.get(sumo_id)
        if tid is None:
            tid = len(self._track_ids) + 1
            self._track_ids[sumo_id] = tid
        return tid

    def world_state(self) -> WorldState:
        vehicles = list(libsumo.vehicle.getIDList())
        persons = list(libsumo.person.getIDList())
        ids = vehicles + persons
        n = len(ids)
        front = np.zeros((n, 3))
        angle = np.zeros(n)
        slope = np.zeros(n)
        speed = np.zeros(n)
        lwh = np.zeros((n, 3))
        cls = np.zeros(n, np.uint8)
        for i, sid in enumerate(ids):
            domain = libsumo.vehicle if i < len(vehicles) else libsumo.person
            front[i] = domain.getPosition3D(sid)
            angle[i] = domain.getAngle(sid)
            slope[i] = domain.getSlope(sid)
            speed[i] = domain.getSpeed(sid)
            cls[i], lwh[i, 0], lwh[i, 1], lwh[i, 2] = self._static_attributes(sid, domain)
        yaw = sumo_angle_to_yaw(angle)
        pitch = np.radians(slope)
        center = front_bumper_to_center(front, yaw, pitch, lwh[:, 0], lwh[:, 2])
        velocity = heading_vectors(yaw, pitch) * speed[:, None]
        track = np.array([self._track_id(s) for s in ids], dtype=np.uint32)
        boxes = AgentBoxes(track, cls, center, lwh, yaw, pitch)
        is_ego = np.array([s == self._ego for s in ids], dtype=bool)
        parked = np.array([s in self._parked for s in ids], dtype=bool)
        return WorldState(
            libsumo.simulation.getTime(), boxes.select(~is_ego), velocity[~is_ego], parked[~is_ego],
            boxes.select(is_ego), velocity[is_ego].reshape(3),
        )  # fmt: skip

    def _static_attributes(self, sid: str, domain: object) -> tuple[int, float, float, float]:
        cached = self._statics.get(sid)
        if cached is None:
            type_id = domain.getTypeID(sid)  # type: ignore[attr-defined]
            kind = "car" if type_id == "ego_car" else type_id.rsplit("_", 1)[0]
            spec = PEDESTRIAN if kind == "pedestrian" else KINDS.get(kind, KINDS["car"])
            cached = (int(spec.semantic_class), domain.getLength(sid), domain.getWidth(sid), domain.getHeight(sid))  # type: ignore[attr-defined]
            self._statics[sid] = cached
        return cached

    @property
    def lane_km(self) -> float:
        return self._index.vehicle_lane_km

    @property
    def vehicle_target(self) -> int:
        return sum(self._targets.values())


def _write_parking(net_path: Path, areas: list[ParkingArea]) -> Path:
    text = additional_xml(areas)
    path = cache_dir("parking", digest(net_path.read_bytes(), text)) / "parking.add.xml"
    if not path.exists():
        path.write_text(text)
    return path
