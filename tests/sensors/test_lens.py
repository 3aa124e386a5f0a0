"""A camera with lens distortion (OpenCV's plumb_bob): its rays, projection, field of view,
refusal of lenses that fold the image, and labels that stay on the distorted image."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from gtgen.objects import ObjectBoxes
from gtgen.projection import camera_boxes
from networks.classes import SemanticClass
from networks.geometry import SE3
from networks.mesh import box_mesh
from sensors.agents import Agents
from sensors.camera import Camera, CameraSpec
from sensors.errors import SensorConfigError
from sensors.pinhole import Pinhole
from sensors.scene import FrameScene
from sensors.weather import DAY

from .conftest import EGO

KITTI_RAW_LENS = (-0.3691481, 0.1968681, 0.001353473, 0.0005677587, -0.06770705)
"""KITTI raw's camera 2 (2011_09_26 calibration): 1392x512 px, fx 959.8."""
KITTI_HFOV_DEG = math.degrees(2.0 * math.atan(696.0 / 959.8))


def test_rays_and_projection_are_opencvs_and_each_others_inverse() -> None:
    pinhole = Pinhole(1392, 512, KITTI_HFOV_DEG, KITTI_RAW_LENS)
    rng = np.random.default_rng(3)
    uv = np.stack([rng.uniform(0, 1391, 2000), rng.uniform(0, 511, 2000)], axis=1)
    rays = pinhole.pixel_directions(uv[:, 0], uv[:, 1])
    assert np.abs(pinhole.project(rays) - uv).max() < 1e-6
    opencv, _ = cv2.projectPoints(rays.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), pinhole.K,
                                  np.asarray(KITTI_RAW_LENS))  # fmt: skip
    assert np.abs(opencv.reshape(-1, 2) - uv).max() < 1e-6


def test_barrel_distortion_widens_the_view_and_culling_follows_it() -> None:
    bent = Pinhole(1392, 512, KITTI_HFOV_DEG, KITTI_RAW_LENS)
    hfov, vfov = bent.view_fov_deg
    assert hfov > KITTI_HFOV_DEG + 10 and vfov > bent.vfov_deg
    assert Pinhole(1392, 512, KITTI_HFOV_DEG).view_fov_deg == (KITTI_HFOV_DEG, bent.vfov_deg)


@pytest.mark.parametrize("lens", [(0.0, -2.0, 0.0, 0.0, 0.0), (-0.3, 0.1, 0.0, 0.0, -0.02), (math.nan, 0, 0, 0, 0)])
def test_a_lens_that_folds_the_image_is_refused_in_one_line(lens: tuple[float, ...]) -> None:
    with pytest.raises(SensorConfigError, match=r"camera front: distortion .* cannot be used") as err:
        CameraSpec(name="front", distortion=lens)  # type: ignore[arg-type]
    assert "\n" not in str(err.value)


def test_labels_2d_box_is_the_silhouette_of_a_box_seen_through_the_lens() -> None:
    """A box near the image's corner, where the lens bends most: the pixels the camera renders
    of it fill exactly the 2D box the labels project (to the pixel), which a pinhole's
    projection misses by pixels."""
    spec = CameraSpec(width_px=640, height_px=360, hfov_deg=70.0, distortion=(-0.35, 0.15, 0.0, 0.0, -0.03))
    camera = Camera(spec)
    assert spec.pinhole.check_lens() is None
    centre, lwh = np.array([9.0, 4.2, 2.6]), (1.5, 1.5, 1.5)
    mesh = box_mesh(lwh, SemanticClass.BUILDING)
    mesh = type(mesh)(mesh.vertices_m + centre, mesh.triangles, mesh.triangle_class)
    frame = camera.sense(FrameScene(mesh, Agents.empty()), EGO, DAY, np.random.default_rng(0)).frame
    vv, uu = np.nonzero(frame.semantic_class == SemanticClass.BUILDING)
    assert vv.size > 500 and uu.min() < spec.width_px * 0.25  # near the top-left corner
    boxes = ObjectBoxes(np.array([1]), np.array([int(SemanticClass.BUILDING)]), centre[None, :], np.array([lwh]),
                        np.zeros(1), np.zeros(1), np.zeros(1), np.zeros((1, 3)), np.zeros(1, bool))  # fmt: skip
    ego_SE3_map = EGO.map_SE3_ego().inverse()
    assert np.allclose(ego_SE3_map.as_matrix(), np.eye(4))
    left, top, right, bottom = camera_boxes(spec.pinhole, spec.ego_SE3_sensor, boxes).amodal_px[0]
    # a pixel is rendered where its centre ray meets the box: the extreme pixel centres lie
    # within one pixel inside the projected box's edges
    assert left - 0.01 <= uu.min() <= left + 1.0 and right - 1.0 <= uu.max() <= right + 0.01
    assert top - 0.01 <= vv.min() <= top + 1.0 and bottom - 1.0 <= vv.max() <= bottom + 0.01
    pinhole = Pinhole(640, 360, 70.0)  # the same box through a pinhole lands elsewhere
    straight = camera_boxes(pinhole, spec.ego_SE3_sensor, boxes).amodal_px[0]
    assert abs(straight[0] - left) > 5.0 and abs(straight[1] - top) > 5.0


def test_the_mcap_calibration_carries_the_lens() -> None:
    from gtgen.sinks.foxglove import calibration
    from sensors.camera import CameraOutput

    spec = CameraSpec(width_px=64, height_px=36, distortion=(-0.1, 0.01, 0.0, 0.0, 0.0))
    frame = Camera(spec).sense(FrameScene(box_mesh((1, 1, 1), SemanticClass.BUILDING), Agents.empty()), EGO, DAY,
                               np.random.default_rng(0)).frame  # fmt: skip
    message = calibration(0, CameraOutput(spec, frame))
    assert message.distortion_model == "plumb_bob" and list(message.D) == [-0.1, 0.01, 0.0, 0.0, 0.0]


_ = SE3
