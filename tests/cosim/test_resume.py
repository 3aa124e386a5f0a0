"""Runs that survive: a run stopped by Ctrl-C, SIGTERM or kill -9 keeps its frames, and
``--resume`` continues it to the same data as a run never stopped."""

import dataclasses
import json
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from mcap.reader import make_reader

from cosim.errors import CosimError
from cosim.resume import AlreadyCompleteError, begin, resume_point
from cosim.scenario import load_scenario
from gtgen.load import load_labels

DATA = Path(__file__).resolve().parents[1] / "data"
TINY = str(DATA / "tiny.yaml")


def start(out: Path, frames: int, *extra: str) -> subprocess.Popen[str]:
    light_camera = "sensors.cameras=[{name: camera, shading: flat, width_px: 320, height_px: 180}]"  # look not tested
    cmd = [sys.executable, "-m", "cosim", "run", TINY, "--frames", str(frames), "--out", str(out), "--no-progress",
           "--set", light_camera, *extra]  # fmt: skip
    return subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def stop_after(proc: subprocess.Popen[str], out: Path, frames: int, sig: int) -> tuple[float, str]:
    """Send ``sig`` once ``frames`` frames are on disk; the seconds until it exits, and its stderr."""
    states = out / ".resume" / "states.jsonl"
    deadline = time.monotonic() + 240
    while proc.poll() is None and time.monotonic() < deadline:
        if states.exists() and states.read_text().count("\n") >= frames:
            break
        time.sleep(0.05)
    sent = time.monotonic()
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=120)
    return time.monotonic() - sent, err


@pytest.mark.slow
@pytest.mark.parametrize(
    ("sig", "code", "word"), [(signal.SIGINT, 130, "interrupted"), (signal.SIGTERM, 143, "stopped")]
)
def test_a_stopped_run_keeps_every_frame_it_wrote_in_every_output(tmp_path, sig, code, word):
    out = tmp_path / "out"
    proc = start(out, 2000)
    seconds, err = stop_after(proc, out, 25, sig)
    # it stops at the next frame (25 kept on an idle machine, in about 3 s with the summary);
    # the time is only a guard against a hang, far above what a loaded machine takes (11 s)
    assert proc.returncode == code and seconds < 60
    line = err.strip().splitlines()[-1]
    manifest = json.loads((out / "manifest.json").read_text())
    kept = manifest["frames"]
    assert manifest["complete"] is False and 25 <= kept <= 30
    assert line.startswith(f"{word}") and f"keeps frames 0 to {kept - 1}" in line and "--resume" in line
    with (out / "run.mcap").open("rb") as stream:  # closed properly: the seeking reader reads its summary
        times = {m.log_time for _, _, m in make_reader(stream).iter_messages(topics=["/gt/labels"])}
    assert len(times) == kept
    assert load_labels(out / "labels.csv")["frame"].nunique() == kept
    for folder, ext in (("kitti/label_2", "txt"), ("kitti/velodyne", "bin"), ("yolo/images", "jpg")):
        assert len(list((out / folder).glob(f"*.{ext}"))) == kept, folder
    assert (out / "summary" / "stats.csv").exists()
    assert not list(out.glob("*.partial"))


def complete_manifest(out: Path, scenario) -> None:
    """The manifest of a complete dataset of ``scenario`` (as ``write_manifest`` records it)."""
    data = dataclasses.asdict(scenario)
    data.pop("source_dir")
    out.mkdir(parents=True, exist_ok=True)
    manifest = {"scenario": data, "complete": True, "frames": scenario.frames}
    (out / "manifest.json").write_text(json.dumps(manifest, default=str))


def test_resuming_a_complete_dataset_or_another_scenario_says_so(tmp_path):
    scenario = load_scenario(TINY)
    complete_manifest(tmp_path, scenario)
    with pytest.raises(AlreadyCompleteError, match="complete already"):
        resume_point(tmp_path, scenario)
    (tmp_path / "manifest.json").unlink()
    begin(tmp_path, scenario)
    other = load_scenario(TINY, ["seed=9", "traffic.pedestrians=3"])
    with pytest.raises(CosimError, match=r"another scenario \(seed, traffic.pedestrians differ\)"):
        resume_point(tmp_path, other)
    assert resume_point(tmp_path, load_scenario(TINY, ["frames=50"])) is None  # nothing kept yet: start afresh
    with pytest.raises(CosimError, match="no interrupted run to continue here"):
        resume_point(tmp_path / "empty", scenario)


def test_resume_with_another_scenario_on_a_complete_dataset_is_one_line_and_exit_code_2(tmp_path):
    """It said "complete already" with exit code 0, and not that the scenario differs."""
    out = tmp_path / "out"
    complete_manifest(out, load_scenario(TINY))
    before = (out / "manifest.json").read_text()
    proc = subprocess.run([sys.executable, "-m", "cosim", "run", TINY, "--seed", "9", "--out", str(out), "--resume"],
                          capture_output=True, text=True, check=False)  # fmt: skip
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert lines == [
        f"error: {out}: the complete dataset there was made from another scenario (seed differ); "
        "give its scenario and overrides, or another --out"
    ]
    assert proc.stdout == "" and (out / "manifest.json").read_text() == before


@pytest.mark.slow
def test_a_busy_live_port_stops_the_run_before_an_earlier_dataset_is_touched(tmp_path):
    import socket

    from cosim.loop import run
    from gtgen.errors import SinkError

    (tmp_path / "manifest.json").write_text('{"complete": true, "frames": 3}\n')
    (tmp_path / "labels.csv").write_text("frame\n0\n")
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        port = busy.getsockname()[1]
        with pytest.raises(SinkError, match=f"live view: cannot listen on 127.0.0.1:{port}"):
            run(load_scenario(TINY, ["frames=3", f"outputs.live={port}"]), tmp_path, progress=False)
    assert (tmp_path / "manifest.json").read_text() == '{"complete": true, "frames": 3}\n'
    assert (tmp_path / "labels.csv").read_text() == "frame\n0\n"
    assert not list(tmp_path.glob("*.partial"))


def test_an_interrupt_during_a_frames_handoff_takes_effect_after_it():
    """The signal is raised in this thread and its Python handler has run before
    ``raise_signal`` returns (``os.kill`` to the process may land in another thread, whose
    handler can run after the block, under load after a fixed sleep too)."""
    from cosim.interrupts import interrupts_after

    done = []
    with pytest.raises(KeyboardInterrupt), interrupts_after():
        signal.raise_signal(signal.SIGINT)  # arrives while the frame is being handed over
        done.append("counted and handed over")
    assert done == ["counted and handed over"]
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


def test_an_interrupt_behind_an_error_of_compiled_code_is_the_interrupt():
    from cosim.errors import Terminated
    from cosim.interrupts import interrupt_behind

    def wrapped(inner: BaseException, how: str) -> SystemError:
        err = SystemError("<numba function> returned a result with an exception set")
        setattr(err, how, inner)
        return err

    ctrl_c, term = KeyboardInterrupt(), Terminated()
    assert interrupt_behind(ctrl_c) is ctrl_c and interrupt_behind(term) is term
    assert interrupt_behind(wrapped(ctrl_c, "__cause__")) is ctrl_c
    assert interrupt_behind(wrapped(wrapped(term, "__context__"), "__cause__")) is term
    assert interrupt_behind(SystemError("a real fault")) is None
    assert interrupt_behind(wrapped(ValueError("x"), "__cause__")) is None
    value = ValueError("not a compiled call's error")
    value.__context__ = ctrl_c
    assert interrupt_behind(value) is None


def test_ctrl_c_inside_compiled_code_keeps_the_frames_written_and_resume_finishes(tmp_path, monkeypatch):
    """Ctrl-C while a Numba kernel or a ray caster runs can come out of it as a SystemError
    caused by the KeyboardInterrupt: the run still stops keeping its frames, not as a crash
    that removes them."""
    import cosim.loop
    from cosim.errors import RunStoppedError

    light = "sensors.cameras=[{name: camera, shading: flat, width_px: 320, height_px: 180}]"
    scenario = load_scenario(TINY, ["frames=8", light])
    real = cosim.loop.sense_and_label

    def cut_at_frame_5(frame_index, *args, **kwargs):
        if frame_index == 5:
            raise SystemError("<numba function> returned a result with an exception set") from KeyboardInterrupt()
        return real(frame_index, *args, **kwargs)

    out = tmp_path / "out"
    monkeypatch.setattr(cosim.loop, "sense_and_label", cut_at_frame_5)
    with pytest.raises(RunStoppedError) as stopped:
        cosim.loop.run(scenario, out, progress=False, one_process=True)
    assert stopped.value.exit_code == 130 and stopped.value.kept == 5
    assert str(stopped.value).startswith("interrupted at frame 5")
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["complete"] is False and manifest["frames"] == 5
    monkeypatch.setattr(cosim.loop, "sense_and_label", real)
    cosim.loop.run(scenario, out, progress=False, one_process=True, resume=True)
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["complete"] is True and manifest["frames"] == 8
