"""``kitti/``: the KITTI object-detection layout (image_2, velodyne, label_2, calib).

One frame per file, named by frame index (``000000``). Images are the first camera's
shaded image (lossless PNG); ``velodyne`` holds the first LiDAR's points as float32 x, y, z,
intensity in the LiDAR frame (x forward, y left, z up, like KITTI's Velodyne).
Labels list the objects whose projected box overlaps the image and that some sensor
saw; boxes and alpha follow KITTI's definitions, ``location`` is the bottom centre of
the 3D box in the camera frame.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from gtgen.errors import SinkError
from gtgen.frame import FrameRecord
from gtgen.sinks.folder import PartialFolder
from gtgen.sinks.images import FrameImages
from networks.classes import SemanticClass

KITTI_TYPES = {
    SemanticClass.CAR: "Car",
    SemanticClass.TRUCK: "Truck",
    SemanticClass.BUS: "Bus",
    SemanticClass.MOTORCYCLE: "Motorcycle",
    SemanticClass.BICYCLE: "Cyclist",
    SemanticClass.PEDESTRIAN: "Pedestrian",
}


def _matrix_line(name: str, m: np.ndarray) -> str:
    return f"{name}: " + " ".join(f"{v:.12e}" for v in np.asarray(m, dtype=np.float64).ravel())


class KittiSink:
    def __init__(self, folder: Path) -> None:
        self._folder = PartialFolder(folder, ("image_2", "velodyne", "label_2", "calib"))

    def encode(self, record: FrameRecord, images: FrameImages) -> dict[str, bytes]:
        """The frame's files, by path relative to the ``kitti`` folder."""
        if not record.cameras or not record.lidars:
            raise SinkError("the KITTI layout needs at least one camera and one LiDAR in the rig")
        name = f"{record.frame_index:06d}"
        camera, lidar, cam_labels = record.cameras[0], record.lidars[0], record.labels.cameras[0]
        points = np.column_stack([lidar.scan.xyz_lidar_m, lidar.scan.intensity]).astype("<f4")
        cam_SE3_ego = camera.spec.ego_SE3_cam.inverse()
        cam_SE3_lidar = cam_SE3_ego.compose(lidar.spec.ego_SE3_sensor)
        lidar_SE3_ego = lidar.spec.ego_SE3_sensor.inverse()
        P = np.hstack([camera.spec.K, np.zeros((3, 1))])
        lines = [_matrix_line(f"P{i}", P) for i in range(4)]
        lines += [_matrix_line("R0_rect", np.eye(3)), _matrix_line("Tr_velo_to_cam", cam_SE3_lidar.as_matrix()[:3]),
                  _matrix_line("Tr_imu_to_velo", lidar_SE3_ego.as_matrix()[:3])]  # fmt: skip
        return {
            f"image_2/{name}.png": images.png(0),
            f"velodyne/{name}.bin": points.tobytes(),
            f"label_2/{name}.txt": self._labels(record, cam_SE3_ego, cam_labels).encode(),
            f"calib/{name}.txt": ("\n".join(lines) + "\n").encode(),
        }

    def write(self, encoded: dict[str, bytes]) -> None:
        self._folder.write_files(encoded)

    @staticmethod
    def _labels(record: FrameRecord, cam_SE3_ego, cam_labels) -> str:  # type: ignore[no-untyped-def]
        labels, o = record.labels, record.labels.objects
        bottom = o.center_ego_m - np.column_stack([np.zeros((len(o), 2)), o.lwh_m[:, 2] / 2])
        location = cam_SE3_ego.transform_from(bottom)
        boxes = cam_labels.boxes
        rows = []
        for i in np.flatnonzero(np.isfinite(boxes.clipped_px[:, 0]) & labels.seen):
            kitti_type = KITTI_TYPES.get(SemanticClass(int(o.semantic_class[i])))
            if kitti_type is None:
                continue
            left, top, right, bottom_px = boxes.clipped_px[i]
            length, width, height = o.lwh_m[i]
            x, y, z = location[i]
            occluded = int(cam_labels.visibility.occluded[i])
            rows.append(
                f"{kitti_type} {boxes.truncated[i]:.2f} {occluded} {boxes.alpha_rad[i]:.2f} "
                f"{left:.2f} {top:.2f} {right:.2f} {bottom_px:.2f} {height:.2f} {width:.2f} {length:.2f} "
                f"{x:.2f} {y:.2f} {z:.2f} {boxes.rotation_y_rad[i]:.2f}"
            )
        return "".join(r + "\n" for r in rows)

    def close(self) -> None:
        self._folder.commit()

    def abort(self) -> None:
        self._folder.discard()
