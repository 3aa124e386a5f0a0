import json
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from cosim.errors import ScenarioError
from cosim.scenario import catalog_names, load_scenario
from networks.vocabulary import HazardKind

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


def test_a_hazard_kind_is_read_into_the_vocabulary_and_a_bad_one_names_the_kinds(tmp_path):
    good = write(tmp_path, "network: skeleton\nhazards: [{kind: cut_in}]\n")
    assert load_scenario(str(good)).hazards[0].kind is HazardKind.CUT_IN
    bad = write(tmp_path, "network: skeleton\nhazards: [{kind: cut-in}]\n")
    expected = "expected one of 'cut_in', 'hard_brake', 'jaywalker', 'red_light', got 'cut-in'"
    with pytest.raises(ScenarioError, match=r"scene\.yaml: hazards\[0\]\.kind: " + re.escape(expected)):
        load_scenario(str(bad))


def test_cli_bad_hazard_kind_prints_one_line_and_writes_nothing(tmp_path):
    path = write(tmp_path, "network: skeleton\nhazards: [{kind: [cut_in]}]\n")
    proc = run_cli("run", str(path), "--out", str(tmp_path / "o"), cwd=ROOT)
    lines = proc.stderr.strip().splitlines()
    assert proc.returncode != 0 and len(lines) == 1 and "hazards[0].kind: expected one of 'cut_in'" in lines[0]
    assert not (tmp_path / "o").exists()


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


def test_a_distorting_lens_keeps_kitti_and_nuscenes_out_and_yolo_in(tmp_path):
    lens = "sensors: {cameras: [{name: front, distortion: [-0.1, 0.01, 0.0, 0.0, 0.0]}]}\n"
    path = write(tmp_path, "network: skeleton\n" + lens)
    kitti = r"outputs\.kitti: its images are undistorted .* camera front has a lens distortion; set its distortion "
    with pytest.raises(ScenarioError, match=kitti + r"to zeros or outputs\.kitti=false"):
        load_scenario(str(path))
    with pytest.raises(ScenarioError, match=r"outputs\.nuscenes: .* camera front has a lens distortion"):
        load_scenario(str(path), ["outputs.kitti=false", "outputs.nuscenes=true"])
    scenario = load_scenario(str(path), ["outputs.kitti=false"])
    assert scenario.outputs.yolo and scenario.sensors.cameras[0].pinhole.distorted
    folds = (
        r"camera front: distortion \[0\.0, -2\.0, .* cannot be used over a 1280x720 image with hfov_deg 85: it folds"
    )
    with pytest.raises(ScenarioError, match=folds):
        load_scenario(
            str(path), ["outputs.kitti=false", "sensors.cameras=[{name: front, distortion: [0, -2, 0, 0, 0]}]"]
        )


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


def test_the_nuscenes_preset_is_the_nuscenes_car_with_its_rates_and_its_export():
    import numpy as np

    from cosim.rigs import HDL32E_ELEVATIONS_DEG

    s = load_scenario("town05_crowded", ["rig=nuscenes"])
    rig = s.sensors
    assert [c.name for c in rig.cameras] == ["CAM_FRONT", "CAM_FRONT_RIGHT", "CAM_BACK_RIGHT", "CAM_BACK",
                                             "CAM_BACK_LEFT", "CAM_FRONT_LEFT"]  # fmt: skip
    assert all((c.width_px, c.height_px, c.rate_hz) == (1600, 900, 12.0) for c in rig.cameras)
    # published focal lengths (n015): CAM_FRONT 1266.417 px, CAM_BACK 809.221 px
    assert rig.cameras[0].pinhole.K[0, 0] == pytest.approx(1266.417, abs=0.01)
    assert rig.cameras[3].pinhole.K[0, 0] == pytest.approx(809.221, abs=0.01)
    # CAM_FRONT looks ahead, CAM_BACK behind: their optical axes in the ego frame
    assert rig.cameras[0].ego_SE3_sensor.rotation[:, 2] @ [1, 0, 0] > 0.99
    assert rig.cameras[3].ego_SE3_sensor.rotation[:, 2] @ [-1, 0, 0] > 0.99
    (lidar,) = rig.lidars
    assert (lidar.name, lidar.beams, lidar.rate_hz) == ("LIDAR_TOP", 32, 20.0)
    assert lidar.elevations_deg == HDL32E_ELEVATIONS_DEG and (HDL32E_ELEVATIONS_DEG[0], HDL32E_ELEVATIONS_DEG[-1]) == (
        -30.67,
        10.67,
    )
    assert np.allclose(np.diff(HDL32E_ELEVATIONS_DEG), 4 / 3, atol=0.011)
    # nuScenes's LiDAR axes: x right, y forward
    assert lidar.ego_SE3_sensor.rotation[:, 1] @ [1, 0, 0] > 0.99
    assert [r.name for r in rig.radars] == ["RADAR_FRONT", "RADAR_FRONT_LEFT", "RADAR_FRONT_RIGHT",
                                            "RADAR_BACK_LEFT", "RADAR_BACK_RIGHT"]  # fmt: skip
    assert all(r.rate_hz == 13.0 for r in rig.radars) and rig.radars[0].mount_xyz_m[0] == pytest.approx(2.0)
    assert s.outputs.nuscenes and not s.outputs.kitti and s.step_s == 0.05
    edited = load_scenario("town05_crowded", ["rig=nuscenes", "outputs.kitti=false", "outputs.nuscenes=false"])
    assert not edited.outputs.nuscenes  # the scenario's own keys win over the preset's


def test_a_preset_sensor_is_edited_key_by_key_by_naming_it(tmp_path):
    text = "network: skeleton\nrig: nuscenes\nsensors: {radars: [{name: RADAR_FRONT, points_per_frame: 60}]}\n"
    rig = load_scenario(str(write(tmp_path, text))).sensors
    assert len(rig.radars) == 5 and rig.radars[0].points_per_frame == 60 and rig.radars[0].rate_hz == 13.0


def test_a_sensor_fires_at_its_own_rate_on_the_frame_clock():
    from sensors.sensor import fires

    def count(rate_hz: float, step_s: float, frames: int) -> int:
        return sum(fires(rate_hz, step_s, k) for k in range(frames))

    assert count(20.0, 0.05, 200) == 200 and count(12.0, 0.05, 200) == 120 and count(13.0, 0.05, 200) == 130
    assert count(10.0, 0.05, 200) == 100 and [k for k in range(6) if fires(10.0, 0.05, k)] == [0, 2, 4]
    assert all(fires(12.0, 0.05, k) for k in range(0, 200, 10))  # cameras fire at every 0.5 s keyframe
    assert count(20.0, 0.1, 50) == 50  # faster than the frames: every frame (the run says so)


def test_a_sensor_faster_than_the_frames_is_named_in_a_notice():
    from cosim.rig import rate_notices
    from sensors.camera import Camera, CameraSpec
    from sensors.lidar import Lidar, LidarSpec

    lines = rate_notices([Lidar(LidarSpec(rate_hz=20.0)), Camera(CameraSpec(rate_hz=10.0))], 0.1)
    assert lines == [
        "notice: sensors: lidar is set to 20 Hz, above the frame rate (10 Hz, step_s 0.1): it fires every frame"
    ]


@pytest.mark.parametrize(
    ("sets", "message"),
    [
        (["rig=nuscenes", "sensors.lidars=[]"], "outputs.nuscenes: needs a LiDAR"),
        (["rig=nuscenes", "step_s=0.04"], "outputs.nuscenes: keyframes come every 0.5 s"),
        (
            ["rig=nuscenes", "sensors.cameras=[{name: CAM_FRONT, width_px: 1280, height_px: 720}]"],
            "sensors: CAM_FRONT: 1280x720 px, 64.5615 deg conflicts with the nuscenes preset's CAM_FRONT",
        ),
        (["sensors.cameras=[{rate_hz: 10}]"], "outputs.kitti: KITTI pairs each image with a LiDAR sweep"),
        (["rig=pandaset"], "rig: expected one of 'default', 'kitti', 'nuscenes', got 'pandaset'"),
    ],
)
def test_a_rig_or_export_that_cannot_work_is_one_line_and_writes_nothing(tmp_path, sets, message):
    args = [a for s in sets for a in ("--set", s)]
    proc = run_cli("run", str(ROOT / "tests" / "data" / "tiny.yaml"), "--out", str(tmp_path / "o"), *args, cwd=ROOT)
    assert proc.returncode != 0
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and message in lines[0], lines
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--seed", "2147483648"], "seed: expected a whole number in [0, 2147483647] (SUMO's seeds), got 2147483648"),
        (["--set", "step_s=1.0e-9"], "step_s: expected seconds in [0.001, 1], a whole number of milliseconds"),
        (["--set", "step_s=0.0125"], "step_s: expected seconds in [0.001, 1], a whole number of milliseconds"),
        (["--set", "warmup_s=.inf"], "warmup_s: expected a finite number, got inf"),
        (["--set", "warmup_s=.nan"], "warmup_s: expected a finite number, got nan"),
        (["--set", "traffic.vehicles_per_lane_km=.inf"], "traffic.vehicles_per_lane_km: expected a finite number"),
    ],
)
def test_values_sumo_or_the_clock_cannot_take_are_one_scenario_line_with_exit_code_2(tmp_path, args, message):
    """They reached SUMO ("SUMO could not load the network") or failed inside the run."""
    tiny = ROOT / "tests" / "data" / "tiny.yaml"
    proc = run_cli("run", str(tiny), "--out", str(tmp_path / "o"), *args, cwd=ROOT)
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"error: {tiny}: {message}"), lines
    assert not (tmp_path / "o").exists()


def test_an_error_line_quotes_a_long_value_in_a_few_hundred_characters(tmp_path):
    long = "x" * 1_000_000
    path = write(tmp_path, f"network: skeleton\nweather: &w {long}\n")
    with pytest.raises(ScenarioError) as err:
        load_scenario(str(path))
    assert str(err.value).startswith(f"{path}: weather: expected one of 'day'") and len(str(err.value)) < 600
    with pytest.raises(ScenarioError) as err:
        load_scenario(str(path), [f"frames={long}"])
    assert "frames: expected a whole number, got 'xxx" in str(err.value) and len(str(err.value)) < 600


@pytest.mark.slow
def test_yaml_aliases_in_the_ego_route_give_an_error_line_of_a_few_hundred_characters(tmp_path):
    """10,000 aliases of a 4,000-character edge id (a 40 KB file) printed a 100 MB line."""
    aliases = ", ".join(["*e"] * 10_000)
    path = write(tmp_path, f"network: skeleton\nframes: 1\nwarmup_s: 0\nego:\n  route: [&e {'e' * 4000}, {aliases}]\n")
    assert path.stat().st_size < 50_000
    proc = run_cli("run", str(path), "--out", str(tmp_path / "o"), "--no-progress", cwd=ROOT)
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ego.route: SUMO refused the ego's route ['eee"), lines
    assert len(lines[0]) < 2_000


@pytest.mark.skipif(shutil.which("make") is None, reason="needs make")
def test_make_scenario_passes_the_name_and_the_folder_as_they_are_never_to_the_shell(tmp_path):
    """The name went to the shell unquoted: backticks ran a command, > made a file, ( and ' failed."""
    for name in ("Makefile", "pyproject.toml", "constraints.txt"):
        shutil.copy(ROOT / name, tmp_path / name)
    python = tmp_path / ".venv" / "bin" / "python"  # stands in for the installed one: records its arguments
    python.parent.mkdir(parents=True)
    record = "with open('argv.jsonl', 'a') as f:\n    f.write(json.dumps(sys.argv[1:]) + '\\n')\n"
    python.write_text(f"#!{sys.executable}\nimport json, sys\n{record}")
    python.chmod(0o755)
    (tmp_path / ".venv" / ".installed").touch()
    names = ["a`date>made`b", "a>made", "a(b", "a'b", 'it\'s(a)"test"', "a;date>made", "a$(date>made)"]
    for name in names:
        proc = subprocess.run(["make", "-s", "scenario", name, "OUT=out dir", "FRAMES=5"], cwd=tmp_path,
                              capture_output=True, text=True, check=False)  # fmt: skip
        assert proc.returncode == 0, proc.stderr
    calls = [json.loads(line) for line in (tmp_path / "argv.jsonl").read_text().splitlines()]
    assert calls == [["-m", "cosim", "run", name, "--frames", "5", "--out", "out dir"] for name in names]
    assert sorted(p.name for p in tmp_path.iterdir() if p.is_file()) == [
        "Makefile", "argv.jsonl", "constraints.txt", "pyproject.toml"]  # fmt: skip
