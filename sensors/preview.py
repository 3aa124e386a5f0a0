"""A quick look at a camera frame: shaded image, colourised instance mask and depth as PNGs.

``python -m sensors.preview /tmp/preview [weather]`` renders a small synthetic scene;
``render_preview(static, agents, map_SE3_ego, prefix)`` renders any scene, such as a town
crop around the ego, and writes ``<prefix>_image.png``, ``_instance.png``, ``_depth.png``.
"""

from __future__ import annotations

import sys
from pathlib import Path

import cv2
import numpy as np
import numpy.typing as npt
from shapely.geometry import Polygon, box

from networks.classes import SemanticClass
from networks.geometry import SE3
from networks.mesh import ClassedMesh, flat_polygon, merge, prism
from sensors.agents import Agents, EgoState
from sensors.camera import Camera, CameraSpec
from sensors.errors import SensorError
from sensors.materials import ALBEDO_BGR_BY_CLASS
from sensors.scene import FrameScene
from sensors.shading import CameraFrame, shade_frame
from sensors.weather import DAY, Weather, weather_preset


def colorize_instances(
    instance_id: npt.NDArray[np.uint32], semantic_class: npt.NDArray[np.uint8]
) -> npt.NDArray[np.uint8]:
    """``(H, W, 3) uint8``: each agent instance a bright colour of its own; the static world
    in its class albedo, dimmed; nothing hit black."""
    hue = ((instance_id.astype(np.uint64) * 2654435761) % 180).astype(np.uint8)
    hsv = np.stack([hue, np.full_like(hue, 220), np.full_like(hue, 255)], axis=-1)
    agents = cv2.cvtColor(hsv, cv2.COLOR_HSV2BGR)
    static = (ALBEDO_BGR_BY_CLASS[semantic_class] * 120.0).astype(np.uint8)
    return np.where((instance_id > 0)[..., None], agents, static)


def colorize_depth(depth_m: npt.NDArray[np.float32], near_m: float = 2.0) -> npt.NDArray[np.uint8]:
    """``(H, W, 3) uint8`` turbo colour map of inverse depth (near: red, far: blue); no depth black."""
    hit = depth_m > 0
    inv = np.where(hit, near_m / np.maximum(depth_m, near_m), 0.0)
    coloured = cv2.applyColorMap((inv * 255.0).astype(np.uint8), cv2.COLORMAP_TURBO)
    return np.where(hit[..., None], coloured, np.uint8(0))


def save_preview(frame: CameraFrame, prefix: str | Path) -> list[Path]:
    """Write the shaded image, instance mask and depth of ``frame`` next to ``prefix``."""
    images = {
        "image": shade_frame(frame),
        "instance": colorize_instances(frame.instance_id, frame.semantic_class),
        "depth": colorize_depth(frame.depth_m),
    }
    paths = []
    for kind, image in images.items():
        path = Path(f"{prefix}_{kind}.png")
        if not cv2.imwrite(str(path), image):
            raise SensorError(f"{path}: could not write the preview image")
        paths.append(path)
    return paths


def render_preview(
    static: ClassedMesh,
    agents: Agents,
    ego: EgoState,
    prefix: str | Path,
    spec: CameraSpec | None = None,
    weather: Weather = DAY,
) -> list[Path]:
    """Render one camera frame of a scene and save its preview PNGs."""
    camera = Camera(CameraSpec() if spec is None else spec)
    output = camera.sense(FrameScene(static, agents), ego, weather, np.random.default_rng(0))
    return save_preview(output.frame, prefix)


def demo_scene() -> tuple[ClassedMesh, Agents]:
    """A straight road with sidewalks, two buildings, a pole and one agent of each class."""
    road = flat_polygon(box(-20, -5, 200, 5), 0.0, SemanticClass.ROAD)
    walks = [prism(box(-20, s * 5, 200, s * 9), 0.0, 0.15, SemanticClass.SIDEWALK) for s in (-1, 1)]
    grass = [flat_polygon(box(-20, s * 9, 200, s * 60), 0.1, SemanticClass.TERRAIN) for s in (-1, 1)]
    houses = [
        prism(Polygon([(x, y), (x + 14, y), (x + 14, y + 10), (x, y + 10)]), 0.0, h, SemanticClass.BUILDING)
        for x, y, h in ((25, 11, 9), (45, -21, 14), (70, 12, 20))
    ]
    pole = prism(box(18, 6, 18.3, 6.3), 0.0, 6.0, SemanticClass.POLE)
    static = merge([road, *walks, *grass, *houses, pole])
    rows = [  # class, x, y, l, w, h, yaw
        (SemanticClass.CAR, 14.0, -2.0, 4.5, 1.8, 1.5, 0.0),
        (SemanticClass.CAR, 26.0, 2.0, 4.3, 1.8, 1.45, np.pi),
        (SemanticClass.TRUCK, 42.0, -2.0, 7.5, 2.5, 3.2, 0.0),
        (SemanticClass.BUS, 60.0, 2.2, 12.0, 2.5, 3.4, np.pi),
        (SemanticClass.MOTORCYCLE, 10.0, 2.5, 2.2, 0.8, 1.7, np.pi),
        (SemanticClass.BICYCLE, 12.0, 6.5, 1.8, 0.6, 1.75, 0.3),
        (SemanticClass.PEDESTRIAN, 9.0, -6.5, 0.3, 0.5, 1.75, np.pi / 2),
        (SemanticClass.PEDESTRIAN, 16.0, -7.0, 0.3, 0.5, 1.7, 0.0),
    ]
    a = np.array([r[1:] for r in rows], dtype=np.float64)
    ground = np.where(a[:, 1] ** 2 > 25.0, 0.15, 0.0)
    ids = np.arange(1, len(rows) + 1, dtype=np.uint32)
    agents = Agents.standing(ids, np.array([r[0] for r in rows], dtype=np.uint8),
                             np.column_stack([a[:, 0], a[:, 1], ground + a[:, 4] / 2]), a[:, 2:5], a[:, 5])  # fmt: skip
    return static, agents


def main(argv: list[str]) -> int:
    prefix = argv[0] if argv else "/tmp/preview"
    weather = weather_preset(argv[1]) if len(argv) > 1 else DAY
    static, agents = demo_scene()
    for path in render_preview(static, agents, EgoState.at(SE3.identity()), prefix, weather=weather):
        print(path)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
