from __future__ import annotations

from pathlib import Path

import cv2

from networks.geometry import SE3
from sensors.agents import EgoState
from sensors.camera import CameraSpec
from sensors.preview import demo_scene, render_preview


def test_preview_writes_image_instance_and_depth_pngs(tmp_path: Path) -> None:
    static, agents = demo_scene()
    paths = render_preview(
        static, agents, EgoState.at(SE3.identity()), tmp_path / "p", CameraSpec(width_px=160, height_px=90)
    )
    assert [p.name for p in paths] == ["p_image.png", "p_instance.png", "p_depth.png"]
    for path in paths:
        image = cv2.imread(str(path))
        assert image.shape == (90, 160, 3)
