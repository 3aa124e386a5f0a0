"""The running simulation: start, demand, the ego, and world states.

libsumo runs one simulation per process; parallel runs use separate processes.
"""

from __future__ import annotations

import os
from collections import Counter
from collections.abc import Iterator
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from cosim.construction import zone_layout
from cosim.demand import (
    CHILD,
    KINDS,
    PEDESTRIAN,
    KindSpec,
    TypeVariant,
    busiest,
    sample_size,
    sample_variants,
    split_by_mix,
    target_vehicle_count,
)
from cosim.errors import TrafficError
from cosim.kinematics import (
    SUMO_BLINKER_LEFT,
    SUMO_BLINKER_RIGHT,
    front_bumper_to_center,
    heading_vectors,
    lamps_of,
    sumo_angle_to_yaw,
)
from cosim.net_index import index_net
from cosim.parking import SPACE_LENGTH_M, ParkingArea, additional_xml, find_parking_areas
from cosim.scenario import Scenario
from cosim.state import WorldState
from cosim.sumo.people import WALKER, StreetPeople
from cosim.trailers import HITCH_BEHIND_M, Combination, hitch_point, pulled_axle, trailer_box_center
from gtgen.content import STOPPED_MPS
from networks.cache import cache_dir, digest, intact, seal, take_notices
from networks.classes import SemanticClass
from networks.errors import clipped, quoted
from networks.sumo_tools import sumo_binary, sumo_home, sumo_refusal
from networks.vocabulary import SignalState
from networks.world import lane_types
from sensors.agents import Agents, EgoState
from sensors.bodies import stride_m, walker_length_m

if TYPE_CHECKING:
    from cosim.sumo.hazards import HazardController

sumo_home()  # exports SUMO_HOME before libsumo loads
import libsumo  # noqa: E402
import sumolib  # noqa: E402

EGO_ID = "ego"
LANE_CHANGE_S = 3.0  # a lane change takes this long (SUMO's continuous lane change); at 0 it is one step
# Every vehicle re-plans its route each minute on the travel times SUMO measures, so
# traffic spreads around queues instead of feeding them (the jams of a crowded town).
REROUTING_OPTIONS = ("--device.rerouting.probability", "1", "--device.rerouting.period", "60")
# The ego is drawn from the quarter of the candidate cars with the most agents within
# 60 m: a scene is recorded where there is traffic, not on an empty edge of the town.
EGO_BUSY_RADIUS_M = 60.0
EGO_BUSY_SHARE = 0.25
HAZARD_EGO_FLOW, HAZARD_EGO_ROAD_M = 0.5, 1500.0  # in a hazard scene, the ego is picked among cars driving at
# least this share of the speed limit whose route stays on roads as fast this far
# A turning vehicle waits for a pedestrian this close to their conflict point (SUMO's
# default, 10 m, lets a busy crossing hold a turn for minutes and jam the junction).
CROSSING_GAP_M = 4.0
ROUTING_AGGREGATED = libsumo.constants.ROUTING_MODE_AGGREGATED  # new trips, too, plan on measured times
# World states read only the agents around the ego, from two context subscriptions: the
# vehicles around the ego itself, the persons around a point of interest kept on the ego
# (SUMO keeps one context subscription per object). SUMO measures from front bumpers and
# the point lags the ego by a step, hence the margin over the radius asked for.
STATE_VARIABLES = (
    libsumo.constants.VAR_POSITION3D,
    libsumo.constants.VAR_ANGLE,
    libsumo.constants.VAR_SLOPE,
    libsumo.constants.VAR_SPEED,
)
TURN_SIGNAL_M = 40.0
"""Indicators flash from this far before a junction (about 3 s at 50 km/h)."""
LAMPED_CLASSES = [int(c) for c in (SemanticClass.CAR, SemanticClass.TRUCK, SemanticClass.BUS, SemanticClass.MOTORCYCLE)]
"""Classes with head, tail and brake lamps and indicators."""
VEHICLE_VARIABLES = (
    *STATE_VARIABLES, libsumo.constants.VAR_SIGNALS, libsumo.constants.VAR_LANE_ID, libsumo.constants.VAR_LANEPOSITION
)  # fmt: skip
"""Read for vehicles: the state of every agent, and the lamps SUMO sets (brakes, indicators)."""
CONTEXT_MARGIN_M = 25.0
PERSON_ANCHOR = "ego_person_context"
FASTER_ROAD_SHARE = 1.3
SIZE_STREAM = 0x5125
"""Vehicles' own sizes are drawn from a random stream of their own (seeded with the scene's seed
and this), so that sizing them does not change the rest of the traffic's draws."""
PARKED_CLEARANCE_M = 0.6
GAIT_FORGET_S = 60.0  # a walker not read for this long (gone, or far from the ego) starts again at its own phase
"""A parked car is at most this much shorter than its parking space."""
EGO_MOVING_MPS = 2.0
"""The ego is picked among the cars moving faster than this, where any are."""


@dataclass(slots=True)
class TrafficCounts:
    """Running totals since the start: vehicles that entered the network (``parked`` of
    them inserted parked), teleports SUMO started (a jam or a stuck vehicle), and who
    teleported."""

    inserted: int = 0
    parked: int = 0
    running: int = 0  # vehicles in the network now, parked ones included
    teleports: int = 0
    teleported_ids: set[str] = field(default_factory=set)

    @property
    def teleported_share(self) -> float:
        """Share of the vehicles that drove (not the parked ones) that SUMO teleported."""
        return len(self.teleported_ids) / max(self.inserted - self.parked, 1)


class Traffic:
    """A running SUMO simulation stepped in lock-step with the frame loop."""

    def __init__(self, net_path: Path, net: sumolib.net.Net, scenario: Scenario) -> None:
        self._scenario = scenario
        self._rng = np.random.default_rng(scenario.seed)
        self._size_rng = np.random.default_rng([scenario.seed, SIZE_STREAM])  # each vehicle's own size
        self._index = index_net(net)
        self._track_ids: dict[str, int] = {}
        self._serial = 0
        self._demand_kind: dict[str, str] = {}  # SUMO id -> the kind each vehicle of the demand was added as
        self._statics: dict[str, tuple[int, float, float, float]] = {}
        self._lane_lengths: dict[str, float] = {}
        self._parking = find_parking_areas(net, lane_types(net_path)) if scenario.traffic.parked > 0 else []
        self._parked: set[str] = set()
        cmd = [
            str(sumo_binary("sumo")), "-n", str(net_path), "--step-length", f"{scenario.step_s}",
            "--seed", str(scenario.seed), "--no-step-log", "true", "--no-warnings", "true",
            "--time-to-teleport", "120", "--collision.action", "warn", "--begin", "0",
            "--lanechange.duration", f"{LANE_CHANGE_S}",  # vehicles move across lanes, not jump
            *REROUTING_OPTIONS,
        ]  # fmt: skip
        if self._parking:
            cmd += ["--additional-files", str(_write_parking(net_path, self._parking))]
        self._cache_notices = take_notices()
        try:
            libsumo.start(cmd)
        except libsumo.TraCIException as err:  # libsumo says only "Process Error": ask the sumo binary why
            reason = sumo_refusal(cmd[1:]) or str(err)
            raise TrafficError(f"{net_path}: SUMO could not load the network: {reason}") from err
        self._variants = self._define_types()
        self._spec_of_type = {v.type_id: v.spec for variants in self._variants.values() for v in variants}
        self._spec_of_type["ego_car"] = KINDS["car"]
        lights = scenario.street.traffic_lights
        self._signals: tuple[str, ...] = tuple(sorted(libsumo.trafficlight.getIDList())) if lights else ()
        traffic = scenario.traffic
        total = target_vehicle_count(traffic.vehicles_per_lane_km, self._index.vehicle_lane_km, traffic.vehicles)
        self.notices: list[str] = list(self._cache_notices)
        self._targets = self._open_targets(split_by_mix(total, traffic.mix))
        self._pedestrians = traffic.pedestrians if self._index.walk_edges else 0
        if traffic.pedestrians and not self._index.walk_edges:
            self.notices.append("note: the network has no sidewalks or footpaths; the scene has no pedestrians")
        self._ego_xy: tuple[float, float] | None = None
        self._ego = ""
        self._egos = 0  # egos inserted so far (a new one after each scene cut)
        self._scene_cut = False
        self._watch_radius_m: float | None = None
        self._long_route: list[str] = []
        self.counts = TrafficCounts()
        self._hazards: HazardController | None = None
        if scenario.hazards:
            from cosim.hazards.plan import Sight
            from cosim.sumo.hazards import HazardController
            from cosim.sumo.hazards.base import CHILD_TYPE

            shortest = min(self._variants.get("pedestrian", []), key=lambda v: v.height_m, default=None)
            cars = tuple(v.type_id for v in self._variants.get("car", []))
            self._spec_of_type[CHILD_TYPE] = PEDESTRIAN  # the jaywalking children's type
            self._hazards = HazardController(scenario.hazards, scenario.seed, self._parked, self._index.walk_edges,
                                             Sight.of_rig(scenario.sensors),
                                             shortest.type_id if shortest is not None else "", cars)  # fmt: skip
        self._street: StreetPeople | None = None
        if traffic.street_pedestrians or traffic.street_cyclists:  # its own random draws: the others' stay
            self._street = StreetPeople(self._index, np.random.default_rng([scenario.seed, 0x57EE7]),
                                        traffic.street_pedestrians, traffic.street_cyclists,
                                        self._variants["pedestrian"], self._variants.get("child", []),
                                        self._variants["bicycle"])  # fmt: skip
        self._ego_collided = False
        self._trailers: dict[str, Combination] = {}  # SUMO id -> lengths, for trucks with a trailer
        self._axles: dict[str, tuple[float, npt.NDArray[np.float64], npt.NDArray[np.float64]]] = {}
        self._headings: tuple[float, dict[int, float]] = (-np.inf, {})  # the last read's time and yaw by track id
        self._gait: dict[int, tuple[float, float]] = {}  # a walker's last read's time and gait cycles by track id
        self._works = self._close_lane(net) if scenario.construction.edge else Agents.empty()
        self._stood_s = 0.0  # how long the ego has stood (below STOPPED_MPS) without a break

    def _close_lane(self, net: sumolib.net.Net) -> Agents:
        """Close the construction zone's lane to every vehicle; its objects (track ids given as
        world states are read)."""
        zone = self._scenario.construction
        where = f"construction.edge {zone.edge!r}"
        if not net.hasEdge(zone.edge):
            raise TrafficError(f"{where}: no such edge in the network")
        lanes = net.getEdge(zone.edge).getLanes()
        if zone.lane >= len(lanes):
            raise TrafficError(
                f"construction.lane {zone.lane}: {where} has {len(lanes)} lane(s), 0 to {len(lanes) - 1}"
            )
        open_lanes = [k for k, ln in enumerate(lanes) if k != zone.lane and ln.allows("passenger")]
        if not open_lanes:
            raise TrafficError(f"{where}: closing lane {zone.lane} leaves no lane open to cars; pick a wider road")
        lane = lanes[zone.lane]
        libsumo.lane.setDisallowed(lane.getID(), ["all"])
        side = 1 if max(open_lanes) > zone.lane else -1  # the open lane beside it: left (+1) or right
        layout = zone_layout(
            lane.getShape3D(), lane.getWidth(), side, zone.start_m, zone.length_m, zone.cone_spacing_m, zone.vehicle
        )
        n = len(layout)
        agents = Agents.standing(np.arange(1, n + 1, dtype=np.uint32), layout.semantic_class, layout.center_map_m,
                                 layout.lwh_m, layout.yaw_map_rad)  # fmt: skip
        parked = layout.semantic_class == int(SemanticClass.CONSTRUCTION_VEHICLE)  # stands for the whole scene
        return Agents(agents.instance_id, agents.semantic_class, agents.center_map_m, agents.lwh_m,
                      agents.yaw_map_rad, agents.pitch_rad, agents.velocity_map_mps, parked)  # fmt: skip

    def _open_targets(self, targets: dict[str, int]) -> dict[str, int]:
        """The vehicle counts of the kinds some lane of the network is open to; a notice for each other."""
        kept = {k: n for k, n in targets.items() if KINDS[k].sumo_vclass in self._index.edges_by_vclass}
        for kind in sorted(k for k, n in targets.items() if n > 0 and k not in kept):
            self.notices.append(f"note: no lane of the network is open to {kind}s; the scene has none")
        return kept

    # --- set-up --------------------------------------------------------------------------
    def _define_types(self) -> dict[str, list[TypeVariant]]:
        variants: dict[str, list[TypeVariant]] = {}
        mix = self._scenario.traffic.mix
        # kinds added later (trucks with trailers) draw their types only where the mix has them,
        # so that scenes without them keep their random draws, and so their traffic
        optional = {"truck_trailer"}
        for spec in [s for s in KINDS.values() if s.kind not in optional or mix.get(s.kind, 0) > 0] + [PEDESTRIAN]:
            base = "DEFAULT_PEDTYPE" if spec is PEDESTRIAN else "DEFAULT_VEHTYPE"
            variants[spec.kind] = sample_variants(spec, self._rng)
            for v in variants[spec.kind]:
                libsumo.vehicletype.copy(base, v.type_id)
                if spec is not PEDESTRIAN:
                    libsumo.vehicletype.setVehicleClass(v.type_id, spec.sumo_vclass)
                    libsumo.vehicletype.setShapeClass(v.type_id, spec.shape_class)
                    libsumo.vehicletype.setAccel(v.type_id, v.accel_mps2)
                    libsumo.vehicletype.setDecel(v.type_id, spec.decel_mps2)
                    libsumo.vehicletype.setParameter(v.type_id, "junctionModel.jmCrossingGap", f"{CROSSING_GAP_M}")
                libsumo.vehicletype.setLength(v.type_id, v.length_m)
                libsumo.vehicletype.setWidth(v.type_id, v.width_m)
                libsumo.vehicletype.setHeight(v.type_id, v.height_m)
                libsumo.vehicletype.setMaxSpeed(v.type_id, v.max_speed_mps)
        libsumo.vehicletype.copy("car_0", "ego_car")
        if self._scenario.traffic.street_pedestrians:  # drawn after the others: their sizes stay
            variants["child"] = sample_variants(CHILD, np.random.default_rng([self._scenario.seed, 0xC41D]))
            for v in variants["child"]:
                libsumo.vehicletype.copy("DEFAULT_PEDTYPE", v.type_id)
                libsumo.vehicletype.setLength(v.type_id, v.length_m)
                libsumo.vehicletype.setWidth(v.type_id, v.width_m)
                libsumo.vehicletype.setHeight(v.type_id, v.height_m)
                libsumo.vehicletype.setMaxSpeed(v.type_id, v.max_speed_mps)
        return variants

    # --- demand ----------------------------------------------------------------------------
    def _far_from_ego(self, edge_id: str, radius_m: float = 90.0) -> bool:
        """New agents enter out of the ego's sight: on an edge no part of which is near it."""
        return self._ego_xy is None or self._index.distance_m(edge_id, self._ego_xy) > radius_m

    def _random_route(self, vclass: str, type_id: str) -> list[str]:
        edges, weights = self._index.edges_by_vclass[vclass], self._index.edge_weights[vclass]
        for _ in range(10):
            a, b = (edges[i] for i in self._rng.choice(len(edges), size=2, p=weights))
            if a == b or not self._far_from_ego(a):
                continue
            route = libsumo.simulation.findRoute(a, b, vType=type_id, routingMode=ROUTING_AGGREGATED)
            if route.edges:
                return list(route.edges)
        return []

    def _entry_route(self, vclass: str, type_id: str) -> list[str]:
        """A trip through the network: from an edge where traffic enters it to one where it
        leaves (a small network, where trips between two distant edges cannot be found)."""
        entries, exits = self._index.entries_by_vclass.get(vclass, []), self._index.exits_by_vclass.get(vclass, [])
        if not entries or not exits:
            return []
        for _ in range(10):
            a, b = entries[int(self._rng.integers(0, len(entries)))], exits[int(self._rng.integers(0, len(exits)))]
            if a == b:
                return [a]
            route = libsumo.simulation.findRoute(a, b, vType=type_id, routingMode=ROUTING_AGGREGATED)
            if route.edges:
                return list(route.edges)
        return []

    def _add_vehicle(self, kind: str) -> None:
        variant = self._variants[kind][int(self._rng.integers(0, len(self._variants[kind])))]
        vclass = KINDS[kind].sumo_vclass
        edges, depart_pos = self._random_route(vclass, variant.type_id), "random_free"
        if not edges:
            edges, depart_pos = self._entry_route(vclass, variant.type_id), "base"
        if not edges:
            return
        self._serial += 1
        vid, rid = f"{kind}_{self._serial}", f"r_{self._serial}"
        libsumo.route.add(rid, edges)
        libsumo.vehicle.add(
            vid, rid, typeID=variant.type_id, depart="now", departLane="best", departPos=depart_pos, departSpeed="max"
        )
        self._demand_kind[vid] = kind
        self._size(vid, KINDS[kind])

    def _size(self, vid: str, spec: KindSpec, max_length_m: float = np.inf) -> None:
        """Give a vehicle a size of its own, drawn from its kind's distribution."""
        length, width, height = sample_size(spec, self._size_rng, max_length_m)
        libsumo.vehicle.setLength(vid, length)
        libsumo.vehicle.setWidth(vid, width)
        libsumo.vehicle.setHeight(vid, height)

    def _walk(self) -> list[str]:
        """Footpath edges of a walk between two distinct footpaths, starting out of the ego's
        sight; else (a small network: one street, no crossing) a walk along one footpath."""
        walk = self._index.walk_edges
        for _ in range(10):
            a, b = (walk[i] for i in self._rng.choice(len(walk), size=2, p=self._index.walk_weights))
            if a == b or not self._far_from_ego(a):
                continue
            stages = libsumo.simulation.findIntermodalRoute(a, b, modes="")
            edges = [e for s in stages for e in s.edges]
            if edges:
                return edges
        return [walk[int(self._rng.choice(len(walk), p=self._index.walk_weights))]]

    def _add_person(self) -> None:
        edges = self._walk()
        variant = self._variants["pedestrian"][int(self._rng.integers(0, len(self._variants["pedestrian"])))]
        self._serial += 1
        pid = f"ped_{self._serial}"
        libsumo.person.add(pid, edges[0], 0.0, depart=-3, typeID=variant.type_id)  # -3: depart now
        arrival_m = float(self._rng.uniform(0.0, self._index.edge_length_m.get(edges[-1], 0.0)))
        libsumo.person.appendWalkingStage(pid, edges, arrivalPos=arrival_m)

    def _top_up(self, max_new: int = 10) -> None:
        """Bring every kind back to its target count (vehicles that arrived are replaced;
        vehicles waiting to enter count as present)."""
        present = [*libsumo.vehicle.getIDList(), *libsumo.simulation.getPendingVehicles()]
        counts = Counter(self._demand_kind.get(v, "") for v in present if v != self._ego and v not in self._parked)
        added = 0
        for kind in sorted(self._targets):
            for _ in range(min(self._targets[kind] - counts[kind], max_new - added)):
                self._add_vehicle(kind)
                added += 1
        walking = libsumo.person.getIDCount()
        if self._street is not None:  # the street's people are counted apart
            walking = sum(1 for p in libsumo.person.getIDList() if not p.startswith(WALKER))
        for _ in range(min(self._pedestrians - walking, 5)):
            self._add_person()

    def _street_top_up(self, at_once: bool) -> None:
        """The people along the ego's way (:mod:`cosim.sumo.people`)."""
        if self._street is not None and self._ego_xy is not None:
            route = libsumo.vehicle.getRoute(self._ego)
            ahead = list(route[max(int(libsumo.vehicle.getRouteIndex(self._ego)), 0) :])
            self._street.top_up(self._ego_xy, ahead, at_once)

    def _add_parked(self) -> None:
        """Vehicles standing in street-parking spaces for the whole scene (inserted parked)."""
        slots = [(a, i) for a in self._parking for i in range(len(a.spaces))]
        asked = self._scenario.traffic.parked
        count = min(asked, len(slots))
        if count < asked:
            where = "has no parking lanes" if not slots else f"has parking spaces for {len(slots)}"
            self.notices.append(f"note: traffic.parked asks for {asked} parked vehicles; the network {where}")
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
                self._size(vid, KINDS["car"], SPACE_LENGTH_M - PARKED_CLEARANCE_M)
                libsumo.vehicle.setParkingAreaStop(vid, area_id, duration=1e7)
                self._parked.add(vid)
        self.counts.parked = len(self._parked)

    # --- stepping --------------------------------------------------------------------------
    def warm_up(self) -> None:
        """Fill the town: run the warm-up, then pick (or insert) the ego. In a hazard scene the
        ego is picked the hazards' lead time before the warm-up ends (at most all of it), and
        the first events are prepared meanwhile."""
        step_s = self._scenario.step_s
        steps = round(self._scenario.warmup_s / step_s)
        lead = 0 if self._hazards is None else min(round(self._hazards.lead_s / step_s), steps)
        self._add_parked()
        for i in range(steps - lead):
            if i % 10 == 0:
                self._top_up(max_new=40)
            self._advance()
        self._choose_ego()
        x, y = libsumo.vehicle.getPosition(self._ego)
        self._ego_xy = (x, y)
        self._street_top_up(at_once=True)
        if self._hazards is not None:
            self._hazards.begin(self._time() + lead * step_s)  # the first events are due after the warm-up
        for _ in range(lead):
            self.step()

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
            if self._scenario.hazards:
                self._keep_to_its_roads()
        libsumo.vehicle.setColor(self._ego, (255, 0, 0, 255))
        self._keep_ego_going()

    def _keep_to_its_roads(self) -> None:
        """A hazard scene's ego is sent to the destination, of 20 drawn among the roads as fast as
        its own (:func:`_as_fast`; and the one it had), whose route keeps to such roads the
        longest (a motorway ego does not leave the motorway at the next exit)."""
        route = list(libsumo.vehicle.getRoute(self._ego))
        best = (_fast_ahead_m(self._ego), route[-1])
        for target in self._ego_sent_to(self._ego_targets()):
            best = max(best, (_fast_ahead_m(self._ego), target))
        libsumo.vehicle.changeTarget(self._ego, best[1])

    def _insert_ego(self, route: list[str], what: str) -> None:
        """Insert a new ego at the start of ``route`` and step until it has entered."""
        self._egos += 1
        suffix = "" if self._egos == 1 else f"_{self._egos}"
        ego_id, route_id = EGO_ID + suffix, "ego_route" + suffix
        try:
            libsumo.route.add(route_id, route)
            libsumo.vehicle.add(ego_id, route_id, typeID="ego_car", depart="now", departSpeed="max")
        except libsumo.TraCIException as err:
            msg = f"{what}: SUMO refused the ego's route {quoted(route)}: {clipped(str(err), 300)}"
            raise TrafficError(msg) from err
        self._ego = ego_id
        self._keep_ego_going()
        for _ in range(400):
            self._advance()
            if ego_id in libsumo.vehicle.getIDList():
                return
        raise TrafficError(f"{what}: the ego could not enter the network within 20 s")

    def _longest_route(self) -> list[str]:
        """The longest route a car can drive between the network's entries and exits (its
        edges when it has none), among up to 40 x 40 of them: where a new ego starts."""
        if self._long_route:
            return self._long_route
        edges = self._index.edges_by_vclass.get("passenger", [])
        if not edges:
            raise TrafficError("no lane of the network is open to cars: the ego needs one (check the map's lane types)")
        starts = _spread(self._index.entries_by_vclass.get("passenger") or edges, 40)
        ends = _spread(self._index.exits_by_vclass.get("passenger") or edges, 40)
        best: tuple[float, list[str]] = (-1.0, [])
        for a in starts:
            for b in ends:
                route = libsumo.simulation.findRoute(a, b, vType="ego_car")
                if route.edges and route.length > best[0]:
                    best = (route.length, list(route.edges))
        self._long_route = best[1] or [max(edges, key=lambda e: self._index.edge_length_m[e])]
        return self._long_route

    def _respawn_ego(self) -> None:
        """The ego ran out of road: a new ego starts at the longest route's start (a scene cut)."""
        self._insert_ego(self._longest_route(), "scene cut")
        libsumo.vehicle.setColor(self._ego, (255, 0, 0, 255))
        if self._watch_radius_m is not None:
            self._subscribe_near_ego(self._watch_radius_m)
        self._scene_cut = True

    def _pick_ego(self, start: str) -> None:
        cars = sorted(v for v in libsumo.vehicle.getIDList() if self._demand_kind.get(v) == "car")
        if start != "any":
            matching = [v for v in cars if not libsumo.vehicle.getRoadID(v).startswith(":") and _fits(v, start)]
            if not matching:
                self.notices.append(f"note: no car is on a {start} road after the warm-up; the ego is a random car")
            cars = matching or cars
        if not cars:
            self.notices.append(
                "note: no car is driving after the warm-up; the ego enters at the start of the network's longest route"
            )
            self._insert_ego(self._longest_route(), "the network's longest route")
            return
        if self._scenario.hazards:  # hazards need an ego that drives, not one queueing in a jam
            flowing = [v for v in cars if _flowing(v)]
            cars = [v for v in flowing if _staying(v, HAZARD_EGO_ROAD_M)] or flowing or cars
        cars = [cars[i] for i in busiest(_positions(cars), _positions(), EGO_BUSY_RADIUS_M, EGO_BUSY_SHARE)]
        moving = [v for v in cars if libsumo.vehicle.getSpeed(v) > EGO_MOVING_MPS]
        cars = moving or cars  # a scene starts on the move: frames of a car waiting repeat one view
        self._ego = cars[int(self._rng.integers(0, len(cars)))]

    def _stood_too_long(self) -> bool:
        """Whether the ego has stood longer than ``ego.max_stopped_s`` (counted from this step)."""
        cap = self._scenario.ego.max_stopped_s
        if cap <= 0:
            return False
        if libsumo.vehicle.getSpeed(self._ego) >= STOPPED_MPS:
            self._stood_s = 0.0
            return False
        self._stood_s += self._scenario.step_s
        return self._stood_s > cap and (self._hazards is None or not self._hazards.busy)

    def _hand_over_ego(self) -> None:
        """A car on the move becomes the ego, picked as at the start (among the busiest, on the
        kind of road ``ego.start`` asks for): a scene cut. The ego that stood goes on as traffic.
        Where no car moves, the ego stays and this is tried again a second later."""
        start = self._scenario.ego.start if self._scenario.ego.start in ("urban", "highway") else "any"
        d = libsumo.vehicle
        cars = sorted(v for v in d.getIDList() if self._demand_kind.get(v) == "car" and d.getSpeed(v) > EGO_MOVING_MPS
                      and not d.getRoadID(v).startswith(":") and (start == "any" or _fits(v, start)))  # fmt: skip
        if self._scenario.hazards:
            flowing = [v for v in cars if _flowing(v)]
            cars = [v for v in flowing if _staying(v, HAZARD_EGO_ROAD_M)] or flowing
        if not cars:
            self._stood_s -= 1.0
            return
        cars = [cars[i] for i in busiest(_positions(cars), _positions(), EGO_BUSY_RADIUS_M, EGO_BUSY_SHARE)]
        if self._watch_radius_m is not None:
            libsumo.vehicle.unsubscribeContext(
                self._ego, libsumo.constants.CMD_GET_VEHICLE_VARIABLE, self._watch_radius_m + CONTEXT_MARGIN_M
            )
        libsumo.vehicle.setColor(self._ego, (200, 200, 200, 255))
        self._ego = cars[int(self._rng.integers(0, len(cars)))]
        self._stood_s = 0.0
        if self._scenario.hazards:
            self._keep_to_its_roads()
        libsumo.vehicle.setColor(self._ego, (255, 0, 0, 255))
        self._keep_ego_going()
        if self._watch_radius_m is not None:
            self._subscribe_near_ego(self._watch_radius_m)
        self._scene_cut = True

    def _keep_ego_going(self) -> None:
        route = libsumo.vehicle.getRoute(self._ego)
        if libsumo.vehicle.getRouteIndex(self._ego) < len(route) - 2:
            return
        self._retarget_ego(self._ego_targets())

    def _ego_targets(self) -> list[str]:
        """Where the ego may be sent on: any road open to cars (with ``ego.start: urban``, the
        streets of at most 60 km/h: an urban ego stays in town); in a hazard scene, the roads as
        fast as the one it is on, where it is on a road (a motorway ego stays on the motorway)."""
        edges = self._index.edges_by_vclass["passenger"]
        lane = libsumo.vehicle.getLaneID(self._ego)
        if not self._scenario.hazards and self._scenario.ego.start == "urban":
            return [e for e in edges if libsumo.lane.getMaxSpeed(f"{e}_0") <= 16.7] or edges
        if not self._scenario.hazards or not lane or lane.startswith(":"):
            return edges
        limit = libsumo.lane.getMaxSpeed(lane)
        return [e for e in edges if _as_fast(libsumo.lane.getMaxSpeed(f"{e}_0"), limit)] or edges

    def _retarget_ego(self, edges: list[str]) -> None:
        """Send the ego on to a road drawn from ``edges`` (its route then goes on for more than
        three roads)."""
        for _ in self._ego_sent_to(edges):
            if len(libsumo.vehicle.getRoute(self._ego)) - libsumo.vehicle.getRouteIndex(self._ego) > 3:
                return

    def _ego_sent_to(self, edges: list[str], draws: int = 20) -> Iterator[str]:
        """Draw ``draws`` roads from ``edges`` and send the ego to each SUMO can route it to,
        yielding each such road while the ego is headed there."""
        for _ in range(draws):
            target = edges[int(self._rng.integers(0, len(edges)))]
            try:
                libsumo.vehicle.changeTarget(self._ego, target)
            except libsumo.TraCIException:
                continue
            yield target

    def _advance(self) -> None:
        libsumo.simulationStep()
        self.counts.inserted += libsumo.simulation.getDepartedNumber()
        self.counts.running = libsumo.vehicle.getIDCount()
        teleported = libsumo.simulation.getStartingTeleportIDList()
        self.counts.teleports += len(teleported)
        self.counts.teleported_ids.update(teleported)

    def step(self) -> None:
        """One step; when the ego has left the network (the end of a road), a new ego enters at
        the longest route's start and :attr:`scene_cut` says so until the next step."""
        self._scene_cut = False
        self._advance()
        try:  # raises for a vehicle no longer in the simulation (cheaper than the list of all ids)
            x, y = libsumo.vehicle.getPosition(self._ego)
        except libsumo.TraCIException:
            self._respawn_ego()
            x, y = libsumo.vehicle.getPosition(self._ego)
        if self._stood_too_long():
            self._hand_over_ego()
            x, y = libsumo.vehicle.getPosition(self._ego)
        self._ego_xy = (x, y)
        self._keep_ego_going()
        if self._hazards is not None:
            self._ego_collided = self._ego in libsumo.simulation.getCollidingVehiclesIDList()
            self._hazards.step(self._ego, self._time())
        if self._watch_radius_m is not None:
            libsumo.poi.setPosition(PERSON_ANCHOR, x, y)
        if self._scene_cut:
            self._street_top_up(at_once=True)
        if round(libsumo.simulation.getTime() / self._scenario.step_s) % 20 == 0:
            self._top_up()
            self._street_top_up(at_once=False)

    def close(self) -> None:
        libsumo.close()

    # --- world state -------------------------------------------------------------------------
    def _track_id(self, sumo_id: str) -> int:
        tid = self._track_ids.get(sumo_id)
        if tid is None:
            tid = len(self._track_ids) + 1
            self._track_ids[sumo_id] = tid
        return tid

    @property
    def scene_cut(self) -> bool:
        """Whether the last step put a new ego into the network (the scene starts again)."""
        return self._scene_cut

    def watch_near_ego(self, radius_m: float) -> None:
        """From now on, world states hold the agents within ``radius_m`` of the ego (and
        some beyond), read from context subscriptions instead of every agent's getters."""
        self._subscribe_near_ego(radius_m)
        x, y = libsumo.vehicle.getPosition(self._ego)
        libsumo.poi.add(PERSON_ANCHOR, x, y, (0, 0, 0, 0), layer=-100)
        persons = libsumo.constants.CMD_GET_PERSON_VARIABLE
        libsumo.poi.subscribeContext(PERSON_ANCHOR, persons, radius_m + CONTEXT_MARGIN_M, STATE_VARIABLES)
        self._watch_radius_m = radius_m

    def _subscribe_near_ego(self, radius_m: float) -> None:
        vehicles = libsumo.constants.CMD_GET_VEHICLE_VARIABLE
        libsumo.vehicle.subscribeContext(self._ego, vehicles, radius_m + CONTEXT_MARGIN_M, VEHICLE_VARIABLES)

    def _agent_variables(self, everyone: bool) -> tuple[list[str], list[str], list[tuple[Any, ...]]]:
        """Vehicle ids, person ids and, per id, (front position, angle, slope, speed, SUMO's
        signals, lane, position on it: 0, "", 0 for persons)."""
        if self._watch_radius_m is not None and not everyone:
            near_vehicles = libsumo.vehicle.getContextSubscriptionResults(self._ego)
            near_persons = libsumo.poi.getContextSubscriptionResults(PERSON_ANCHOR)
            rows = [tuple(v[k] for k in VEHICLE_VARIABLES) for v in near_vehicles.values()]
            rows += [(*(v[k] for k in STATE_VARIABLES), 0, "", 0.0) for v in near_persons.values()]
            return list(near_vehicles), list(near_persons), rows
        vehicles, persons = list(libsumo.vehicle.getIDList()), list(libsumo.person.getIDList())
        d = libsumo.vehicle
        rows = [(d.getPosition3D(v), d.getAngle(v), d.getSlope(v), d.getSpeed(v), d.getSignals(v), d.getLaneID(v),
                 d.getLanePosition(v)) for v in vehicles]  # fmt: skip
        d = libsumo.person
        rows += [(d.getPosition3D(p), d.getAngle(p), d.getSlope(p), d.getSpeed(p), 0, "", 0.0) for p in persons]
        return vehicles, persons, rows

    def world_state(self, everyone: bool = False) -> WorldState:
        """The ego and the agents around it (all agents before :meth:`watch_near_ego`, or
        with ``everyone``), in the map frame."""
        vehicles, persons, rows = self._agent_variables(everyone)
        ids = vehicles + persons
        n = len(ids)
        front = np.array([r[0] for r in rows], dtype=np.float64).reshape(n, 3)
        angle = np.array([r[1] for r in rows], dtype=np.float64)
        slope = np.array([r[2] for r in rows], dtype=np.float64)
        speed = np.array([r[3] for r in rows], dtype=np.float64)
        lwh = np.zeros((n, 3))
        cls = np.zeros(n, np.uint8)
        for i, sid in enumerate(ids):
            domain = libsumo.vehicle if i < len(vehicles) else libsumo.person
            cls[i], lwh[i, 0], lwh[i, 1], lwh[i, 2] = self._static_attributes(sid, domain)
        yaw = sumo_angle_to_yaw(angle)
        pitch = np.radians(slope)
        pulling = [i for i, sid in enumerate(ids[: len(vehicles)]) if sid in self._trailers]
        for i in pulling:
            lwh[i, 0] = self._trailers[ids[i]].truck_m
        center = front_bumper_to_center(front, yaw, pitch, lwh[:, 0], lwh[:, 2])
        walkers = np.flatnonzero(cls == int(SemanticClass.PEDESTRIAN))
        lwh[walkers, 0] = walker_length_m(lwh[walkers, 2])  # about the same centre: the stride fore and aft
        velocity = heading_vectors(yaw, pitch) * speed[:, None]
        track = np.array([self._track_id(s) for s in ids], dtype=np.uint32)
        parked = np.array([s in self._parked for s in ids], dtype=bool)
        is_ego = np.array([s == self._ego for s in ids], dtype=bool)
        sumo_signals = np.array([r[4] for r in rows], dtype=np.int64)
        sumo_signals[~self._turn_signal_shown(rows)] &= ~(SUMO_BLINKER_LEFT | SUMO_BLINKER_RIGHT)
        lamps = lamps_of(sumo_signals, np.isin(cls, LAMPED_CLASSES), parked, self._time(), track)
        gait = self._gait_cycles(track, walkers, speed, lwh[:, 2])
        agents = Agents(track, cls, center, lwh, yaw, pitch, velocity, parked, lamps, gait_cycles=gait)
        agents = agents.joined(
            self._trailers_of([ids[i] for i in pulling], agents.select(np.asarray(pulling, np.intp)), front[pulling])
        )
        agents = agents.joined(self._works_now())
        rates = self._yaw_rates(agents.instance_id, agents.yaw_map_rad)
        agents = replace(agents, yaw_rate_rad_s=rates, yaw_rate_after_rad_s=rates)
        is_ego = np.concatenate([is_ego, np.zeros(len(agents) - n, np.bool_)])
        if not is_ego.any():
            raise TrafficError(f"the ego vehicle {self._ego!r} is not among the agents read at t={self._time():.2f} s")
        e = int(np.flatnonzero(is_ego)[0])
        ego = EgoState(center[e], lwh[e], float(yaw[e]), float(pitch[e]), velocity[e], float(agents.yaw_rate_rad_s[e]))
        signals = {tls: SignalState.decode(libsumo.trafficlight.getRedYellowGreenState(tls)) for tls in self._signals}
        lane = str(libsumo.vehicle.getLaneID(self._ego))
        route = libsumo.vehicle.getRoute(self._ego)
        ahead = tuple(route[max(int(libsumo.vehicle.getRouteIndex(self._ego)), 0) :])
        hazards = () if self._hazards is None else self._hazards.active(self._track_id, self._ego)
        return WorldState(self._time(), agents.select(~is_ego), ego, self._scene_cut, signals, lane, ahead, hazards,
                          self._ego_collided)  # fmt: skip

    def _gait_cycles(
        self, track: npt.NDArray[np.uint32], walkers: npt.NDArray[np.intp], speed: npt.NDArray[np.float64],
        height: npt.NDArray[np.float64],
    ) -> npt.NDArray[np.float64]:  # fmt: skip
        """``(N,)`` the gait cycles each walker (rows ``walkers``) has walked: since its last read,
        its speed over its stride at that speed (:func:`sensors.bodies.stride_m`) times the time
        between; a walker read for the first time, or not read for :data:`GAIT_FORGET_S`, starts at
        a phase of its own (from its track id); NaN for the others."""
        now = self._time()
        out = np.full(track.shape[0], np.nan)
        for i in walkers.tolist():
            tid = int(track[i])
            last = self._gait.get(tid)
            if last is None or now - last[0] > GAIT_FORGET_S:
                cycles = (tid * 0.6180339887) % 1.0
            else:
                cycles = last[1] + float(speed[i]) * (now - last[0]) / stride_m(float(height[i]), float(speed[i]))
            self._gait[tid] = (now, cycles)
            out[i] = cycles
        if len(self._gait) > 2 * max(len(walkers), 100):  # forget walkers gone for long, so the table stays small
            self._gait = {tid: read for tid, read in self._gait.items() if now - read[0] <= GAIT_FORGET_S}
        return out

    def _yaw_rates(self, track: npt.NDArray[np.uint32], yaw: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
        """Each agent's rate of turn: its heading's change since the last read (wrapped to +-pi)
        over the time between; 0 for agents not read then. Read every step, so a timed LiDAR
        sweep turns a body between its last step and this one as SUMO turned it (and between this
        step and the next by the next one's: cosim.traffic_feed.turn_rates_across)."""
        now = self._time()
        then, last = self._headings
        rates = np.zeros(track.shape[0])
        if now > then:
            for i, tid in enumerate(track.tolist()):
                before = last.get(tid)
                if before is not None:
                    rates[i] = float(np.angle(np.exp(1j * (yaw[i] - before)))) / (now - then)
        self._headings = (now, dict(zip(track.tolist(), yaw.tolist(), strict=True)))
        return rates

    def _trailers_of(self, sids: list[str], trucks: Agents, front: npt.NDArray[np.float64]) -> Agents:
        """The trailers of the trucks ``sids`` (``trucks``: their boxes, ``front``: their front
        bumpers), each pulled along by its truck's hitch since the last read (cosim/trailers.py)."""
        now = self._time()
        axles = {}
        rows = []
        for k, sid in enumerate(sids):
            combo, yaw, pitch = self._trailers[sid], float(trucks.yaw_map_rad[k]), float(trucks.pitch_rad[k])
            hitch = hitch_point(front[k, :2], yaw, combo)
            last = self._axles.get(sid)
            axle = pulled_axle(None if last is None else last[1], hitch, yaw, combo)
            center_xy, trailer_yaw = trailer_box_center(hitch, axle, combo)
            height = float(trucks.lwh_m[k, 2])
            behind = combo.truck_m + HITCH_BEHIND_M + combo.axle_to_hitch_m
            z = front[k, 2] - behind * np.sin(pitch) + np.cos(pitch) * height / 2.0
            center = np.array([center_xy[0], center_xy[1], z])
            dt = now - last[0] if last is not None else 0.0
            velocity = (center - last[2]) / dt if last is not None and dt > 0 else trucks.velocity_map_mps[k]
            axles[sid] = (now, axle, center)
            rows.append((self._track_id(f"{sid}/trailer"), center, (combo.trailer_m, float(trucks.lwh_m[k, 1]), height),
                         trailer_yaw, pitch, velocity, bool(trucks.parked[k]), int(trucks.lamps[k])))  # fmt: skip
        self._axles = axles  # trucks not read this time start in line when read again
        if not rows:
            return Agents.empty()
        cols = list(zip(*rows, strict=True))
        return Agents(np.array(cols[0], np.uint32), np.full(len(rows), int(SemanticClass.TRAILER), np.uint8),
                      np.array(cols[1], np.float64), np.array(cols[2], np.float64), np.array(cols[3], np.float64),
                      np.array(cols[4], np.float64), np.array(cols[5], np.float64), np.array(cols[6], np.bool_),
                      np.array(cols[7], np.uint8))  # fmt: skip

    def _works_now(self) -> Agents:
        """The construction zone's objects with their track ids."""
        w = self._works
        if not len(w):
            return w
        track = np.array([self._track_id(f"works_{k}") for k in range(len(w))], np.uint32)
        return Agents(track, w.semantic_class, w.center_map_m, w.lwh_m, w.yaw_map_rad, w.pitch_rad,
                      w.velocity_map_mps, w.parked, w.lamps)  # fmt: skip

    def _turn_signal_shown(self, rows: list[tuple[Any, ...]]) -> npt.NDArray[np.bool_]:
        """Whether each vehicle's indicators may flash: in a junction, or within
        ``TURN_SIGNAL_M`` of its lane's end (SUMO sets them for the next turn however far away it
        is, and for lane changes it wishes; drivers signal a few seconds ahead)."""
        out = np.zeros(len(rows), np.bool_)
        for i, row in enumerate(rows):
            lane = row[5]
            if lane.startswith(":"):
                out[i] = True
            elif lane:
                length = self._lane_lengths.get(lane)
                if length is None:
                    length = self._lane_lengths[lane] = float(libsumo.lane.getLength(lane))
                out[i] = length - float(row[6]) <= TURN_SIGNAL_M
        return out

    @staticmethod
    def _time() -> float:
        return float(libsumo.simulation.getTime())

    def _static_attributes(self, sid: str, domain: object) -> tuple[int, float, float, float]:
        """An agent's class (from the kind of its SUMO type) and its length, width and height."""
        cached = self._statics.get(sid)
        if cached is None:
            spec = self._spec_of(domain.getTypeID(sid), domain is libsumo.person)  # type: ignore[attr-defined]
            cached = (int(spec.semantic_class), domain.getLength(sid), domain.getWidth(sid), domain.getHeight(sid))  # type: ignore[attr-defined]
            self._statics[sid] = cached
            if spec.kind == "truck_trailer":
                self._trailers[sid] = Combination.of(cached[1])
        return cached

    def _spec_of(self, type_id: str, person: bool) -> KindSpec:
        """The kind of a SUMO type (one the traffic defined; else a car, or a pedestrian for a
        person). A vehicle sized alone has its own copy of its type, named ``<type>@<vehicle>``."""
        fallback = PEDESTRIAN if person else KINDS["car"]
        return self._spec_of_type.get(type_id.split("@", 1)[0], fallback)

    @property
    def ego_id(self) -> str:
        """The SUMO id of the ego vehicle ("" before it is picked)."""
        return self._ego

    @property
    def ego_road_id(self) -> str:
        """The SUMO edge the ego is on (``:``-prefixed inside a junction)."""
        return str(libsumo.vehicle.getRoadID(self._ego))

    @property
    def ego_route(self) -> tuple[str, ...]:
        """The edges the ego is routed over now (its route grows as it drives)."""
        return tuple(libsumo.vehicle.getRoute(self._ego))

    @property
    def lane_km(self) -> float:
        return self._index.vehicle_lane_km

    @property
    def vehicle_target(self) -> int:
        return sum(self._targets.values())


def _positions(vehicles: list[str] | None = None) -> npt.NDArray[np.float64]:
    """``(N, 2)`` map positions of the given vehicles, else of every vehicle and person."""
    if vehicles is not None:
        return np.array([libsumo.vehicle.getPosition(v) for v in vehicles], dtype=np.float64).reshape(-1, 2)
    people = [libsumo.person.getPosition(p) for p in libsumo.person.getIDList()]
    return np.concatenate([_positions(list(libsumo.vehicle.getIDList())), np.array(people).reshape(-1, 2)])


def _fits(vid: str, start: str) -> bool:
    """Whether a vehicle is on the kind of road ``start`` names (urban: at most 60 km/h,
    highway: at least 80 km/h)."""
    lane = libsumo.vehicle.getLaneID(vid)
    speed = libsumo.lane.getMaxSpeed(lane) if lane else 0
    return bool(speed <= 16.7 if start == "urban" else speed >= 22.2)


def _flowing(vid: str) -> bool:
    """Whether a vehicle drives at least ``HAZARD_EGO_FLOW`` of its lane's speed limit."""
    lane = libsumo.vehicle.getLaneID(vid)
    return bool(lane) and libsumo.vehicle.getSpeed(vid) >= HAZARD_EGO_FLOW * libsumo.lane.getMaxSpeed(lane)


def _staying(vid: str, road_m: float) -> bool:
    """Whether a vehicle's route stays on roads as fast as its own for ``road_m`` (it is not
    about to leave a motorway)."""
    return _fast_ahead_m(vid, road_m) >= road_m


def _fast_ahead_m(vid: str, up_to_m: float = 10_000.0) -> float:
    """How far a vehicle's route goes on roads as fast as its own (up to ``up_to_m``)."""
    limit = libsumo.lane.getMaxSpeed(libsumo.vehicle.getLaneID(vid))
    route, at = libsumo.vehicle.getRoute(vid), libsumo.vehicle.getRouteIndex(vid)
    ahead = -libsumo.vehicle.getLanePosition(vid)
    for road in route[at:]:
        if not _as_fast(libsumo.lane.getMaxSpeed(f"{road}_0"), limit) or ahead >= up_to_m:
            break
        ahead += libsumo.lane.getLength(f"{road}_0")
    return float(max(ahead, 0.0))


def _as_fast(road_mps: float, own_mps: float) -> bool:
    """Whether a road's speed limit is like a vehicle's own road's: as fast, and less than
    ``FASTER_ROAD_SHARE`` faster (a motorway ego stays on the motorway; a town ego does not
    take the ring road, where a scene's hazards at crossings and lights cannot happen)."""
    return own_mps - 0.1 <= road_mps <= FASTER_ROAD_SHARE * own_mps + 0.1


def _spread(items: list[str], count: int) -> list[str]:
    """Up to ``count`` of ``items``, evenly spaced through the list."""
    if len(items) <= count:
        return items
    return [items[int(i)] for i in np.linspace(0, len(items) - 1, count)]


def _write_parking(net_path: Path, areas: list[ParkingArea]) -> Path:
    text = additional_xml(areas)
    path = cache_dir("parking", digest(net_path.read_bytes(), text)) / "parking.add.xml"
    if not intact(path):
        tmp = path.with_name(f"{path.name}.{os.getpid()}.partial")
        tmp.write_text(text)
        tmp.replace(path)
        seal(path)
    return path
