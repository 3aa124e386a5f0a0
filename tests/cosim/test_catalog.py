"""The built-in scenes: the reference set, each on a built-in town, conditions as named."""

from cosim.scenario import catalog_names, load_scenario
from networks.towns import TOWNS

REFERENCE_SCENES = {
    "town03_day", "town03_night", "town05_crowded", "town05_highway", "town06_entrance", "town06_crowded",
    "town06_rain", "town07_village", "town07_rain", "town10_crowded", "town10_night",
}  # fmt: skip


def test_catalog_holds_the_reference_scenes():
    assert set(catalog_names()) >= REFERENCE_SCENES


def test_every_catalog_scene_names_the_built_in_town_of_its_name():
    for name in catalog_names():
        scenario = load_scenario(name)
        assert scenario.network in TOWNS, name
        assert not TOWNS[scenario.network].stand_in, name
        assert name.startswith(scenario.network + "_"), name


def test_scene_names_match_their_conditions():
    for name in catalog_names():
        weather = load_scenario(name).weather
        for condition in ("night", "rain", "fog"):
            assert (weather == condition) == name.endswith("_" + condition), name


def test_every_catalog_scene_has_traffic_and_a_described_setting():
    for name in catalog_names():
        scenario = load_scenario(name)
        assert scenario.description, name
        assert scenario.traffic.vehicles_per_lane_km > 0 or (scenario.traffic.vehicles or 0) > 0, name
