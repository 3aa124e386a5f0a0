"""Writers that continue an earlier run: a run stopped after some frames (closed, or killed
with its files cut short) and continued writes the same files as a run never stopped."""

import shutil
from pathlib import Path

from gtgen.compare import compare_datasets
from gtgen.sinks.group import SinkChoice, SinkGroup
from gtgen.sinks.mcap_sink import complete_frames
from gtgen.sinks.resume_sink import read_states


def write(records, out: Path, keep_frames: int = 0, first=None) -> None:
    out.mkdir(exist_ok=True)
    choice = SinkChoice(out, resume=True, keep_frames=keep_frames, first_map_SE3_ego=first)
    with SinkGroup.open(choice) as sinks:
        for record in records[keep_frames:]:
            sinks.write(record)


def test_a_run_closed_early_and_continued_writes_what_a_run_never_stopped_writes(records, tmp_path):
    write(records, tmp_path / "whole")
    write(records[:2], tmp_path / "stopped")
    assert len(read_states(tmp_path / "stopped")) == 2
    write(records, tmp_path / "stopped", keep_frames=1, first=records[0].map_SE3_ego)  # frame 1 again, then 2
    result = compare_datasets(tmp_path / "whole", tmp_path / "stopped")
    assert result.same, result.differences
    assert result.messages > 30


def cut_to_whole_frames(path: Path, frames: int) -> None:
    """Cut a file's end as a killed writer would, until it holds ``frames`` whole frames."""
    data = path.read_bytes()
    while complete_frames(path) > frames:
        data = data[: len(data) - 4096]
        path.write_bytes(data)


def test_files_cut_short_by_a_kill_are_taken_back_to_their_last_whole_frame(records, tmp_path, monkeypatch):
    import functools

    import gtgen.sinks.mcap_sink as mcap_sink

    monkeypatch.setattr(mcap_sink, "McapWriter", functools.partial(mcap_sink.McapWriter, chunk_size=1 << 16))
    write(records, tmp_path / "whole")
    killed = tmp_path / "killed"
    write(records[:2], killed)
    for name in ("run.mcap", "labels.csv", "kitti", "yolo"):  # a killed writer leaves them partial
        shutil.move(killed / name, killed / f"{name}.partial")
    cut_to_whole_frames(killed / "run.mcap.partial", 1)  # the second frame's chunks are lost
    (killed / "labels.csv.partial").write_bytes((killed / "labels.csv.partial").read_bytes()[:-20])
    write(records, killed, keep_frames=1, first=records[0].map_SE3_ego)
    result = compare_datasets(tmp_path / "whole", killed)
    assert result.same, result.differences
    assert not list(killed.glob("*.partial")) and not list(killed.glob("*.earlier"))
