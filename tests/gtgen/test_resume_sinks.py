"""Writers that continue an earlier run: a run stopped after some frames (closed, or killed
with its files cut short) and continued writes the same files as a run never stopped."""

import json
import shutil
from pathlib import Path

import pandas as pd

from gtgen.compare import compare_datasets
from gtgen.sinks.group import SinkChoice, SinkGroup
from gtgen.sinks.mcap_sink import complete_frames
from gtgen.sinks.resume_sink import read_states
from gtgen.summary import event_summary, hazard_lines
from networks.vocabulary import HazardKind


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


def test_a_nuscenes_export_stopped_and_continued_is_the_export_never_stopped(records, tmp_path):
    from gtgen.sinks.nuscenes_sink import NuscenesSetup

    # frames 0.25 s apart: keyframes (every 0.5 s) at frames 0 and 2; every sensor every frame
    setup = NuscenesSetup(
        "run", 0.25, (("lidar", "lidar", 4.0), ("camera", "camera", 4.0), ("radar", "radar", 4.0)), "skeleton"
    )

    def export(out: Path, upto: int, keep: int = 0) -> None:
        out.mkdir(exist_ok=True)
        with SinkGroup.open(
            SinkChoice(out, mcap=False, csv=False, kitti=False, yolo=False, nuscenes=setup, keep_frames=keep)
        ) as sinks:
            for record in records[keep:upto]:
                sinks.write(record)

    export(tmp_path / "whole", 3)
    export(tmp_path / "stopped", 2)
    export(tmp_path / "stopped", 3, keep=1)  # frame 1 again (its files and records are made anew), then 2
    result = compare_datasets(tmp_path / "whole", tmp_path / "stopped")
    assert result.same, result.differences
    tables = tmp_path / "whole" / "nuscenes" / "v1.0-trainval"
    assert len(json.loads((tables / "sample.json").read_text())) == 2
    data = json.loads((tables / "sample_data.json").read_text())
    assert len(data) == 9 and sum(d["is_key_frame"] for d in data) == 6
    sweeps = tmp_path / "stopped" / "nuscenes" / "sweeps" / "LIDAR_TOP"
    assert [p.name for p in sweeps.iterdir()] == ["run__LIDAR_TOP__50000.pcd.bin"]  # frame 1 once


def test_merging_what_holds_no_nuscenes_export_is_one_line(tmp_path, capsys):
    from gtgen import nuscenes

    (tmp_path / "a").mkdir()
    assert nuscenes.main(["merge", str(tmp_path / "out"), str(tmp_path / "a")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [
        f"error: {tmp_path / 'a'}: no nuScenes export (expected {tmp_path / 'a'}/nuscenes/v1.0-trainval; "
        "run it with outputs.nuscenes=true)"
    ]
    assert not (tmp_path / "out").exists()


def test_events_of_a_run_stopped_and_continued_are_those_of_a_run_never_stopped(records, tmp_path):
    from dataclasses import replace

    from gtgen.frame import ActiveHazard

    marked = [
        replace(r, hazards=(ActiveHazard("hard_brake-1", HazardKind.HARD_BRAKE, (3, 5), 1),) if i else ())
        for i, r in enumerate(records)
    ]

    def export(out: Path, upto: int, keep: int = 0) -> None:
        out.mkdir(exist_ok=True)
        choice = SinkChoice(out, mcap=False, kitti=False, yolo=False, hazards=True, keep_frames=keep)
        with SinkGroup.open(choice) as sinks:
            for record in marked[keep:upto]:
                sinks.write(record)

    export(tmp_path / "whole", 3)
    export(tmp_path / "stopped", 2)
    export(tmp_path / "stopped", 3, keep=1)
    result = compare_datasets(tmp_path / "whole", tmp_path / "stopped")
    assert result.same, result.differences
    rows = (tmp_path / "whole" / "events.csv").read_text().splitlines()
    assert rows[0].startswith("event,kind,first_frame,last_frame,frames,actors,ego_id,min_ttc,min_distance")
    assert rows[1].startswith("hard_brake-1,hard_brake,1,2,2,3 5,1,")
    assert len((tmp_path / "whole" / "event_frames.csv").read_text().splitlines()) == 3


def test_the_summary_lists_every_hazard_kind_asked_with_its_rate_even_without_events(tmp_path):
    events = pd.DataFrame(
        {"event": ["cut_in-1"], "kind": ["cut_in"], "first_frame": [10], "min_ttc": [2.5], "ego_collided": [0]}
    )
    folder = tmp_path / "summary"
    folder.mkdir()
    event_summary(events, 0.5, folder, {"cut_in": 4.0, "red_light": 1.0})
    table = pd.read_csv(folder / "events.csv")
    assert list(table["kind"]) == ["cut_in", "red_light"]
    assert list(table["events"]) == [1, 0] and list(table["per_minute"]) == [2.0, 0.0]
    assert list(table["asked_per_minute"]) == [4.0, 1.0]
    lines = hazard_lines(tmp_path)
    assert lines[0] == "hazard events, cut_in: 1 (2.0 a minute, 4 asked, smallest time to collision 2.50 s)"
    assert lines[1] == "hazard events, red_light: 0 (0.0 a minute, 1 asked)"
    assert lines[2].startswith("  fewer than asked: a red_light starts only where")
