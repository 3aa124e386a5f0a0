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


URBAN_SCENES = {"town03_day", "town03_night", "town05_crowded", "town07_village", "town07_rain", "town10_crowded",
                "town10_night"}  # fmt: skip


def test_reference_scenes_cap_the_egos_standing_and_urban_ones_have_people_along_its_way():
    """Issue #26: the reference scenes keep the ego moving (a stop lasts at most 10 s); the
    urban ones keep pedestrians and cyclists along the ego's way."""
    for name in REFERENCE_SCENES:
        scenario = load_scenario(name)
        assert 0 < scenario.ego.max_stopped_s <= 10, name
        if name in URBAN_SCENES:
            assert scenario.traffic.street_pedestrians > 0 and scenario.traffic.street_cyclists > 0, name


def test_a_negative_stop_cap_or_street_count_is_refused_naming_the_key():
    import pytest

    from cosim.errors import ScenarioError

    for key in ("ego.max_stopped_s=-1", "traffic.street_pedestrians=-2", "traffic.street_cyclists=-1"):
        with pytest.raises(ScenarioError, match=key.split("=")[0].replace(".", r"\.")):
            load_scenario("town03_day", [key])
