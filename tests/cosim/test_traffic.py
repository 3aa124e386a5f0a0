"""SUMO traffic of a scene: parked cars on parking lanes, the ego kept driving, density,
and the ego's start on a motorway entrance ramp (issue #4)."""

from collections.abc import Iterator
from contextlib import contextmanager

import numpy as np
import pytest
import shapely
import sumolib
from shapely.geometry import Point

from cosim.demand import KINDS, busiest
from cosim.net_index import index_net
from cosim.parking import SPACE_LENGTH_M
from cosim.scenario import load_scenario
from cosim.soak import soak
from cosim.sumo.traffic import PARKED_CLEARANCE_M, Traffic
from cosim.trailers import DRAWBAR_M, HITCH_BEHIND_M
from cosim.world_setup import PreparedNetwork, prepare_network
from networks.classes import SemanticClass
from networks.world import lane_footprint, lane_types

pytestmark = pytest.mark.slow

LIGHT = ("traffic.pedestrians=0", "warmup_s=5")
MOTORWAY_MPS = 22.0


@contextmanager
def running(scene: str, *overrides: str) -> Iterator[tuple[Traffic, PreparedNetwork]]:
    """A scene's traffic after its warm-up (SUMO runs one simulation per process)."""
    scenario = load_scenario(scene, list(overrides))
    prepared = prepare_network(scenario)
    traffic = Traffic(prepared.net_path, prepared.net, scenario)
    try:
        traffic.warm_up()
        yield traffic, prepared
    finally:
        traffic.close()


def _lane_area(net: sumolib.net.Net, types: dict[str, str], kind: str) -> shapely.Geometry:
    """Union of the footprints of one kind of lane: ``parking``, ``driving`` or ``sidewalk``."""

    def kind_of(lane: sumolib.net.lane.Lane) -> str:
        if types.get(lane.getID()) == "parking":
            return "parking"
        if lane.getPermissions() == {"pedestrian"}:
            return "sidewalk"
        return "driving" if lane.allows("passenger") else "other"

    return shapely.union_all(
        [
            lane_footprint(lane)
            for edge in net.getEdges(withInternal=False)
            if not edge.getFunction()
            for lane in edge.getLanes()
            if kind_of(lane) == kind
        ]
    )


def _centres_by_track(state_agents_ids: np.ndarray, centres: np.ndarray) -> dict[int, np.ndarray]:
    return {int(i): c for i, c in zip(state_agents_ids, centres, strict=True)}


def test_parked_cars_stand_still_on_parking_lanes_and_are_labelled_parked():
    overrides = (*LIGHT, "traffic.vehicles_per_lane_km=3", "traffic.parked=25")
    with running("town10_crowded", *overrides) as (traffic, prepared):
        first = traffic.world_state()
        for _ in range(200):
            traffic.step()
        later = traffic.world_state()
    parked = first.agents.parked
    assert parked.sum() == 25
    assert set(np.unique(first.agents.semantic_class[parked]).tolist()) == {SemanticClass.CAR}
    assert np.all(first.agents.lwh_m[parked, 0] <= SPACE_LENGTH_M - PARKED_CLEARANCE_M + 1e-6)  # they fit their space
    types = lane_types(prepared.net_path)
    on_parking = _lane_area(prepared.net, types, "parking").buffer(0.3)
    driving = _lane_area(prepared.net, types, "driving").buffer(-0.3)
    sidewalk = _lane_area(prepared.net, types, "sidewalk").buffer(-0.3)
    for x, y in first.agents.center_map_m[parked, :2]:
        spot = Point(x, y)
        assert on_parking.contains(spot), (x, y)
        assert not driving.contains(spot) and not sidewalk.contains(spot), (x, y)
    before = _centres_by_track(first.agents.instance_id[parked], first.agents.center_map_m[parked])
    after = _centres_by_track(
        later.agents.instance_id[later.agents.parked], later.agents.center_map_m[later.agents.parked]
    )
    assert before.keys() == after.keys()
    assert max(float(np.linalg.norm(after[k] - before[k])) for k in before) < 0.01


def test_ego_is_rerouted_when_its_route_ends_and_stays_in_the_scene():
    overrides = (*LIGHT, "step_s=0.1", "traffic.vehicles_per_lane_km=4", "ego.start=urban", "ego.max_stopped_s=0",
                 "traffic.street_pedestrians=0", "traffic.street_cyclists=0")  # fmt: skip
    with running("town03_day", *overrides) as (traffic, _):  # the same ego all along, on its own
        first_route = traffic.ego_route
        visited = [traffic.ego_road_id]
        for _ in range(3000):  # 300 s: longer than any first route across the town
            traffic.step()  # raises if the ego left the simulation
            road = traffic.ego_road_id
            if road != visited[-1] and not road.startswith(":"):
                visited.append(road)
        assert traffic.world_state().ego.lwh_m.shape == (3,)
    assert first_route[-1] in visited
    after_first = visited[visited.index(first_route[-1]) + 1 :]
    assert after_first, f"the ego stopped at the end of its first route {first_route}"


@pytest.mark.parametrize("density", [6.0, 18.0])
def test_density_sets_the_number_of_vehicles(density):
    overrides = ("traffic.pedestrians=0", "warmup_s=20", f"traffic.vehicles_per_lane_km={density}")
    with running("town03_day", *overrides, "traffic.parked=0") as (traffic, _):
        state = traffic.world_state()
        lane_km = traffic.lane_km
    vehicles = int(np.sum(state.agents.semantic_class != SemanticClass.PEDESTRIAN)) + 1  # the ego drives too
    expected = density * lane_km
    assert abs(vehicles - expected) <= max(3.0, 0.1 * expected), (vehicles, expected)
    cars = state.agents.lwh_m[state.agents.semantic_class == SemanticClass.CAR]
    assert len({tuple(c) for c in cars.round(2).tolist()}) >= 0.9 * len(cars)  # each car its own size
    assert abs(float(cars[:, 0].mean()) - KINDS["car"].mean_lwh_m[0]) < 0.25  # nuScenes' 4.62 m


def test_on_ramp_start_puts_the_ego_on_an_entrance_ramp_that_merges_into_the_motorway():
    overrides = (*LIGHT, "traffic.vehicles_per_lane_km=3", "ego.start=on_ramp")
    with running("town06_entrance", *overrides) as (traffic, prepared):
        net = prepared.net
        ramp = traffic.ego_road_id
        assert ramp in index_net(net).on_ramps
        after_ramp = net.getEdge(ramp).getToNode().getOutgoing()
        assert any(e.getSpeed() >= MOTORWAY_MPS and e.getLaneNumber() >= 3 for e in after_ramp)
        roads = set()
        for _ in range(600):  # 30 s
            traffic.step()
            roads.add(traffic.ego_road_id)
    assert net.getEdge(ramp).getSpeed() < MOTORWAY_MPS
    motorway = [r for r in roads if not r.startswith(":") and net.getEdge(r).getSpeed() >= MOTORWAY_MPS]
    assert motorway, f"the ego never reached the motorway from {ramp}: {sorted(roads)}"


@pytest.mark.parametrize("scene", ["town07_village", "town03_day"])
def test_nominal_demand_runs_ten_minutes_with_under_one_percent_teleported(scene):
    """Issue #3: the scene's own traffic, headless, for 600 s after its warm-up (the
    village's narrow T-junctions; the roundabout town)."""
    result = soak(scene, 600.0, ("step_s=0.1",))
    assert result.counts.inserted - result.counts.parked > result.vehicle_target
    assert result.counts.teleported_share < 0.01, result.line()


def test_the_ego_is_drawn_from_the_busiest_cars():
    cars = [(0.0, 0.0), (500.0, 0.0), (1000.0, 0.0), (1500.0, 0.0)]
    agents = [(500.0, 10.0)] * 5 + [(1500.0, 5.0)] * 2 + [(0.0, 100.0)]
    assert busiest(cars, agents, 60.0, 0.25).tolist() == [1]
    assert busiest(cars, agents, 60.0, 0.5).tolist() == [1, 3]
    assert busiest(cars[:1], [], 60.0, 0.25).tolist() == [0]


def test_agents_read_around_the_ego_equal_those_found_among_all_agents():
    """The frame loop reads only the agents near the ego (context subscriptions); they
    are exactly the agents a search over every vehicle and person finds, parked cars and
    pedestrians included, with the same boxes and velocities."""
    radius_m = 60.0
    overrides = ("warmup_s=20", "traffic.parked=300", "traffic.pedestrians=300", "traffic.vehicles_per_lane_km=10")
    kinds = {"parked": 0, "pedestrian": 0}
    with running("town10_crowded", *overrides) as (traffic, _):
        traffic.watch_near_ego(radius_m)
        for k in range(120):
            traffic.step()
            if k % 20:
                continue
            near = traffic.world_state().near(radius_m)
            every = traffic.world_state(everyone=True).near(radius_m)
            a, b = np.argsort(near.agents.instance_id), np.argsort(every.agents.instance_id)
            assert near.agents.instance_id[a].tolist() == every.agents.instance_id[b].tolist()
            np.testing.assert_allclose(near.agents.center_map_m[a], every.agents.center_map_m[b])
            np.testing.assert_allclose(near.agents.velocity_map_mps[a], every.agents.velocity_map_mps[b])
            np.testing.assert_array_equal(near.agents.parked[a], every.agents.parked[b])
            np.testing.assert_allclose(near.ego.center_map_m, every.ego.center_map_m)
            kinds["parked"] += int(near.agents.parked.sum())
            kinds["pedestrian"] += int(np.sum(near.agents.semantic_class == SemanticClass.PEDESTRIAN))
    assert kinds["parked"] > 0 and kinds["pedestrian"] > 0, kinds


def test_walkers_boxes_hold_their_stride_about_sumos_own_and_their_gait_follows_the_distance_walked():
    """SUMO keeps its walkers' lengths (0.3-0.5 m, its draws and traffic unchanged); their
    labelled boxes are lengthened fore and aft about the centre of SUMO's (half its length behind
    the front SUMO reports) to hold their stride, and their gait cycles grow by the distance
    walked over the stride."""
    import libsumo

    from cosim.kinematics import front_bumper_to_center, sumo_angle_to_yaw
    from sensors.bodies import stride_m, walker_length_m

    with running("town05_crowded", "warmup_s=20", "hazards=[]") as (traffic, _):
        last: dict[int, tuple[float, float]] = {}
        seen = advanced = 0
        for _ in range(5):
            traffic.step()
            state = traffic.world_state(everyone=True)
            walkers = state.agents.select(state.agents.semantic_class == SemanticClass.PEDESTRIAN)
            front = {tid: sid for sid, tid in traffic._track_ids.items()}
            for i, tid in enumerate(walkers.instance_id.tolist()):
                pid = front[tid]
                sumo_length, h = libsumo.person.getLength(pid), float(walkers.lwh_m[i, 2])
                assert 0.3 <= sumo_length <= 0.5
                assert walkers.lwh_m[i, 0] == pytest.approx(float(walker_length_m(h)))
                yaw = sumo_angle_to_yaw(np.array([libsumo.person.getAngle(pid)]))
                pitch = np.radians([libsumo.person.getSlope(pid)])
                front_m = libsumo.person.getPosition3D(pid)
                centre = front_bumper_to_center(front_m, yaw, pitch, sumo_length, h)[0]  # of SUMO's own box
                np.testing.assert_allclose(walkers.center_map_m[i], centre, atol=1e-9)
                speed = float(np.linalg.norm(walkers.velocity_map_mps[i]))
                if tid in last:
                    step_s = libsumo.simulation.getDeltaT()
                    assert walkers.gait_cycles[i] - last[tid][1] == pytest.approx(speed * step_s / stride_m(h, speed))
                    advanced += speed > 0.2
                last[tid] = (speed, float(walkers.gait_cycles[i]))
                seen += 1
        assert seen > 50 and advanced > 20, (seen, advanced)


def test_vehicles_change_lanes_by_moving_across_not_by_jumping():
    """A lane change takes SUMO's continuous lane-change time: where a vehicle's lane index
    changes, its sideways position moves on by a step's worth (SUMO's default, a jump of a
    lane width in one step, would teleport its box 3.5 m between two frames)."""
    import libsumo

    with running("town06_cut_ins", "traffic.pedestrians=0", "hazards=[]"):
        last: dict[str, tuple[str, int, float]] = {}
        shifts = []
        for _ in range(600):
            libsumo.simulationStep()
            for vid in libsumo.vehicle.getIDList():
                road, index = libsumo.vehicle.getRoadID(vid), libsumo.vehicle.getLaneIndex(vid)
                lateral = libsumo.vehicle.getLateralLanePosition(vid)  # from its lane's centre, + left
                if vid in last and last[vid][0] == road and last[vid][1] != index:
                    before = last[vid][1]
                    widths = libsumo.lane.getWidth(f"{road}_{before}"), libsumo.lane.getWidth(f"{road}_{index}")
                    half_widths = sum(widths) / 2
                    shifts.append(lateral - last[vid][2] + (index - before) * half_widths)
                last[vid] = (road, index, lateral)
    assert len(shifts) >= 10  # lane changes happened
    assert max(abs(s) for s in shifts) < 0.3  # about 2.5 m/s for 0.05 s, not a lane's width


def _hitches(agents, index: np.ndarray, behind_m: np.ndarray) -> np.ndarray:
    """``(K, 2)`` points ``behind_m`` behind the front (+) or rear (-) of the given boxes."""
    heading = np.column_stack([np.cos(agents.yaw_map_rad[index]), np.sin(agents.yaw_map_rad[index])])
    return agents.center_map_m[index, :2] + heading * behind_m[:, None]


def test_a_construction_zone_closes_its_lane_and_trailers_hang_on_their_trucks_hitches():
    overrides = (*LIGHT, "warmup_s=20", "traffic.mix.truck_trailer=0.6")
    works = (SemanticClass.TRAFFIC_CONE, SemanticClass.BARRIER, SemanticClass.CONSTRUCTION_VEHICLE)
    bends, pairs, first = [], 0, None
    with running("town05_construction", *overrides) as (traffic, prepared):
        zone = traffic._scenario.construction
        closed = lane_footprint(prepared.net.getEdge(zone.edge).getLanes()[zone.lane]).buffer(-0.9)
        for step in range(200):
            traffic.step()
            state = traffic.world_state(everyone=True)
            a = state.agents
            static = np.isin(a.semantic_class, [int(c) for c in works])
            first = first if first is not None else (a.instance_id[static], a.center_map_m[static])
            np.testing.assert_array_equal(a.instance_id[static], first[0])  # the zone stands still
            np.testing.assert_array_equal(a.center_map_m[static], first[1])
            moving = np.flatnonzero(~static & (a.semantic_class != int(SemanticClass.PEDESTRIAN)))
            inside = [closed.contains(Point(*a.center_map_m[i, :2])) for i in moving]
            assert not any(inside) or step < 40, "a vehicle drives in the closed lane"
            trailers = np.flatnonzero(a.semantic_class == int(SemanticClass.TRAILER))
            trucks = np.flatnonzero(a.semantic_class == int(SemanticClass.TRUCK))
            if not len(trailers):
                continue
            at_trailer = _hitches(a, trailers, a.lwh_m[trailers, 0] / 2 + DRAWBAR_M)
            at_truck = _hitches(a, trucks, -(a.lwh_m[trucks, 0] / 2 + HITCH_BEHIND_M))
            gaps = np.linalg.norm(at_trailer[:, None] - at_truck[None], axis=2)
            mate = gaps.argmin(axis=1)
            level = np.abs(a.pitch_rad[trailers]) < 1e-3  # on slopes the boxes' centres shift by pitch x height
            assert np.all(gaps.min(axis=1)[level] < 0.01) and np.all(gaps.min(axis=1) < 0.3)  # hung on a hitch
            pairs += len(trailers)
            bends += np.abs(np.angle(np.exp(1j * (a.yaw_map_rad[trailers] - a.yaw_map_rad[trucks[mate]])))).tolist()
    counts = {c: int(np.sum(a.semantic_class[static] == int(c))) for c in works}
    assert counts[SemanticClass.BARRIER] == 2 and counts[SemanticClass.CONSTRUCTION_VEHICLE] == 1
    assert counts[SemanticClass.TRAFFIC_CONE] >= 18
    assert pairs > 100 and max(bends) > 0.2  # trailers bend behind turning trucks


def test_street_people_walk_near_the_egos_route_in_groups_with_children_and_cyclists_ride_it():
    """Issue #26: ``traffic.street_pedestrians`` are kept on the sidewalks along the ego's way
    (within reach of it, near its route), some of them children; ``street_cyclists`` on its roads."""
    from cosim.sumo.people import ENTER_MAX_M, KEEP_M, NEAR_ROUTE_M

    overrides = ("traffic.pedestrians=0", "warmup_s=10", "traffic.street_pedestrians=40", "traffic.street_cyclists=6",
                 "traffic.vehicles_per_lane_km=4", "ego.start=urban", "traffic.mix={car: 1}")  # fmt: skip
    with running("town05_crowded", *overrides) as (traffic, prepared):
        index = index_net(prepared.net)
        traffic.step()  # people added in a step walk from the next
        first = traffic.world_state(everyone=True)
        route = [e for e in traffic.ego_route if e in index.edge_length_m]
        near_50, heights = [], []
        for step in range(1200):  # 60 s
            traffic.step()
            if step % 100 == 99:
                state = traffic.world_state(everyone=True)
                people = state.agents.semantic_class == SemanticClass.PEDESTRIAN
                d = np.linalg.norm(state.agents.center_map_m[:, :2] - state.ego.center_map_m[:2], axis=1)
                assert people.sum() <= 40 and d[people].max() <= KEEP_M + 20
                near_50.append(int((people & (d <= 50)).sum()))
                heights += state.agents.lwh_m[people, 2].tolist()
    people = first.agents.semantic_class == SemanticClass.PEDESTRIAN
    assert people.sum() == 40  # all of them at once when the ego is picked
    ego_xy = tuple(first.ego.center_map_m[:2])
    route_d = np.array(
        [min(index.distance_m(e, (p[0], p[1])) for e in route) for p in first.agents.center_map_m[people]]
    )
    from_ego = np.linalg.norm(first.agents.center_map_m[people, :2] - np.asarray(ego_xy), axis=1)
    assert np.all(from_ego <= ENTER_MAX_M + 5)
    assert np.all(route_d <= NEAR_ROUTE_M + 15), route_d.max()  # + sampling and the sidewalk's offset
    bikes = first.agents.semantic_class == SemanticClass.BICYCLE
    assert 1 <= bikes.sum() <= 6
    assert np.mean(near_50) >= 3, near_50  # the ego drives among them
    assert min(heights) < 1.45 and max(heights) > 1.55  # children and adults


@pytest.mark.parametrize("scene", ["town03_day", "town05_crowded"])
def test_cyclists_are_near_the_ego_from_the_first_frames_of_an_urban_catalog_scene(scene):
    """Issue #26: cyclists within 50 m of the ego in the first 200 frames (10 s) with the
    catalog's seed, whether the ego stands in a queue (town03_day) or drives (town05_crowded):
    some ride towards it, and those entering at once lie near and far (both scenes had none)."""
    from cosim.motion import simulate

    motion = simulate(load_scenario(scene, ["frames=200"]))
    assert motion.near_per_frame.get("bicycle", 0.0) >= 0.15, motion.near_per_frame


def test_the_ego_stands_no_longer_than_max_stopped_s_then_a_moving_car_takes_over():
    """``ego.max_stopped_s``: a queue or a red light holds the ego this long at most; then a
    car on the move is the ego (a scene cut)."""
    overrides = ("traffic.pedestrians=0", "warmup_s=30", "traffic.vehicles_per_lane_km=31", "ego.start=urban",
                 "ego.max_stopped_s=4")  # fmt: skip
    with running("town10_crowded", *overrides) as (traffic, _):
        stood, longest, cuts, egos = 0, 0, 0, {traffic.ego_id}
        for _ in range(800):  # 40 s in the densest town (the cap ended stands at 11 s and 20 s)
            traffic.step()
            state = traffic.world_state()
            cuts += state.scene_cut
            egos.add(traffic.ego_id)
            stood = stood + 1 if np.linalg.norm(state.ego.velocity_map_mps) < 0.1 else 0
            longest = max(longest, stood)
    assert longest <= 4.0 / 0.05 + 1, longest
    assert cuts == len(egos) - 1 and cuts >= 1


def test_walkers_gone_for_long_are_forgotten_and_start_again_at_their_own_phase(monkeypatch: pytest.MonkeyPatch):
    """The gait table keeps only walkers read in the last GAIT_FORGET_S (it would otherwise grow
    with every walker that ever walked); one back after longer starts at its own phase again."""
    from cosim.sumo import traffic as traffic_module

    clock = [0.0]
    monkeypatch.setattr(Traffic, "_time", staticmethod(lambda: clock[0]))
    traffic = Traffic.__new__(Traffic)
    traffic._gait = {}
    ones = np.ones(1)
    first = traffic._gait_cycles(np.array([7], np.uint32), np.array([0]), ones, 1.7 * ones)[0]
    clock[0] = 1.0
    walked = traffic._gait_cycles(np.array([7], np.uint32), np.array([0]), ones, 1.7 * ones)[0]
    assert walked > first
    for t in range(300):  # 300 other walkers, each read once, long ago
        clock[0] = 2.0 + t * 0.1
        traffic._gait_cycles(np.array([1000 + t], np.uint32), np.array([0]), ones, 1.7 * ones)
    clock[0] = 40.0 + traffic_module.GAIT_FORGET_S
    traffic._gait_cycles(np.array([7], np.uint32), np.array([0]), ones, 1.7 * ones)
    assert len(traffic._gait) < 100
    assert traffic._gait[7][1] == pytest.approx(first)  # walker 7 unread for longer than GAIT_FORGET_S
