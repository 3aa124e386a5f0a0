"""The README's camera figure: one frame of a scene through a flat-shaded and a realistic camera.

``python -m cosim.figure`` runs the scene with two cameras on the same mount (the first
realistic, the second flat-shaded), takes the chosen frame from each and writes them side by
side, flat on the left, each scaled to ``--width`` with a white gap between them::

    python -m cosim.figure --scenario town10_crowded --frame 25 --out sensors/images/flat_vs_realistic.jpg
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
from pathlib import Path

import cv2
import numpy as np
import numpy.typing as npt

from gtgen.load import iter_messages

DEFAULT_OUT = Path(__file__).resolve().parent.parent / "sensors" / "images" / "flat_vs_realistic.jpg"
CAMERAS = "sensors.cameras=[{name: camera, shading: realistic}, {name: flat, shading: flat}]"
GAP_PX = 8


def frame_image(mcap_path: Path, camera: str, frame: int) -> npt.NDArray[np.uint8]:
    """The ``frame``-th image (from 0) the run's MCAP holds for ``camera``, as BGR."""
    for index, (_, _, message) in enumerate(iter_messages(mcap_path, [f"/{camera}/image"])):
        if index == frame:
            image = cv2.imdecode(np.frombuffer(message.data, np.uint8), cv2.IMREAD_COLOR)
            if image is None:
                raise ValueError(f"{mcap_path}: /{camera}/image frame {frame} is not a decodable image")
            return np.asarray(image, np.uint8)
    raise ValueError(f"{mcap_path}: /{camera}/image has no frame {frame}")


def side_by_side(left: npt.NDArray[np.uint8], right: npt.NDArray[np.uint8], width: int) -> npt.NDArray[np.uint8]:
    """Both images scaled to ``width`` pixels wide (area averaging), ``GAP_PX`` of white between."""
    height = round(left.shape[0] * width / left.shape[1])
    scaled = [cv2.resize(image, (width, height), interpolation=cv2.INTER_AREA) for image in (left, right)]
    gap = np.full((height, GAP_PX, 3), 255, np.uint8)
    return np.concatenate([scaled[0], gap, scaled[1]], axis=1)


def make_figure(scenario: str, frame: int, out: Path, width: int, seed: int | None = None) -> None:
    with tempfile.TemporaryDirectory(prefix="figure_") as tmp:
        run_dir = Path(tmp) / "run"
        command = [sys.executable, "-m", "cosim", "run", scenario, "--frames", str(frame + 1), "--out", str(run_dir)]
        command += ["--no-progress", "--no-summary", "--set", CAMERAS]
        command += ["--set", "outputs.kitti=false", "--set", "outputs.yolo=false", "--set", "outputs.map=false"]
        if seed is not None:
            command += ["--seed", str(seed)]
        done = subprocess.run(command, capture_output=True, text=True)
        if done.returncode != 0:
            lines = (done.stderr or done.stdout).strip().splitlines()
            raise RuntimeError(lines[-1] if lines else f"the run of {scenario} failed (exit {done.returncode})")
        mcap_path = run_dir / "run.mcap"
        figure = side_by_side(frame_image(mcap_path, "flat", frame), frame_image(mcap_path, "camera", frame), width)
    out.parent.mkdir(parents=True, exist_ok=True)
    if not cv2.imwrite(str(out), figure, [cv2.IMWRITE_JPEG_QUALITY, 90]):
        raise RuntimeError(f"{out}: could not write the figure (expected a .jpg or .png path)")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m cosim.figure", description=__doc__.splitlines()[0])
    parser.add_argument("--scenario", default="town10_crowded", help="scenario name or .yaml (default town10_crowded)")
    parser.add_argument("--frame", type=int, default=25, help="frame index from 0 (default 25)")
    parser.add_argument("--width", type=int, default=640, help="width of each half in pixels (default 640)")
    parser.add_argument("--seed", type=int, help="random seed (default: the scenario's)")
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT, help="output image (default: the README's figure)")
    args = parser.parse_args(argv)
    if args.frame < 0 or args.width < 16:
        print(f"cosim.figure: --frame {args.frame} --width {args.width}: expected a frame >= 0 and a width >= 16")
        return 2
    try:
        make_figure(args.scenario, args.frame, args.out, args.width, args.seed)
    except (RuntimeError, ValueError) as err:
        print(f"cosim.figure: {err}", file=sys.stderr)
        return 1
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
