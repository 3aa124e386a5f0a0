"""The run folder's lifecycle: made before the first frame, its ``*.partial`` files removed when
a run fails (kept when the disk fills or a writer dies, to continue from), its disk space checked
early, the lines for a run that stopped, the summary, and ``manifest.json`` last."""

from __future__ import annotations

import contextlib
import json
import shutil
from collections import Counter
from collections.abc import Iterator
from dataclasses import asdict, dataclass, field
from importlib import metadata
from pathlib import Path
from typing import Any

from cosim.errors import CosimError, RunStoppedError, Terminated
from cosim.interrupts import interrupt_behind
from cosim.resume import kept_frames
from cosim.scenario import Scenario
from gtgen.content import STOPPED_MPS
from gtgen.errors import OutputKeptError
from gtgen.labels import FrameLabels
from gtgen.sinks.resume_sink import RESUME_DIR
from networks.cache import file_sha256
from networks.classes import SemanticClass


@dataclass(slots=True)
class RunSummary:
    frames: int = 0
    objects: int = 0
    seen: int = 0
    per_class: Counter[str] = field(default_factory=Counter)
    scene_cuts: list[int] = field(default_factory=list)  # frames that start a new scene
    ego_stopped: int = 0  # frames in which the ego moved slower than STOPPED_MPS

    def add(self, labels: FrameLabels, scene_cut: bool = False, ego_speed_mps: float | None = None) -> None:
        if scene_cut:
            self.scene_cuts.append(labels.frame_index)
        if ego_speed_mps is not None and ego_speed_mps < STOPPED_MPS:
            self.ego_stopped += 1
        self.frames += 1
        self.objects += len(labels)
        self.seen += int(labels.seen.sum())
        self.per_class.update(SemanticClass(int(c)).label for c in labels.objects.semantic_class[labels.seen])

    def to_dict(self) -> dict[str, Any]:
        return {
            "frames": self.frames,
            "objects": self.objects,
            "seen": self.seen,
            "per_class": dict(sorted(self.per_class.items())),
            "scene_cuts": list(self.scene_cuts),
            "ego_stopped": self.ego_stopped,
        }

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> RunSummary:
        return cls(
            frames=int(data["frames"]),
            objects=int(data["objects"]),
            seen=int(data["seen"]),
            per_class=Counter(data["per_class"]),
            scene_cuts=[int(f) for f in data["scene_cuts"]],
            ego_stopped=int(data.get("ego_stopped", 0)),
        )

    def lines(self) -> list[str]:
        n = max(self.frames, 1)
        out = [
            f"frames: {self.frames}",
            f"objects in range per frame: {self.objects / n:.1f}",
            f"objects seen per frame: {self.seen / n:.1f}",
        ]
        out += [f"  {cls}: {count / n:.1f}" for cls, count in sorted(self.per_class.items())]
        out.append(f"ego stopped (below {STOPPED_MPS:g} m/s): {100 * self.ego_stopped / n:.0f} % of the frames")
        if self.scene_cuts:
            frames = ", ".join(str(f) for f in self.scene_cuts)
            out.append(f"scene cuts (the ego ran out of road and started again) at frames: {frames}")
        return out


def summarize(out_dir: Path, scenario: Scenario) -> BaseException | None:
    """Write ``summary/`` (it moves into place when whole); the Ctrl-C or SIGTERM that cut it
    short (the partial summary goes), else None."""
    from gtgen.summary import asked_rates, write_summary

    try:
        write_summary(out_dir, asked=asked_rates([asdict(h) for h in scenario.hazards]))
    except (KeyboardInterrupt, Terminated, SystemError) as err:
        cause = interrupt_behind(err)
        if cause is None:
            raise
        shutil.rmtree(out_dir / "summary.partial", ignore_errors=True)
        return cause
    return None


def run_stopped(cause: BaseException, out_dir: Path, kept: int, in_summary: bool = False) -> RunStoppedError:
    """The line for a run that stopped and kept its first ``kept`` frames (``in_summary``: all
    of them, while it wrote the summary), and its exit code."""
    where = f'{out_dir} keeps frames 0 to {kept - 1} (manifest.json: "complete": false)'
    again = "run the same command with --resume to continue"
    at = f"at frame {kept}"
    if in_summary:
        at = "while writing summary/"
        where = f'{out_dir} holds all {kept} frames and no summary (manifest.json: "complete": false)'
        again = "run the same command with --resume to finish it"
    if isinstance(cause, KeyboardInterrupt):
        return RunStoppedError(f"interrupted {at}; {where}; {again}", kept, 130)
    if isinstance(cause, Terminated):
        return RunStoppedError(f"stopped (SIGTERM) {at}; {where}; {again}", kept, 143)
    return RunStoppedError(f"{cause} ({at}); {where}", kept, 2)


def outputs_kept(kept: OutputKeptError, out_dir: Path, scenario: Scenario, continuing: bool) -> RunStoppedError:
    """The line for a run whose writers stopped and kept their files (disk full, writer killed);
    a new run that kept no frame leaves nothing (there is nothing to continue)."""
    frames = kept_frames(out_dir, scenario)
    space = "free some space, then " if kept.disk_full else ""
    if frames == 0 and not continuing:
        remove_partials(out_dir)
        return RunStoppedError(f"{kept}; no frame was written; {space}run the same command again", 0, 2)
    held = f"frames 0 to {frames - 1}" if frames else "no whole frame"
    where = f"{out_dir} keeps {held} under the files' .partial names"
    return RunStoppedError(f"{kept}; {where}; {space}run the same command with --resume to continue", frames, 2)


def make_output_folder(out_dir: Path) -> None:
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        reason = err.strerror or "not a folder that can be made"
        raise CosimError(f"{out_dir}: cannot create the output folder ({err.filename}: {reason})") from err


@contextlib.contextmanager
def partials_removed_on_error(out_dir: Path) -> Iterator[None]:
    """Remove what the ``with`` block wrote under ``*.partial`` names if it raises (but for
    :class:`OutputKeptError`: the outputs keep their frames)."""
    try:
        yield
    except OutputKeptError:
        raise
    except BaseException:
        remove_partials(out_dir)
        raise


DISK_CHECK_FRAMES = 30  # the frames written before the output size is extrapolated
DISK_MARGIN = 1.1
WRITER_LAG_FRAMES = 3  # frames still in the writer's queue or buffers


def disk_check_frame(frames: int) -> int:
    """The frame after which :func:`check_disk_space` runs (-1: a run too short to check)."""
    return min(DISK_CHECK_FRAMES, frames // 2) if frames >= 2 * WRITER_LAG_FRAMES + 2 else -1


def check_disk_space(out_dir: Path, frames_done: int, frames_total: int) -> None:
    """Stop early, with one line, when the run's files (extrapolated from what the first
    frames wrote) will not fit on the disk: not after hours, with the disk full."""
    written = sum(f.stat().st_size for partial in out_dir.glob("*.partial") for f in _files(partial))
    frames_written = max(frames_done - WRITER_LAG_FRAMES, 1)
    needed = written / frames_written * frames_total
    free = shutil.disk_usage(out_dir).free
    if (needed - written) * DISK_MARGIN > free:
        raise CosimError(
            f"{out_dir}: not enough free disk space for this run: about {_size(needed)} in all "
            f"(from its first {frames_written} frames), {_size(free)} free; free some space, write "
            "fewer frames or turn outputs off (outputs.kitti=false, outputs.yolo=false, outputs.mcap=false)"
        )


def _size(n_bytes: float) -> str:
    return f"{n_bytes / 1e9:.1f} GB" if n_bytes >= 1e9 else f"{n_bytes / 1e6:.0f} MB"


def _files(path: Path) -> list[Path]:
    return [path] if path.is_file() else [f for f in path.rglob("*") if f.is_file()]


def remove_partials(out_dir: Path) -> None:
    """Remove what a failed run left: ``*.partial`` files and folders, and its resume state."""
    shutil.rmtree(out_dir / RESUME_DIR, ignore_errors=True)
    for partial in out_dir.glob("*.partial"):
        if partial.is_dir():
            shutil.rmtree(partial, ignore_errors=True)
        else:
            partial.unlink(missing_ok=True)


def write_manifest(scenario: Scenario, out_dir: Path, summary: RunSummary, xodr: Path, complete: bool = True) -> None:
    """``manifest.json``: the run's scenario, versions, counts and file hashes; ``complete``:
    whether the run wrote all its frames (false: it stopped early and kept ``frames``)."""
    versions = {}
    for dist in ("eclipse-sumo", "libsumo", "open3d-cpu", "numpy", "mcap", "sumo-dataset-factory"):
        try:
            versions[dist] = metadata.version(dist)
        except metadata.PackageNotFoundError:
            versions[dist] = "unknown"
    files = {
        str(p.relative_to(out_dir)): file_sha256(p)
        for p in sorted(out_dir.rglob("*"))
        if p.is_file()
        and p.name != "manifest.json"
        and p.parent.name not in ("image_2", "image_3", "velodyne", "images")
        and p.relative_to(out_dir).parts[0] not in (RESUME_DIR, "summary")
    }
    scenario_data = asdict(scenario)
    scenario_data.pop("source_dir")  # where the scenario file was: not part of the dataset
    manifest = {
        "scenario": scenario_data,
        "seed": scenario.seed,
        "network_sha256": file_sha256(xodr),  # the OpenDRIVE file driven (the town's, or the user's)
        "complete": complete,
        "frames": summary.frames,
        "objects_per_frame": summary.objects / max(summary.frames, 1),
        "seen_per_frame": summary.seen / max(summary.frames, 1),
        "ego_stopped_share": summary.ego_stopped / max(summary.frames, 1),
        "scene_cuts": summary.scene_cuts,
        "versions": versions,
        "files_sha256": files,
    }
    tmp = out_dir / "manifest.json.partial"
    tmp.write_text(json.dumps(manifest, indent=2, sort_keys=True, default=str) + "\n")
    tmp.replace(out_dir / "manifest.json")
