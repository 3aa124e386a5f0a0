"""The writer process: the same files as the sinks in this process, one-line errors, no
complete-looking file after a failure."""

import multiprocessing
import os
import pickle
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
from mcap.reader import make_reader

import gtgen.sinks.background as background_module
import gtgen.sinks.images as images_module
from gtgen.channel import Inband, Ready, Start
from gtgen.errors import OutputKeptError, SinkError
from gtgen.sinks.background import BackgroundSinks, serve
from gtgen.sinks.csv_sink import rows_of_frames
from gtgen.sinks.group import SinkChoice, SinkGroup
from gtgen.sinks.mcap_sink import complete_frames
from gtgen.sinks.resume_sink import read_states
from gtgen.timing import StageTimes

OUTPUTS = ("run.mcap", "foxglove_layout.json", "labels.csv", "kitti", "yolo")


def files(folder: Path) -> dict[str, bytes]:
    """Every file under ``folder`` by relative path (YOLO's data.yaml names its own folder)."""
    out = {}
    for path in sorted(folder.rglob("*")):
        if path.is_file() and path.name != "data.yaml":
            out[str(path.relative_to(folder))] = path.read_bytes()
    return out


def leftovers(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir() if p.name in OUTPUTS or p.name.endswith(".partial"))


def test_writer_process_writes_the_same_bytes_as_the_sinks_in_this_process(records, tmp_path):
    inline, background = tmp_path / "inline", tmp_path / "background"
    inline.mkdir()
    background.mkdir()
    group = SinkGroup.open(SinkChoice(inline))
    writer = BackgroundSinks(SinkChoice(background), depth=2)
    for record in records:
        group.write(record)
        writer.write(record)
    group.close()
    writer.close()
    assert sorted(p.name for p in background.iterdir()) == sorted(OUTPUTS)
    expected = files(inline)
    assert len(expected) > 10
    assert files(background) == expected


def test_frames_shaded_while_the_writer_is_behind_give_the_same_bytes(records, tmp_path, monkeypatch):
    inline, background = tmp_path / "inline", tmp_path / "background"
    inline.mkdir()
    background.mkdir()
    ahead: list[int] = []

    def shaded(record):
        ahead.append(record.frame_index)
        return images_module.shaded(record)

    monkeypatch.setattr(background_module, "shaded", shaded)
    group = SinkGroup.open(SinkChoice(inline))
    writer = BackgroundSinks(SinkChoice(background), depth=1)
    monkeypatch.setattr(writer, "_drain", lambda: None)  # its slot freed only when waited for: always behind
    for record in records:
        group.write(record)
        writer.write(record)
    group.close()
    writer.close()
    assert ahead == [r.frame_index for r in records[1:]]  # the first frame finds its slot free
    assert files(background) == files(inline)


def test_a_frame_larger_than_the_shared_memory_slots_still_arrives(record_maker, tmp_path):
    small, large = record_maker(0, lidar_azimuth_steps=64), record_maker(1, lidar_azimuth_steps=8192)
    for folder in ("inline", "background"):
        (tmp_path / folder).mkdir()
    group, writer = (
        SinkGroup.open(SinkChoice(tmp_path / "inline")),
        BackgroundSinks(SinkChoice(tmp_path / "background")),
    )
    for record in (small, large, small):
        group.write(record)
        writer.write(record)
    group.close()
    writer.close()
    assert files(tmp_path / "background") == files(tmp_path / "inline")


def test_an_error_in_the_writer_process_comes_back_as_one_line_and_leaves_no_output(record_maker, tmp_path):
    writer = BackgroundSinks(SinkChoice(tmp_path), depth=1)
    writer.write(record_maker(0))
    with pytest.raises(SinkError) as err:
        for i in range(1, 20):  # KITTI needs a camera: the child fails on the first such frame
            writer.write(record_maker(i, cameras=False))
        writer.close()
    writer.abort()
    message = str(err.value)
    assert message == "the KITTI layout needs at least one camera and one LiDAR in the rig"
    assert leftovers(tmp_path) == []


def written_frames(folder: Path) -> int:
    return len(read_states(folder))


def test_a_killed_writer_process_is_reported_and_keeps_every_frame_it_wrote(records, tmp_path):
    """It said "no dataset was completed" and emptied the folder, .resume/ included."""
    writer = BackgroundSinks(SinkChoice(tmp_path, resume=True))
    for record in records[:2]:
        writer.write(record)
    deadline = time.monotonic() + 30
    while written_frames(tmp_path) < 2 and time.monotonic() < deadline:
        time.sleep(0.02)
    os.kill(writer.pid, signal.SIGKILL)
    with pytest.raises(OutputKeptError, match=r"^writer process stopped unexpectedly \(exit code -9\)$") as err:
        for record in records * 5:
            writer.write(record)
        writer.close()
    assert not err.value.disk_full
    writer.keep()  # what the ``with`` block does with this error
    assert leftovers(tmp_path) == ["kitti.partial", "labels.csv.partial", "run.mcap.partial", "yolo.partial"]
    assert written_frames(tmp_path) == 2
    assert rows_of_frames((tmp_path / "labels.csv.partial").read_text(), 2)[0].count("\n") > 2
    labels = tmp_path / "kitti.partial" / "training" / "label_2"
    assert sorted(p.name for p in labels.iterdir()) == ["000000.txt", "000001.txt"]


def test_a_writer_whose_parent_dies_while_it_answers_keeps_the_frames_it_wrote(records, tmp_path):
    """The parent killed while the writer acknowledges a frame (a broken pipe): the writer
    deleted everything; now it keeps the files, the MCAP finished, under their partial names."""
    frames_rx, frames_tx = multiprocessing.Pipe(duplex=False)
    acks_rx, acks_tx = multiprocessing.Pipe(duplex=False)
    child = threading.Thread(target=serve, args=(frames_rx, acks_tx))
    child.start()
    frames_tx.send(Start(SinkChoice(tmp_path, kitti=False, yolo=False, resume=True)))
    assert isinstance(acks_rx.recv(), Ready)
    acks_rx.close()  # the parent has gone: the writer's acknowledgement meets a broken pipe
    frames_tx.send(Inband(0, pickle.dumps(records[0], protocol=5)))
    child.join(30)
    frames_tx.close()
    assert not child.is_alive()
    assert leftovers(tmp_path) == ["labels.csv.partial", "run.mcap.partial"]
    assert written_frames(tmp_path) == 1 and complete_frames(tmp_path / "run.mcap.partial") == 1
    with (tmp_path / "run.mcap.partial").open("rb") as stream:  # finished: the seeking reader reads its index
        assert make_reader(stream).get_summary() is not None


def test_a_writer_whose_parent_dies_while_it_waits_keeps_the_frames_it_wrote(records, tmp_path):
    frames_rx, frames_tx = multiprocessing.Pipe(duplex=False)
    _acks_rx, acks_tx = multiprocessing.Pipe(duplex=False)  # open, but never read
    child = threading.Thread(target=serve, args=(frames_rx, acks_tx))
    child.start()
    frames_tx.send(Start(SinkChoice(tmp_path, kitti=False, yolo=False, resume=True)))
    for i, record in enumerate(records):
        frames_tx.send(Inband(i % 2, pickle.dumps(record, protocol=5)))
    frames_tx.close()  # the parent has gone: the writer's next read ends
    child.join(30)
    assert leftovers(tmp_path) == ["labels.csv.partial", "run.mcap.partial"]
    assert written_frames(tmp_path) == len(records) == complete_frames(tmp_path / "run.mcap.partial")


@pytest.mark.skipif(not Path("/dev/full").exists(), reason="needs /dev/full")
def test_a_full_disk_keeps_every_frame_written_and_says_so_in_one_line(records, tmp_path):
    """The writer aborted its sinks: the frames written went, .resume/ with them. /dev/full
    stands in for a full disk under lights_and_signs.csv (written after labels.csv)."""
    (tmp_path / "lights_and_signs.csv.partial").symlink_to("/dev/full")
    writer = BackgroundSinks(SinkChoice(tmp_path, kitti=False, yolo=False, resume=True, traffic_lights=True))
    with pytest.raises(OutputKeptError) as err:
        for record in records * 3:
            writer.write(record)
        writer.close()
    writer.keep()
    assert str(err.value) == f"{tmp_path}/lights_and_signs.csv.partial: cannot write: No space left on device"
    assert err.value.disk_full
    assert leftovers(tmp_path) == ["labels.csv.partial", "lights_and_signs.csv.partial", "run.mcap.partial"]
    assert written_frames(tmp_path) == 0  # the first frame did not reach every output
    assert rows_of_frames((tmp_path / "labels.csv.partial").read_text(), 1)[1]
    assert (tmp_path / ".resume" / "states.jsonl").exists()


def test_a_sink_that_cannot_open_is_reported_at_the_first_frame(records, tmp_path):
    (tmp_path / "kitti.partial").write_text("a file where the KITTI folder goes")
    writer = BackgroundSinks(SinkChoice(tmp_path))
    with pytest.raises(SinkError, match=r"^writer process: "):
        writer.write(records[0])
        writer.close()
    writer.abort()
    assert leftovers(tmp_path) == []


def test_the_writer_process_reports_its_stage_times_on_close(records, tmp_path):
    times = StageTimes()
    writer = BackgroundSinks(SinkChoice(tmp_path, kitti=False, yolo=False), clock=times)
    for record in records:
        writer.write(record)
    writer.close()
    assert times.calls["handoff"] == len(records)
    assert times.calls["writer encode"] == len(records) and times.calls["writer write"] == len(records)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["foxglove_layout.json", "labels.csv", "run.mcap"]


CHURN = """
import resource
import numpy as np
from gtgen.child import keep_freed_memory
keep_freed_memory()
def frame():
    arrays = [np.ones((921600, 3), np.float32) for _ in range(3)] + [np.ones(921600, np.float32) for _ in range(3)]
    del arrays
frame()
before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
for _ in range(10):
    frame()
print(resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before)
"""


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc's allocator")
def test_the_writer_keeps_freed_memory_instead_of_faulting_its_pages_in_every_frame():
    done = subprocess.run([sys.executable, "-c", CHURN], capture_output=True, text=True, check=True)
    # ten frames of 44 MB of arrays made and dropped: their pages stay mapped (without: about 80,000
    # page faults with glibc 2.36)
    assert int(done.stdout.strip()) < 500
