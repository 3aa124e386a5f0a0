"""Faults from outside a run: its process or its writer killed, Ctrl-C or SIGTERM at any stage,
a disk that fills up, a sweep stopped. Every frame written stays, ``--resume`` continues to the
data of a run never stopped, and no helper process outlives the run."""

import contextlib
import csv
import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from cosim.resume import kept_frames
from cosim.scenario import load_scenario
from gtgen.compare import compare_datasets
from gtgen.sinks.resume_sink import wait_for_writer

pytestmark = pytest.mark.slow
DATA = Path(__file__).resolve().parents[1] / "data"
TINY = str(DATA / "tiny.yaml")
FRAMES = 40
# The camera's look is not under test here: a small flat-shaded camera (every output still written).
LIGHT_CAMERA = ["--set", "sensors.cameras=[{name: camera, shading: flat, width_px: 320, height_px: 180}]"]
PARTIALS = ["kitti.partial", "labels.csv.partial", "lights_and_signs.csv.partial", "map.partial",
            "run.mcap.partial", "yolo.partial"]  # fmt: skip


def command(out: Path, *extra: str, frames: int = FRAMES, progress: bool = False) -> list[str]:
    quiet = [] if progress else ["--no-progress"]
    return [sys.executable, "-m", "cosim", "run", TINY, "--frames", str(frames), "--out", str(out), *quiet,
            *LIGHT_CAMERA, *extra]  # fmt: skip


def start(out: Path, *extra: str, frames: int = FRAMES) -> subprocess.Popen[str]:
    return subprocess.Popen(
        command(out, *extra, frames=frames), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )


def wait_for_frames(proc: subprocess.Popen[str], out: Path, frames: int) -> None:
    """Until ``frames`` frames are on disk in every output (or the run has ended)."""
    states = out / ".resume" / "states.jsonl"
    deadline = time.monotonic() + 240
    while proc.poll() is None and time.monotonic() < deadline:
        if states.exists() and states.read_text().count("\n") >= frames:
            return
        time.sleep(0.02)
    raise AssertionError(f"{frames} frames were not written: {proc.poll()}")


def children(pid: int, word: str) -> list[int]:
    """The processes whose parent is ``pid`` and whose command line holds ``word``."""
    found = []
    for entry in Path("/proc").iterdir():
        try:
            stat = (entry / "stat").read_text()
            cmdline = (entry / "cmdline").read_bytes().decode(errors="replace")
        except (OSError, ValueError):
            continue
        if entry.name.isdigit() and int(stat.rsplit(")", 1)[1].split()[1]) == pid and word in cmdline:
            found.append(int(entry.name))
    return found


def alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"


def resume(out: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(command(out, "--resume"), capture_output=True, text=True, timeout=300, check=False)


def kept(out: Path) -> int:
    assert wait_for_writer(out, 60)  # a writer left behind by a killed run keeps its files first
    return kept_frames(out, load_scenario(TINY, [f"frames={FRAMES}"]))


@pytest.fixture(scope="module")
def whole(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The dataset of a run never stopped."""
    out = tmp_path_factory.mktemp("whole") / "out"
    subprocess.run(command(out), check=True, capture_output=True, timeout=300)
    return out


def assert_same(whole: Path, resumed: Path) -> None:
    result = compare_datasets(whole, resumed)
    assert result.same, result.differences[:5]
    assert json.loads((resumed / "manifest.json").read_text())["complete"] is True
    assert not (resumed / ".resume").exists() and not list(resumed.glob("*.partial"))


def test_kill_9_of_the_run_keeps_every_frame_under_partial_names_and_resume_continues(tmp_path, whole):
    """Its writer keeps the files whether it notices the run's death while waiting for a frame
    or while answering (a broken pipe: it deleted them, 4 times in 6, and --resume started
    again at frame 0)."""
    out = tmp_path / "out"
    proc = start(out)
    wait_for_frames(proc, out, 10)
    proc.kill()
    proc.communicate(timeout=60)
    assert kept(out) >= 10
    assert sorted(p.name for p in out.iterdir()) == [".resume", *PARTIALS]
    resumed = resume(out)
    assert resumed.returncode == 0, resumed.stderr
    assert_same(whole, out)


def test_kill_9_of_the_writer_keeps_every_frame_it_wrote_and_resume_continues(tmp_path, whole):
    """It said "no dataset was completed" and emptied the folder, .resume/ included."""
    out = tmp_path / "out"
    proc = start(out)
    wait_for_frames(proc, out, 10)
    (writer,) = children(proc.pid, "gtgen.sinks.background:serve")
    os.kill(writer, signal.SIGKILL)
    _, err = proc.communicate(timeout=120)
    frames = kept(out)
    assert proc.returncode == 2 and frames >= 8
    assert err.strip().splitlines() == [
        f"error: writer process stopped unexpectedly (exit code -9); {out} keeps frames 0 to {frames - 1} under the "
        "files' .partial names; run the same command with --resume to continue"
    ]
    assert sorted(p.name for p in out.iterdir()) == [".resume", *PARTIALS]
    resumed = resume(out)
    assert resumed.returncode == 0, resumed.stderr
    assert_same(whole, out)


def test_ctrl_c_while_the_summary_is_written_leaves_an_incomplete_dataset_that_resume_finishes(tmp_path, whole):
    """The manifest said "complete": true with 4 of summary/'s 14 files, and --resume said complete."""
    out = tmp_path / "out"
    proc = start(out)
    while proc.poll() is None and not (out / "summary.partial").exists():
        time.sleep(0.005)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 130
    assert err.strip().splitlines()[-1] == (
        f"interrupted while writing summary/; {out} holds all {FRAMES} frames and no summary (manifest.json: "
        '"complete": false); run the same command with --resume to finish it'
    )
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["complete"] is False and manifest["frames"] == FRAMES
    assert not (out / "summary").exists() and not (out / "summary.partial").exists()
    resumed = resume(out)
    assert resumed.returncode == 0, resumed.stderr
    assert len(list((out / "summary").iterdir())) == len(list((whole / "summary").iterdir()))
    assert_same(whole, out)


@pytest.mark.parametrize(
    ("signals", "code", "line"),
    [
        ((signal.SIGINT, signal.SIGINT), 130, "interrupted; no dataset was completed"),
        ((signal.SIGTERM,), 143, "stopped (SIGTERM); no dataset was completed"),
    ],
)
def test_a_signal_during_a_long_warm_up_ends_the_run_and_its_traffic_process_at_once(tmp_path, signals, code, line):
    """The run waited 30 s for the traffic process to finish its warm-up; a second Ctrl-C left
    that process warming up at full CPU with nobody to tell."""
    out = tmp_path / "out"
    proc = subprocess.Popen(command(out, "--set", "warmup_s=100000", progress=True), stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)  # fmt: skip
    assert proc.stderr is not None
    while "warming up the traffic" not in proc.stderr.readline():
        assert proc.poll() is None
    deadline = time.monotonic() + 60
    while not children(proc.pid, "cosim.traffic_feed:serve") and time.monotonic() < deadline:
        time.sleep(0.05)
    (traffic,) = children(proc.pid, "cosim.traffic_feed:serve")
    time.sleep(1.0)  # well into the warm-up
    for sig in signals:
        proc.send_signal(sig)
        time.sleep(0.2)
    _, err = proc.communicate(timeout=15)  # it took over 30 s
    assert proc.returncode == code and err.strip().splitlines()[-1] == line
    assert not alive(traffic)
    assert list(out.iterdir()) == []


@contextlib.contextmanager
def small_disk(folder: Path, size: str) -> Iterator[Path]:
    """A file system of ``size`` mounted at ``folder`` (needs the right to mount)."""
    folder.mkdir()
    mounted = subprocess.run(
        ["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(folder)], capture_output=True, check=False
    )
    if mounted.returncode != 0:
        pytest.skip("mounting a small file system needs root")
    try:
        yield folder
    finally:
        subprocess.run(["umount", "-l", str(folder)], check=False)


def fill(disk: Path) -> Path:
    """Fill ``disk`` with one file, as another program would."""
    filler = disk / "filler"
    with filler.open("wb") as f, contextlib.suppress(OSError):
        while True:
            f.write(b"\0" * (1 << 20))
            f.flush()
    return filler


def test_a_disk_that_fills_up_keeps_every_frame_written_and_a_resume_out_of_space_deletes_none(tmp_path, whole):
    """Filled by another program after the size check (frame 20): all frames and .resume/ went.
    A --resume that ran out of space deleted the frames the first run kept."""
    with small_disk(tmp_path / "disk", "200m") as disk:
        out = disk / "out"
        proc = start(out)
        wait_for_frames(proc, out, 22)
        filler = fill(disk)
        _, err = proc.communicate(timeout=120)
        frames = kept(out)
        assert proc.returncode == 2 and frames >= 20
        (line,) = err.strip().splitlines()
        assert "cannot write: No space left on device; " in line and line.endswith(
            f"{out} keeps frames 0 to {frames - 1} under the files' .partial names; free some space, then run the "
            "same command with --resume to continue"
        )
        assert sorted(p.name for p in out.iterdir()) == [".resume", *PARTIALS]
        again = resume(out)  # the disk is still full
        assert again.returncode == 2 and "No space left on device" in again.stderr
        assert kept(out) == frames
        filler.unlink()
        resumed = resume(out)
        assert resumed.returncode == 0, resumed.stderr
        assert_same(whole, out)


def sweep(out: Path, *extra: str) -> subprocess.Popen[str]:
    cmd = [sys.executable, "-m", "cosim", "sweep", TINY, "--out", str(out), "--workers", "1", *LIGHT_CAMERA, *extra]
    return subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def test_sigterm_to_a_sweep_stops_its_run_keeping_its_frames_and_writes_sweep_csv(tmp_path):
    """The run went on to its end, the sweep exited 27 s later with a BrokenPipeError traceback
    and said "no dataset was completed", and wrote no sweep.csv."""
    root = tmp_path / "sweep"
    proc = sweep(root, "--seed", "0", "1", "--frames", "2000")
    run = root / "tiny-s0"
    wait_for_frames(proc, run, 5)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 143 and "Traceback" not in err
    assert err.strip().splitlines()[-1] == (
        f"stopped (SIGTERM); {root}/sweep.csv lists the 1 run that ended (0 complete, 1 stopped part-way keeping the "
        "frames they wrote, 0 failed); start the same sweep again to continue"
    )
    with (root / "sweep.csv").open() as f:
        (row,) = list(csv.DictReader(f))
    manifest = json.loads((run / "manifest.json").read_text())
    assert manifest["complete"] is False and 5 <= manifest["frames"] < 2000
    assert row["name"] == "tiny-s0" and int(row["frames"]) == manifest["frames"]
    assert row["error"].startswith("stopped (SIGTERM) at frame")
    assert not (root / "tiny-s1").exists()
