"""Error lines from the helper processes and the command line: the project's own messages
as they are, a refused file with the system's reason, anything else as an internal error
whose details go to a crash report (no exception class, no library wording on the line)."""

import pytest

from gtgen.channel import error_line
from gtgen.errors import SinkError


def test_a_project_error_is_its_own_message():
    line = error_line(SinkError("labels.csv: cannot write"), (SinkError,), "writer process")
    assert line == "labels.csv: cannot write"


def test_a_refused_file_names_the_file_and_the_reason():
    err = PermissionError(13, "Permission denied", "/data/out/run.mcap")
    assert error_line(err, (SinkError,), "writer process") == "writer process: /data/out/run.mcap: Permission denied"


def test_an_unforeseen_error_is_one_line_without_its_class_and_the_details_go_to_a_crash_report(tmp_path, monkeypatch):
    monkeypatch.setenv("SUMO_DATASET_CACHE", str(tmp_path))
    try:
        raise ValueError("a must be a positive integer unless no samples are taken")
    except ValueError as err:
        line = error_line(err, (SinkError,), "traffic process")
    assert line.startswith("internal error in the traffic process: the details are in ")
    assert "ValueError" not in line and "positive integer" not in line and "\n" not in line
    (report,) = (tmp_path / "crash-reports").iterdir()
    assert str(report) in line and "ValueError: a must be a positive integer" in report.read_text()


def test_the_command_line_turns_an_unforeseen_error_into_one_line_and_exit_code_3(tmp_path, monkeypatch, capsys):
    import cosim.cli as cli

    monkeypatch.setenv("SUMO_DATASET_CACHE", str(tmp_path))

    def broken() -> int:
        raise KeyError("edge_42")

    monkeypatch.setattr(cli, "_cmd_list", broken)
    assert cli.main(["list"]) == 3
    err = capsys.readouterr().err.strip()
    assert err.startswith("error: internal error in cosim list: the details are in ") and "\n" not in err
    assert "KeyError" not in err and "edge_42" not in err


@pytest.mark.parametrize("where", ["/proc/no_such_folder/out", "/dev/null/out"])
def test_an_output_folder_that_cannot_be_made_is_one_line(where, capsys):
    import cosim.cli as cli

    assert cli.main(["run", "tests/data/tiny.yaml", "--out", where, "--frames", "2"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith(f"error: {where}: cannot create the output folder (") and "\n" not in err
