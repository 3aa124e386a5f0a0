"""The writer process: the same files as the sinks in this process, one-line errors, no
complete-looking file after a failure."""

import os
import signal
from pathlib import Path

import pytest

from gtgen.errors import SinkError
from gtgen.sinks.background import BackgroundSinks
from gtgen.sinks.group import SinkChoice, SinkGroup
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


def test_a_killed_writer_process_is_reported_and_its_partial_files_removed(records, tmp_path):
    writer = BackgroundSinks(SinkChoice(tmp_path))
    writer.write(records[0])
    os.kill(writer.pid, signal.SIGKILL)
    with pytest.raises(SinkError, match="writer process stopped unexpectedly"):
        for record in records * 5:
            writer.write(record)
        writer.close()
    writer.abort()
    assert leftovers(tmp_path) == []


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
