from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from cosim.rigs import HDL32E_SPOT_MRAD
from networks.classes import SemanticClass
from sensors.errors import SensorConfigError
from sensors.lidar import Lidar, LidarScan, LidarSpec
from sensors.weather import DAY

WIDE = {"beams": 32, "vertical_min_deg": -15.0, "vertical_max_deg": 5.0, "azimuth_steps": 1024,
        "beam_divergence_mrad": HDL32E_SPOT_MRAD}  # fmt: skip


def panel(synth: SimpleNamespace, x_m: float, half_m: float, cls: SemanticClass) -> object:
    """A board facing the LiDAR at ``x_m``, ``2 * half_m`` wide, from the ground to 4 m."""
    return synth.quad([(x_m, -half_m, 0.0), (x_m, half_m, 0.0), (x_m, half_m, 4.0), (x_m, -half_m, 4.0)], cls)


def sense(synth: SimpleNamespace, static: list, seed: int = 1, **kw: object) -> LidarScan:
    lidar = Lidar(LidarSpec(**{**WIDE, **kw}))  # type: ignore[arg-type]
    return lidar.sense(synth.scene(static), synth.EGO, DAY, np.random.default_rng(seed)).scan


# the board's edges 8 mm (0.8 mrad) short of the 17th column either side of straight ahead, within half a spot
HALF_M = 10.0 * np.tan(17 * 2 * np.pi / 1024) - 0.008


def world(synth: SimpleNamespace, behind_m: float) -> list:
    return [synth.ground(), panel(synth, 10.0, HALF_M, SemanticClass.OTHER_OBJECT),
            synth.wall_at_x(10.0 + behind_m, cls=SemanticClass.BUILDING)]  # fmt: skip


def test_wide_beams_grow_edges_by_half_a_spot_and_dual_returns_add_the_far_echo(synth: SimpleNamespace) -> None:
    static = world(synth, 10.0)
    thin = sense(synth, static, beam_divergence_mrad=(0.0, 0.0))
    strongest = sense(synth, static)
    dual = sense(synth, static, returns="dual")
    on = strongest.semantic_class == SemanticClass.OTHER_OBJECT
    # strongest: one point a shot; the board's edges reach out by at most half a spot (1.65 mrad x 10 m)
    assert len(strongest) == len(thin)
    half_spot_m = 0.5 * HDL32E_SPOT_MRAD[0] / 1000.0 * 10.0
    width = np.abs(strongest.xyz_lidar_m[on, 1]).max()
    assert HALF_M + 1e-3 < width <= HALF_M + half_spot_m + 1e-3
    assert np.abs(thin.xyz_lidar_m[thin.semantic_class == SemanticClass.OTHER_OBJECT, 1]).max() <= HALF_M
    # dual: the first len(strongest) points are the strongest echoes, then each edge shot's other echo
    assert np.array_equal(dual.xyz_lidar_m[: len(strongest)], strongest.xyz_lidar_m)
    extra = dual.xyz_lidar_m[len(strongest) :]
    extra_cls = dual.semantic_class[len(strongest) :]
    assert len(extra) > 20
    on_board = np.abs(extra[:, 0] - 10.0) < 0.01
    on_wall = np.abs(extra[:, 0] - 20.0) < 0.01
    # the road where the board and the wall stand (a grazing spot's echo at its slices' mean range)
    on_road = (np.abs(extra[:, 2] + 1.95) < 0.05) & (extra_cls == SemanticClass.ROAD)
    assert np.all(on_board | on_wall | on_road) and on_board.sum() > 20 and on_wall.sum() > 0
    assert np.all(extra_cls[on_wall] == SemanticClass.BUILDING)
    assert np.all(extra_cls[on_board] == SemanticClass.OTHER_OBJECT)
    assert np.all(np.isin(dual.ring[len(strongest) :], dual.ring[: len(strongest)]))
    # a weak echo is weak: the far echoes' intensity below the wall's median
    wall = strongest.semantic_class == SemanticClass.BUILDING
    assert np.median(dual.intensity[len(strongest) :][on_wall]) < np.median(strongest.intensity[wall])


def test_echoes_closer_than_a_pulse_merge_into_unlabelled_points_between_the_surfaces(synth: SimpleNamespace) -> None:
    scan = sense(synth, world(synth, 0.5))
    mixed = scan.semantic_class == SemanticClass.NONE
    assert mixed.sum() > 20
    assert np.all(scan.instance_id[mixed] == 0)
    x = scan.xyz_lidar_m[mixed, 0]
    assert np.all((x > 10.0 + 0.01) & (x < 10.5 - 0.01))  # between the board and the wall behind it
    labelled = ~mixed & (scan.semantic_class != SemanticClass.ROAD)
    x = scan.xyz_lidar_m[labelled, 0]
    assert np.all((np.abs(x - 10.0) <= 0.05) | (np.abs(x - 10.5) <= 0.05))  # labelled points on their surface


def test_same_seed_same_bytes_and_thin_beams_change_nothing(synth: SimpleNamespace) -> None:
    static = world(synth, 3.0)
    a, b = (sense(synth, static, seed=4, returns="dual") for _ in range(2))
    thin = sense(synth, static, seed=4, beam_divergence_mrad=(0.0, 0.0))
    plain = Lidar(LidarSpec(**{**WIDE, "beam_divergence_mrad": (0.0, 0.0)}))  # type: ignore[arg-type]
    again = plain.sense(synth.scene(static), synth.EGO, DAY, np.random.default_rng(4)).scan
    for f in LidarScan.__slots__:
        assert getattr(a, f).tobytes() == getattr(b, f).tobytes()
        assert getattr(thin, f).tobytes() == getattr(again, f).tobytes()


@pytest.mark.parametrize(
    ("kw", "message"),
    [
        ({"beams": 64, "firing": "hdl64e", "returns": "dual"}, "HDL-64E S2"),
        ({"beam_divergence_mrad": (0.0, 0.0), "returns": "dual"}, "needs beam_divergence_mrad"),
        ({"beam_divergence_mrad": (7.0, 1.0)}, "narrower than the grid"),
    ],
)
def test_beam_options_the_sensor_cannot_have_are_refused(kw: dict, message: str) -> None:
    with pytest.raises(SensorConfigError, match=message):
        LidarSpec(**{**WIDE, **kw})


def test_a_timed_sweeps_edge_echoes_come_from_the_moving_car_where_it_is_then(synth: SimpleNamespace) -> None:
    speed = 15.0
    car = synth.agents([(5, SemanticClass.CAR, 0.0, 8.0, 0.75, 4.5, 1.8, 1.5, 0.0)], [[speed, 0.0, 0.0]])
    world = synth.scene([synth.ground(), synth.wall_at_x(30.0)], car)
    spec = LidarSpec(**{**WIDE, "sweep": "timed", "rate_hz": 10.0, "returns": "dual"})  # type: ignore[arg-type]
    scan = Lidar(spec).sense(world, synth.EGO, DAY, np.random.default_rng(2)).scan
    thin = Lidar(LidarSpec(**{**WIDE, "sweep": "timed", "rate_hz": 10.0, "beam_divergence_mrad": (0.0, 0.0)}))
    plain = thin.sense(world, synth.EGO, DAY, np.random.default_rng(2)).scan
    assert len(scan) > len(plain)
    on = scan.instance_id == 5
    xyz = Lidar(spec).spec.ego_SE3_sensor.transform_from(scan.xyz_lidar_m[on].astype(np.float64))
    back = xyz[:, 0] - speed * (scan.t_s[on] - 0.05)  # moved back to the sweep's middle, the car's time
    reach = 0.5 * HDL32E_SPOT_MRAD[0] / 1000.0 * np.linalg.norm(xyz[:, :2], axis=1)  # half a spot across
    assert np.all(np.abs(back) <= 2.25 + reach + 0.02)
    assert np.all(np.abs(xyz[:, 1] - 8.0) <= 0.9 + reach + 0.02)
