import re
import subprocess
import sys
from pathlib import Path

import pytest

from cosim.errors import ScenarioError
from cosim.scenario import catalog_names, load_scenario

ROOT = Path(__file__).resolve().parents[2]


def write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "scene.yaml"
    path.write_text(text)
    return path


def test_every_catalog_scene_loads():
    names = catalog_names()
    assert "town05_crowded" in names
    for name in names:
        assert load_scenario(name).frames > 0


def test_unknown_key_names_the_file_and_the_key(tmp_path):
    path = write(tmp_path, "network: skeleton\ntraffic:\n  pedestrains: 3\n")
    with pytest.raises(ScenarioError, match=r"scene\.yaml: traffic\.pedestrains: unknown key"):
        load_scenario(str(path))


def test_wrong_type_names_the_key_and_the_expected_type(tmp_path):
    path = write(tmp_path, "network: skeleton\nframes: many\n")
    with pytest.raises(ScenarioError, match=r"scene\.yaml: frames: expected a whole number, got 'many'"):
        load_scenario(str(path))


@pytest.mark.parametrize(
    ("text", "key"),
    [
        ("frames: 0", "frames"),
        ("step_s: 0", "step_s"),
        ("step_s: -0.05", "step_s"),
        ("traffic:\n  vehicles_per_lane_km: -1", "traffic.vehicles_per_lane_km"),
        ("traffic:\n  mix: {tram: 1.0}", "traffic.mix.tram"),
        ("weather: snow", "weather"),
    ],
)
def test_out_of_range_values_are_rejected_with_their_key(tmp_path, text, key):
    path = write(tmp_path, f"network: skeleton\n{text}\n")
    with pytest.raises(ScenarioError, match=r"scene\.yaml: " + re.escape(key) + ": "):
        load_scenario(str(path))


def test_overrides_reach_nested_keys():
    scenario = load_scenario("town05_crowded", ["traffic.pedestrians=7", "frames=12", "weather=night"])
    assert (scenario.traffic.pedestrians, scenario.frames, scenario.weather) == (7, 12, "night")


def test_override_of_unknown_key_is_rejected():
    with pytest.raises(ScenarioError, match=r"traffic\.nope: unknown key"):
        load_scenario("town05_crowded", ["traffic.nope=1"])


def test_yaml_tags_for_python_objects_are_refused(tmp_path):
    path = write(tmp_path, "network: !!python/object/apply:os.system ['true']\n")
    with pytest.raises(ScenarioError, match="not valid YAML"):
        load_scenario(str(path))


def test_network_path_resolves_relative_to_the_scenario_file(tmp_path):
    (tmp_path / "maps").mkdir()
    (tmp_path / "maps" / "my.xodr").write_text("<OpenDRIVE/>")
    path = write(tmp_path, "network: maps/my.xodr\n")
    assert load_scenario(str(path)).network_path() == (tmp_path / "maps" / "my.xodr").resolve()


def test_missing_network_file_names_the_scenario_and_the_key(tmp_path):
    path = write(tmp_path, "network: maps/none.xodr\n")
    with pytest.raises(ScenarioError, match=r"scene\.yaml: network: OpenDRIVE file .*none\.xodr not found"):
        load_scenario(str(path))


def test_sensor_spec_errors_name_the_sensor_in_the_list(tmp_path):
    path = write(tmp_path, "network: skeleton\nsensors:\n  lidars:\n    - beams: 0\n")
    with pytest.raises(ScenarioError, match=r"scene\.yaml: sensors\.lidars\[0\]: .*beams must be 1\.\.512, got 0"):
        load_scenario(str(path))


def run_cli(*args: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "cosim", *args], capture_output=True, text=True, cwd=cwd, check=False)


def test_cli_unknown_scenario_prints_one_line_naming_the_known_ones(tmp_path):
    proc = run_cli("run", "no_such_scene", "--out", str(tmp_path / "o"), cwd=ROOT)
    assert proc.returncode != 0
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "no_such_scene" in lines[0] and "town05_crowded" in lines[0]
    assert not (tmp_path / "o").exists()


def test_cli_unknown_key_prints_one_line_and_writes_nothing(tmp_path):
    path = write(tmp_path, "network: skeleton\nsensorz: {}\n")
    proc = run_cli("run", str(path), "--out", str(tmp_path / "o"), cwd=ROOT)
    assert proc.returncode != 0
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"error: {path}: sensorz: unknown key")
    assert not (tmp_path / "o").exists()


def test_cli_list_shows_each_scene_with_a_description():
    proc = run_cli("list", cwd=ROOT)
    assert proc.returncode == 0
    assert any(line.startswith("town05_crowded") and "intersection" in line for line in proc.stdout.splitlines())


def test_cli_help_lists_the_subcommands():
    proc = run_cli("--help", cwd=ROOT)
    assert proc.returncode == 0 and "run" in proc.stdout and "list" in proc.stdout


def test_cli_live_view_on_a_bad_address_or_a_busy_port_is_one_line_and_no_dataset(tmp_path):
    from gtgen.sinks.live import LiveAddress, LiveSink

    proc = run_cli(
        "run", str(ROOT / "tests/data/tiny.yaml"), "--live", "host:port", "--out", str(tmp_path / "a"), cwd=ROOT
    )
    assert proc.returncode != 0
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "outputs.live: expected PORT, HOST:PORT or HOST" in lines[0]
    busy = LiveSink(LiveAddress("127.0.0.1", 0))
    try:
        out = tmp_path / "b"
        proc = run_cli("run", str(ROOT / "tests/data/tiny.yaml"), "--live", str(busy.port), "--out", str(out), cwd=ROOT)
    finally:
        busy.close()
    assert proc.returncode != 0
    errors = [line for line in proc.stderr.splitlines() if line.startswith("error:")]
    assert len(errors) == 1 and f"live view: cannot listen on 127.0.0.1:{busy.port}" in errors[0], proc.stderr
    assert not any(p.suffix in (".mcap", ".csv", ".json") for p in out.rglob("*")), sorted(out.rglob("*"))


def test_kitti_and_yolo_without_a_camera_say_what_to_change(tmp_path):
    path = write(tmp_path, "network: skeleton\nsensors: {cameras: []}\n")
    with pytest.raises(ScenarioError, match=r"outputs\.kitti: needs a rig with a camera and a LiDAR, this one has 0"):
        load_scenario(str(path))
    with pytest.raises(ScenarioError, match=r"outputs\.yolo: needs a rig with a camera.*set outputs\.yolo=false"):
        load_scenario(str(path), ["outputs.kitti=false"])


def test_the_kitti_rig_preset_is_kittis_car_and_stays_editable(tmp_path):
    from cosim.rigs import HDL64E_ELEVATIONS_DEG

    rig = load_scenario("town05_crowded", ["rig=kitti"]).sensors
    (lidar,) = rig.lidars
    assert lidar.elevations_deg == HDL64E_ELEVATIONS_DEG and len(lidar.elevations_deg) == 64
    assert lidar.elevations_deg[0] == -24.33 and lidar.elevations_deg[-1] == 2.0 and lidar.mount_xyz_m[2] == 1.73
    steps = sorted(b - a for a, b in zip(lidar.elevations_deg, lidar.elevations_deg[1:], strict=False))
    assert steps[0] == pytest.approx(1 / 3, abs=0.01) and steps[-1] == pytest.approx(0.5, abs=0.01)
    assert [(c.name, c.width_px, c.height_px) for c in rig.cameras] == [("cam2", 1242, 375), ("cam3", 1242, 375)]
    assert rig.cameras[0].pinhole.K[0, 0] == pytest.approx(721.5377, abs=0.01) and rig.radars == ()
    edited = load_scenario(
        str(write(tmp_path, "network: skeleton\nrig: kitti\nsensors: {radars: [{rate_hz: 10}]}\n"))
    ).sensors
    assert len(edited.radars) == 1 and edited.cameras == rig.cameras  # the rest of the preset stays
    with pytest.raises(ScenarioError, match=r"rig: expected one of 'default', 'kitti', 'nuscenes', got 'carla'"):
        load_scenario("town05_crowded", ["rig=carla"])


def test_a_lidar_with_explicit_beam_elevations_casts_them_and_checks_them():
    import numpy as np

    from sensors.errors import SensorConfigError
    from sensors.lidar import LidarSpec

    spec = LidarSpec(beams=3, elevations_deg=(-10.0, -2.0, 1.0), azimuth_steps=8)
    dirs, ring = spec.directions()
    np.testing.assert_allclose(np.degrees(np.arcsin(dirs[ring == 1, 2])), -2.0)
    with pytest.raises(SensorConfigError, match="elevations_deg"):
        LidarSpec(beams=3, elevations_deg=(1.0, -2.0, 3.0))
