"""Per-frame labels computed from the agents and the sensors' rays (numpy, all objects at once)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from gtgen.counting import count_hits, mask_counts_and_boxes
from gtgen.criticality import path_distance, time_to_collision
from gtgen.objects import ObjectBoxes
from gtgen.projection import CameraBoxes, camera_boxes
from gtgen.visibility import CameraVisibility, SilhouetteCaster, camera_visibility
from networks.geometry import SE3
from networks.records import check_arrays
from sensors.agents import Agents, EgoState
from sensors.camera import CameraOutput
from sensors.lidar import LidarOutput
from sensors.radar import RadarOutput
from sensors.sensor import SensorOutput


@dataclass(frozen=True, slots=True)
class CameraLabels:
    """One camera's view of the labelled objects, row-aligned with them."""

    name: str
    boxes: CameraBoxes
    visibility: CameraVisibility


@dataclass(frozen=True, slots=True)
class FrameLabels:
    """Labels of one frame: ``objects`` plus, per object, ``distance_m: (N,) float64``
    (horizontal, from the ego origin), ``lidar_points`` and ``radar_points: (N,) int32``
    summed over the sensors of that kind, ``seen: (N,) bool`` (a ray of some sensor hit the
    object: a LiDAR or radar return, or a visible camera pixel) and one :class:`CameraLabels`
    per camera that fired in the frame (each sensor fires at its own rate)."""

    frame_index: int
    timestamp_ns: int
    objects: ObjectBoxes
    distance_m: npt.NDArray[np.float64]
    lidar_points: npt.NDArray[np.int32]
    radar_points: npt.NDArray[np.int32]
    seen: npt.NDArray[np.bool_]
    cameras: tuple[CameraLabels, ...] = ()
    camera_names: tuple[str, ...] = ()  # every camera of the rig ('': those of ``cameras``)
    ttc_s: npt.NDArray[np.float64] | None = None  # time to collision with the ego (NaN: none); see criticality
    ego_lw_m: tuple[float, float] = (0.0, 0.0)  # the ego's footprint the time to collision is to
    path_distance_m: npt.NDArray[np.float64] | None = None  # to the ego's predicted path
    hazard_event: tuple[str, ...] = ()  # per object: the hazard event it is an actor of ('' none; () no hazards)

    @property
    def rig_cameras(self) -> tuple[str, ...]:
        """The names of the rig's cameras, in rig order (those that did not fire included)."""
        return self.camera_names or tuple(c.name for c in self.cameras)

    def camera(self, name: str) -> CameraLabels | None:
        """The labels of camera ``name`` in this frame (None: it did not fire)."""
        return next((c for c in self.cameras if c.name == name), None)

    @property
    def first_camera(self) -> CameraLabels | None:
        """The labels of the rig's first camera, if it fired in this frame."""
        names = self.rig_cameras
        return self.camera(names[0]) if names else None

    def __post_init__(self) -> None:
        n = len(self.objects)
        check_arrays(self, distance_m=(np.float64, (n,)), lidar_points=(np.int32, (n,)),
                     radar_points=(np.int32, (n,)), seen=(np.bool_, (n,)))  # fmt: skip

    def __len__(self) -> int:
        return len(self.objects)


def _hits(
    outputs: tuple[SensorOutput, ...], kind: type[LidarOutput | RadarOutput], track_ids: npt.NDArray[np.uint32]
) -> npt.NDArray[np.int32]:
    counts = [count_hits(o.scan.instance_id, track_ids) for o in outputs if isinstance(o, kind)]
    return sum(counts, np.zeros(track_ids.shape[0], np.int32))


def label_frame(
    frame_index: int,
    timestamp_ns: int,
    agents: Agents,
    ego: EgoState,
    outputs: tuple[SensorOutput, ...],
    scene: SilhouetteCaster,
    range_m: float,
    camera_names: tuple[str, ...] = (),
    events: Mapping[int, str] | None = None,
) -> FrameLabels:
    """Label every agent whose box centre lies within ``range_m`` of the ego, and every agent
    a sensor ray hit (a long bus can be hit while its centre is out of range). ``outputs`` are
    the outputs of the sensors that fired in the frame, ``scene`` the scene they were cast in,
    ``camera_names`` the rig's cameras (those that did not fire get no 2D labels this frame),
    ``events`` the hazard event of each actor's track id (None: the run makes no hazards)."""
    objects = ObjectBoxes.seen_from(ego, agents)
    distance = np.linalg.norm(objects.center_ego_m[:, :2], axis=1)
    lidar = _hits(outputs, LidarOutput, objects.track_id)
    radar = _hits(outputs, RadarOutput, objects.track_id)
    cameras = [o for o in outputs if isinstance(o, CameraOutput)]
    per_camera = [mask_counts_and_boxes(c.frame.instance_id, objects.track_id) for c in cameras]
    pixels = sum((px for px, _ in per_camera), np.zeros(len(objects), np.int32))
    seen = (lidar > 0) | (radar > 0) | (pixels > 0)
    keep = (distance <= range_m) | seen
    kept = objects.select(keep)
    map_SE3_ego = ego.map_SE3_ego()
    camera_labels = tuple(
        _camera_labels(camera, kept, map_SE3_ego, scene, px[keep], modal[keep])
        for camera, (px, modal) in zip(cameras, per_camera, strict=True)
    )
    p_xy, v_xy = kept.center_ego_m[:, :2], kept.velocity_ego_mps[:, :2]
    ego_lw = (float(ego.lwh_m[0]), float(ego.lwh_m[1]))
    ttc = time_to_collision(p_xy, v_xy, kept.yaw_ego_rad, kept.lwh_m[:, :2], np.array(ego_lw))
    near_path = path_distance(p_xy, float(np.linalg.norm(ego.velocity_map_mps[:2])))
    hazard = () if events is None else tuple(events.get(int(t), "") for t in kept.track_id)
    return FrameLabels(frame_index, timestamp_ns, kept, distance[keep], lidar[keep], radar[keep], seen[keep],
                       camera_labels, camera_names, ttc, ego_lw, near_path, hazard)  # fmt: skip


def _camera_labels(
    camera: CameraOutput, objects: ObjectBoxes, map_SE3_ego: SE3, scene: SilhouetteCaster,
    visible_px: npt.NDArray[np.int32], modal_px: npt.NDArray[np.float64],
) -> CameraLabels:  # fmt: skip
    spec, pinhole = camera.spec, camera.spec.pinhole
    boxes = camera_boxes(pinhole, spec.ego_SE3_sensor, objects)
    map_SE3_cam = map_SE3_ego.compose(spec.ego_SE3_sensor)
    visibility = camera_visibility(
        pinhole, map_SE3_cam, objects.track_id, boxes.clipped_px, camera.frame.instance_id, scene, visible_px,
        modal_px,
    )  # fmt: skip
    return CameraLabels(spec.name, boxes, visibility)
