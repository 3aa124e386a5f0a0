"""``kitti/``: the KITTI object-detection layout as OpenPCDet and mmdetection3d read it, and
SemanticKITTI's point labels beside it.

``training/`` holds every frame, one file per frame named by frame index (``000000``):
``image_2`` (the first camera's shaded image, lossless PNG), ``image_3`` (the second camera's,
where the rig has one that fires every frame), ``velodyne`` (the first LiDAR's points as
float32 x, y, z, intensity in the LiDAR frame: x forward, y left, z up, like KITTI's
Velodyne), ``label_2``, ``calib`` and ``planes`` (the road plane under the ego in the camera
frame, KITTI's ``a b c d`` with the normal up). Labels list the objects whose projected box
overlaps the image and that some sensor saw; boxes and alpha follow KITTI's definitions,
``location`` is the bottom centre of the 3D box in the camera frame. A frame without such an
object gets one ``DontCare`` line of zero area (an empty file stops OpenPCDet's reader).

When the run closes, ``ImageSets/{train,val,test,trainval}.txt`` split the frames by
:mod:`gtgen.splits` (time blocks: the last 15 % test, the 15 % before val), and ``testing/``
holds the test frames again (hard links, no second copy; no ``label_2``), as KITTI's
test set. The former flat paths (``kitti/image_2``, ``kitti/label_2``, ...) are relative links
into ``training/``.

``training/labels/NNNNNN.label`` has one uint32 per ``velodyne`` point, as SemanticKITTI: the
class id of SemanticKITTI's label set in the low 16 bits, the track id (0 for the static
world) in the high 16 bits. ``training/poses.txt`` has one line per frame, the camera's pose
in the first frame's camera frame (3x4, row-major), and ``training/calib.txt`` the rig's
P0..P3 and Tr (LiDAR to camera), so that ``training/`` reads as a SemanticKITTI sequence
folder. Both are written as the frames come, so an interrupted run's are complete; a run that
continues an earlier one (``keep_frames``) keeps their first lines and needs the ego's pose
at the first frame.
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import numpy as np
import numpy.typing as npt

from gtgen.errors import SinkError
from gtgen.frame import FrameRecord
from gtgen.labels import CameraLabels
from gtgen.objects import EXPORT_MARGIN_M
from gtgen.sinks.folder import PartialFolder, cut_to, kept_lines
from gtgen.sinks.images import FrameImages
from gtgen.splits import SPLITS, split_units
from networks.classes import SemanticClass
from networks.geometry import SE3
from sensors.camera import CameraOutput

POSE_LINE = "poses.txt+"  # an encoded frame's line of poses.txt (appended, not a file of its own)
FRAME_FOLDERS = ("image_2", "image_3", "velodyne", "label_2", "calib", "planes", "labels")
TEST_FOLDERS = ("image_2", "image_3", "velodyne", "calib", "planes")  # KITTI's testing/ has no labels
FORMER_PATHS = ("image_2", "velodyne", "label_2", "calib", "labels", "poses.txt", "calib.txt")
DONT_CARE = "DontCare -1 -1 -10 0.00 0.00 0.00 0.00 -1 -1 -1 -1000 -1000 -1000 -10\n"

# KITTI's own types (Car, Van, Truck, Pedestrian, Person_sitting, Cyclist, Tram, Misc,
# DontCare): two-wheelers with their rider are Cyclist, a bus, a trailer and a construction
# vehicle are Misc (KITTI's "other vehicles"); traffic cones and barriers, which KITTI does
# not label, are DontCare regions (their 2D box only, so that a detector finding them is
# neither rewarded nor penalised). ``native``: the simulator's class names, every object with
# its 3D box.
KITTI_TYPES = {
    SemanticClass.CAR: "Car",
    SemanticClass.TRUCK: "Truck",
    SemanticClass.BUS: "Misc",
    SemanticClass.MOTORCYCLE: "Cyclist",
    SemanticClass.BICYCLE: "Cyclist",
    SemanticClass.PEDESTRIAN: "Pedestrian",
    SemanticClass.TRAILER: "Misc",
    SemanticClass.CONSTRUCTION_VEHICLE: "Misc",
    SemanticClass.TRAFFIC_CONE: "DontCare",
    SemanticClass.BARRIER: "DontCare",
}
NATIVE_TYPES = {cls: cls.label.capitalize() for cls in KITTI_TYPES}


# Our classes as SemanticKITTI's label ids (its semantic-kitti.yaml): bicycles and
# motorcycles include their riders, which SemanticKITTI would label bicyclist/motorcyclist;
# the curb goes with the sidewalk, crossings with the road; 1 "outlier" for spurious returns;
# trailers are SemanticKITTI's other-vehicle (20), construction vehicles its truck (18), traffic
# cones and barriers its other-object (99).
SEMANTIC_KITTI_IDS = {
    SemanticClass.NONE: 1,
    SemanticClass.ROAD: 40,
    SemanticClass.CROSSING: 40,
    SemanticClass.SIDEWALK: 48,
    SemanticClass.CURB: 48,
    SemanticClass.BUILDING: 50,
    SemanticClass.VEGETATION: 70,
    SemanticClass.POLE: 80,
    SemanticClass.TERRAIN: 72,
    SemanticClass.CAR: 10,
    SemanticClass.TRUCK: 18,
    SemanticClass.BUS: 13,
    SemanticClass.MOTORCYCLE: 15,
    SemanticClass.BICYCLE: 11,
    SemanticClass.PEDESTRIAN: 30,
    SemanticClass.TRAILER: 20,
    SemanticClass.CONSTRUCTION_VEHICLE: 18,
    SemanticClass.TRAFFIC_CONE: 99,
    SemanticClass.BARRIER: 99,
    SemanticClass.LANE_MARKING: 60,
    SemanticClass.LANE_MARKING_YELLOW: 60,
    SemanticClass.TRAFFIC_LIGHT: 81,  # SemanticKITTI has no traffic-light class: with the signs
    SemanticClass.TRAFFIC_SIGN: 81,
    SemanticClass.FENCE: 51,
    SemanticClass.OTHER_OBJECT: 99,
    SemanticClass.TRUNK: 71,
    SemanticClass.PARKING: 44,
}
INSTANCE_MASK = np.uint32(0x7FFF)  # SemanticKITTI instance ids: the track id modulo 32,768
SEMANTIC_KITTI_LUT = np.zeros(256, np.uint32)  # 0 "unlabeled" for any class not listed
for _cls, _id in SEMANTIC_KITTI_IDS.items():
    SEMANTIC_KITTI_LUT[int(_cls)] = _id


def semantic_kitti_labels(
    semantic_class: npt.NDArray[np.uint8], instance_id: npt.NDArray[np.uint32]
) -> npt.NDArray[np.uint32]:
    """``(N,) uint32`` SemanticKITTI point labels: label id | (instance mod 32,768) << 16. The
    instance stays under 2^15: SemanticKITTI's panoptic evaluation (semantic-kitti-api,
    ``auxiliary/eval_np.py``) multiplies a label by 2^32 in int64 and overflows from 2^31 on."""
    return np.asarray(SEMANTIC_KITTI_LUT[semantic_class] | ((instance_id.astype(np.uint32) & INSTANCE_MASK) << 16))


def _matrix_line(name: str, m: np.ndarray) -> str:
    return f"{name}: " + " ".join(f"{v:.12e}" for v in np.asarray(m, dtype=np.float64).ravel())


def road_plane_line(cam_SE3_ego: SE3) -> str:
    """``planes/NNNNNN.txt``: the ego's ground plane (the road under it) in the camera frame,
    ``a x + b y + c z + d = 0`` with the normal up (b < 0 for a level camera), as KITTI's."""
    normal = cam_SE3_ego.rotation[:, 2]
    d = -float(normal @ cam_SE3_ego.translation)
    values = " ".join(f"{v:.6e}" for v in (*normal, d))
    return f"# Matrix\nWIDTH 4\nHEIGHT 1\n{values}\n"


def image_sets(frames: list[str]) -> dict[str, str]:
    """``ImageSets/*.txt`` for these frame names in order: train, val, test (see
    :mod:`gtgen.splits`) and trainval."""
    by_split: dict[str, list[str]] = {split: [] for split in SPLITS}
    for name, split in zip(frames, split_units(len(frames)), strict=True):
        by_split[split].append(name)
    by_split["trainval"] = by_split["train"] + by_split["val"]
    return {split: "".join(f"{n}\n" for n in names) for split, names in by_split.items()}


class KittiSink:
    def __init__(
        self, folder: Path, keep_frames: int = 0, first_map_SE3_ego: SE3 | None = None, native_types: bool = False,
        image_3: bool = False,
    ) -> None:  # fmt: skip
        self._types = NATIVE_TYPES if native_types else KITTI_TYPES
        if keep_frames > 0 and first_map_SE3_ego is None:
            raise SinkError("kitti: continuing a run needs the ego's pose at its first frame")
        self._image_3 = image_3
        folders = tuple(f"training/{f}" for f in FRAME_FOLDERS if image_3 or f != "image_3")
        self._folder = PartialFolder(folder, folders, keep_frames)
        _remove_derived(self._folder.partial)
        self._first_map_SE3_ego = first_map_SE3_ego
        self._first_map_SE3_cam: SE3 | None = None
        poses = self._folder.partial / "training" / "poses.txt"
        if keep_frames > 0 and poses.exists():  # cut in place: a full disk keeps the lines
            cut_to(poses, kept_lines(poses, keep_frames))
        else:
            self._folder.write_files({"training/poses.txt": b""})
        self._calib_written = keep_frames > 0 and (self._folder.partial / "training" / "calib.txt").exists()

    def encode(self, record: FrameRecord, images: FrameImages) -> dict[str, bytes]:
        """The frame's files, by path relative to the ``kitti`` folder."""
        if not record.cameras or not record.lidars:
            raise SinkError("the KITTI layout needs at least one camera and one LiDAR in the rig")
        name = f"{record.frame_index:06d}"
        camera, lidar, cam_labels = record.cameras[0], record.lidars[0], record.labels.cameras[0]
        points = np.column_stack([lidar.scan.xyz_lidar_m, lidar.scan.intensity]).astype("<f4")
        cam_SE3_ego = camera.spec.ego_SE3_sensor.inverse()
        cam_SE3_lidar = cam_SE3_ego.compose(lidar.spec.ego_SE3_sensor)
        lidar_SE3_ego = lidar.spec.ego_SE3_sensor.inverse()
        second = record.cameras[1] if self._image_3 and len(record.cameras) > 1 else None
        P2 = camera.spec.pinhole.P
        P3 = P2 if second is None else second.spec.pinhole.K @ _cam_from(second, camera).as_matrix()[:3]
        lines = [_matrix_line(f"P{i}", P) for i, P in enumerate((P2, P2, P2, P3))]
        sequence_calib = [*lines, _matrix_line("Tr", cam_SE3_lidar.as_matrix()[:3])]
        lines += [_matrix_line("R0_rect", np.eye(3)), _matrix_line("Tr_velo_to_cam", cam_SE3_lidar.as_matrix()[:3]),
                  _matrix_line("Tr_imu_to_velo", lidar_SE3_ego.as_matrix()[:3])]  # fmt: skip
        map_SE3_cam = record.map_SE3_ego.compose(camera.spec.ego_SE3_sensor)
        if self._first_map_SE3_cam is None:
            first = record.map_SE3_ego if self._first_map_SE3_ego is None else self._first_map_SE3_ego
            self._first_map_SE3_cam = first.compose(camera.spec.ego_SE3_sensor)
        pose = self._first_map_SE3_cam.inverse().compose(map_SE3_cam).as_matrix()[:3]
        point_labels = semantic_kitti_labels(lidar.scan.semantic_class, lidar.scan.instance_id).astype("<u4")
        label_text = self._labels(record, cam_SE3_ego, cam_labels, self._types) or DONT_CARE
        files = {
            f"training/image_2/{name}.png": images.png(0),
            f"training/velodyne/{name}.bin": points.tobytes(),
            f"training/labels/{name}.label": point_labels.tobytes(),
            f"training/label_2/{name}.txt": label_text.encode(),
            f"training/calib/{name}.txt": ("\n".join(lines) + "\n").encode(),
            f"training/planes/{name}.txt": road_plane_line(cam_SE3_ego).encode(),
            POSE_LINE: (" ".join(f"{v:.12e}" for v in pose.ravel()) + "\n").encode(),
        }
        if second is not None:
            files[f"training/image_3/{name}.png"] = images.png(1)
        if not self._calib_written:
            self._calib_written = True
            files["training/calib.txt"] = ("\n".join(sequence_calib) + "\n").encode()
        return files

    def write(self, encoded: dict[str, bytes]) -> None:
        files = dict(encoded)
        pose = files.pop(POSE_LINE)
        self._folder.write_files(files)
        self._folder.append_file("training/poses.txt", pose)

    @staticmethod
    def _labels(
        record: FrameRecord, cam_SE3_ego: SE3, cam_labels: CameraLabels, types: dict[SemanticClass, str]
    ) -> str:
        """One line per object the camera's image holds and a sensor saw. The 3D box (metres,
        4 decimals) is the box turned by yaw only that holds the object's box (KITTI has no
        pitch or roll: on a slope it is longer and taller than the object), grown by
        ``EXPORT_MARGIN_M`` on every side and lifted by it; the 2D box, truncation and alpha keep
        KITTI's 2 decimals."""
        labels, o = record.labels, record.labels.objects
        upright = o.upright_lwh_m()
        lifted_bottom = upright[:, 2] / 2 - EXPORT_MARGIN_M
        location = cam_SE3_ego.transform_from(o.center_ego_m - np.column_stack([np.zeros((len(o), 2)), lifted_bottom]))
        dims = upright + np.array([2 * EXPORT_MARGIN_M, 2 * EXPORT_MARGIN_M, 0.0])
        boxes = cam_labels.boxes
        rows = []
        for i in np.flatnonzero(np.isfinite(boxes.clipped_px[:, 0]) & labels.seen):
            kitti_type = types.get(SemanticClass(int(o.semantic_class[i])))
            if kitti_type is None:
                continue
            left, top, right, bottom_px = boxes.clipped_px[i]
            length, width, height = dims[i]
            x, y, z = location[i]
            occluded = int(cam_labels.visibility.occluded[i])
            if kitti_type == "DontCare":  # a region: KITTI's DontCare lines carry no 3D box
                rows.append(
                    f"DontCare -1 -1 -10 {left:.2f} {top:.2f} {right:.2f} {bottom_px:.2f} -1 -1 -1 "
                    "-1000 -1000 -1000 -10"
                )
                continue
            rows.append(
                f"{kitti_type} {boxes.truncated[i]:.2f} {occluded} {boxes.alpha_rad[i]:.2f} "
                f"{left:.2f} {top:.2f} {right:.2f} {bottom_px:.2f} {height:.4f} {width:.4f} {length:.4f} "
                f"{x:.4f} {y:.4f} {z:.4f} {boxes.rotation_y_rad[i]:.4f}"
            )
        return "".join(r + "\n" for r in rows)

    def close(self) -> None:
        if not self._calib_written:
            self._folder.write_files({"training/calib.txt": b""})
        _write_derived(self._folder.partial)
        self._folder.commit()

    def abort(self) -> None:
        self._folder.discard()

    def keep(self) -> None:
        pass  # each frame's files are written whole


def _cam_from(camera: CameraOutput, reference: CameraOutput) -> SE3:
    """``cam_SE3_reference``: the reference camera's frame in this camera's."""
    return camera.spec.ego_SE3_sensor.inverse().compose(reference.spec.ego_SE3_sensor)


def _remove_derived(root: Path) -> None:
    """What :func:`_write_derived` makes from the frames, removed before frames change."""
    shutil.rmtree(root / "testing", ignore_errors=True)
    shutil.rmtree(root / "ImageSets", ignore_errors=True)
    for name in FORMER_PATHS:
        if (root / name).is_symlink():
            (root / name).unlink()


def _write_derived(root: Path) -> None:
    """``ImageSets/``, ``testing/`` (hard links of the test frames) and the former flat paths
    as links into ``training/``, from the frames under ``training/``."""
    _remove_derived(root)
    training = root / "training"
    frames = sorted(p.stem for p in (training / "velodyne").glob("*.bin"))
    sets = image_sets(frames)
    (root / "ImageSets").mkdir()
    for split, text in sets.items():
        (root / "ImageSets" / f"{split}.txt").write_text(text)
    for folder in TEST_FOLDERS:
        if not (training / folder).is_dir():
            continue
        (root / "testing" / folder).mkdir(parents=True)
        for name in sets["test"].split():
            for source in (training / folder).glob(f"{name}.*"):
                _link(source, root / "testing" / folder / source.name)
    for name in FORMER_PATHS:
        if (training / name).exists():
            (root / name).symlink_to(Path("training") / name)


def _link(source: Path, target: Path) -> None:
    try:
        os.link(source, target)
    except OSError:
        shutil.copy2(source, target)
