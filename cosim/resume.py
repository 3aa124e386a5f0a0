"""Continuing an interrupted run: whether the folder holds one of this scenario, the last frame
every output holds whole, and the frame loop's state after it.

A run keeps ``.resume/`` in its output folder while it runs: ``run.json`` (the scenario it was
started with) and ``states.jsonl`` (one line per frame written to every output, see
:mod:`gtgen.sinks.resume_sink`). The traffic is not saved: it is simulated again up to the
frame the run continues from (SUMO is deterministic for a seed), without sensing or writing.
"""

from __future__ import annotations

import json
import shutil
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from cosim.errors import CosimError
from cosim.scenario import Scenario
from gtgen.sinks.mcap_sink import complete_frames, earlier_file
from gtgen.sinks.resume_sink import RESUME_DIR, read_states, wait_for_writer
from networks.geometry import SE3

RUN_FILE = "run.json"
# Keys that may differ between the run and its continuation: they change no frame's content.
FREE_KEYS = ("frames", "name", "source_dir", "outputs.live")
WRITER_WAIT_S = 60.0


class AlreadyCompleteError(CosimError):
    """The folder holds the complete dataset already."""


@dataclass(frozen=True, slots=True)
class ResumePoint:
    """Where a run continues: ``frames`` kept, the loop's ``checkpoint`` after the last of them
    and the ego's pose at frame 0."""

    frames: int
    checkpoint: dict[str, Any]
    first_map_SE3_ego: SE3


def scenario_identity(scenario: Scenario | dict[str, Any]) -> dict[str, Any]:
    """The scenario (or its plain data, as in manifest.json) without the keys a continuation
    may change."""
    data = json.loads(json.dumps(asdict(scenario) if isinstance(scenario, Scenario) else scenario, default=str))
    for key in FREE_KEYS:
        *parents, leaf = key.split(".")
        node = data
        for part in parents:
            node = node.get(part, {})
        node.pop(leaf, None)
    return dict(data)


def begin(out_dir: Path, scenario: Scenario) -> None:
    """A new run in ``out_dir``: forget any earlier run's resume state, record this scenario."""
    folder = out_dir / RESUME_DIR
    (folder / RUN_FILE).parent.mkdir(parents=True, exist_ok=True)
    (folder / RUN_FILE).write_text(json.dumps(scenario_identity(scenario), indent=1, sort_keys=True) + "\n")


def finish(out_dir: Path) -> None:
    """The run is complete: nothing is left to continue."""
    shutil.rmtree(out_dir / RESUME_DIR, ignore_errors=True)


def complete_run(out_dir: Path, scenario: Scenario) -> dict[str, Any] | None:
    """The manifest of a complete dataset of this scenario with all its frames in ``out_dir``, else None."""
    path = out_dir / "manifest.json"
    if not path.exists():
        return None
    manifest: dict[str, Any] = json.loads(path.read_text())
    same = scenario_identity(manifest.get("scenario", {})) == scenario_identity(scenario)
    whole = manifest.get("complete", True) and manifest.get("frames") == scenario.frames
    return manifest if same and whole else None


def _differences(a: Any, b: Any, prefix: str = "") -> list[str]:
    if isinstance(a, dict) and isinstance(b, dict):
        keys = sorted(set(a) | set(b))
        return [d for k in keys for d in _differences(a.get(k), b.get(k), f"{prefix}{k}.")]
    return [] if a == b else [prefix.rstrip(".")]


def resume_point(out_dir: Path, scenario: Scenario) -> ResumePoint | None:
    """Where the run in ``out_dir`` continues (None: it has no frame to keep, start afresh).
    Raises :class:`AlreadyCompleteError` for a complete dataset, :class:`CosimError` when the
    folder holds no run to continue or one of another scenario."""
    settle(out_dir)
    manifest = out_dir / "manifest.json"
    if manifest.exists():
        done = json.loads(manifest.read_text())
        if done.get("complete", True) and done.get("frames", 0) >= scenario.frames:
            differ = _differences(scenario_identity(done.get("scenario", {})), scenario_identity(scenario))
            if differ:
                msg = f"{out_dir}: the complete dataset there was made from another scenario ({_keys(differ)} differ)"
                raise CosimError(msg + "; give its scenario and overrides, or another --out")
            raise AlreadyCompleteError(f"{out_dir}: the dataset is complete already ({done.get('frames')} frames)")
    run_file = out_dir / RESUME_DIR / RUN_FILE
    if not run_file.exists():
        raise CosimError(f"{out_dir}: no interrupted run to continue here; run without --resume to start one")
    differ = _differences(json.loads(run_file.read_text()), scenario_identity(scenario))
    if differ:
        raise CosimError(
            f"{out_dir}: the run there was made from another scenario ({_keys(differ)} differ); "
            "give the same scenario and overrides, or run without --resume to start again"
        )
    return _point(out_dir, scenario)


def _keys(differ: list[str]) -> str:
    return ", ".join(differ[:6]) + (f" and {len(differ) - 6} more" if len(differ) > 6 else "")


def kept_frames(out_dir: Path, scenario: Scenario) -> int:
    """How many frames every output of the run in ``out_dir`` holds whole (the frames a run
    that continues keeps)."""
    frames = len(read_states(out_dir))
    if scenario.outputs.mcap:
        mcap = earlier_file(out_dir / "run.mcap")
        frames = min(frames, complete_frames(mcap) if mcap is not None else 0)
    return frames


def settle(out_dir: Path) -> None:
    """Wait for the writer of an earlier run in ``out_dir`` (one killed with its run keeps its
    files for a moment after) to end."""
    if not wait_for_writer(out_dir, WRITER_WAIT_S):
        raise CosimError(
            f"{out_dir}: the writer process of another run still writes here after "
            f"{WRITER_WAIT_S:g} s; let it end (or stop it) first"
        )


def _point(out_dir: Path, scenario: Scenario) -> ResumePoint | None:
    states = read_states(out_dir)
    frames = kept_frames(out_dir, scenario)
    if frames > scenario.frames:
        msg = f"{out_dir}: the run there has {frames} frames, more than frames={scenario.frames}"
        raise CosimError(msg + "; ask for at least as many")
    if frames == 0:
        return None
    first = SE3.from_matrix(np.asarray(states[0]["map_SE3_ego"], dtype=np.float64))
    return ResumePoint(frames, dict(states[frames - 1]["checkpoint"]), first)
