"""The label table: one column per field, one row per labelled object of a frame.

CSV, JSON (MCAP ``/gt/labels``), KITTI and YOLO writers all read these columns, so a
field has one definition. The camera columns of ``COLUMNS`` come from the first camera of
the rig; every further camera adds its own, prefixed with its name (``rear_occluded``). A
camera that did not fire in a frame (each fires at its own rate) leaves its columns empty.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from gtgen.labels import FrameLabels
from networks.classes import SemanticClass
from sensors.agents import Lamp
from sensors.bodies import BODIES, body_of

REFERENCE_COLUMNS = [
    "frame", "timestamp", "id", "type", "alpha", "left", "top", "right", "bottom", "l", "w", "h", "x", "y", "z",
    "rotation_z", "vx", "vy", "vz", "truncated", "occluded",
]  # fmt: skip
CAMERA_EXTRA_COLUMNS = [
    "camera_visible_px", "visible_fraction", "visibility_bin", "modal_left", "modal_top", "modal_right", "modal_bottom",
]  # fmt: skip
EXTRA_COLUMNS = ["pitch", "roll", "class_id", "parked", "distance", "lidar_points", "radar_points",
                 *CAMERA_EXTRA_COLUMNS, "seen", "ttc", "ego_length", "ego_width", "path_distance",
                 "hazard_event", "brake_lamps", "indicator", "subtype"]  # fmt: skip
COLUMNS = REFERENCE_COLUMNS + EXTRA_COLUMNS

# Columns of every camera after the first: "<camera name>_<column>".
PER_CAMERA_COLUMNS = [
    "alpha", "left", "top", "right", "bottom", "truncated", "occluded", "visible_px", "visible_fraction",
    "visibility_bin", "modal_left", "modal_top", "modal_right", "modal_bottom",
]  # fmt: skip

INDICATOR_NAMES = np.array(["", "left", "right", "both"])
"""The ``indicator`` column by the Lamp.LEFT and Lamp.RIGHT bits (both: hazard lights)."""
CLASS_NAMES = np.array([SemanticClass(c).label if c in SemanticClass._value2member_map_ else "" for c in range(256)])


SUBTYPED = [int(SemanticClass.CAR), int(SemanticClass.TRUCK), int(SemanticClass.BUS)]


def subtypes(
    semantic_class: npt.NDArray[np.uint8], lwh_m: npt.NDArray[np.float64], track_id: npt.NDArray[np.uint32]
) -> npt.NDArray[np.str_]:
    """Each object's body type, the one the camera draws (:func:`sensors.bodies.body_of`): cars
    as sedan, hatchback, estate, suv, van or pickup (or, about 0.8 % each, police and
    ambulance), trucks as box_truck or semi_trailer, buses as city_bus or coach; empty for
    other classes."""
    out = np.full(len(track_id), "", dtype=object)
    for i in np.flatnonzero(np.isin(semantic_class, SUBTYPED)):
        c = int(semantic_class[i])
        out[i] = BODIES[c][body_of(c, lwh_m[i], int(track_id[i]))].name
    return np.asarray(out, dtype=str)


def label_table(labels: FrameLabels) -> dict[str, npt.NDArray[np.generic]]:
    o = labels.objects
    n = len(o)
    nan = np.full(n, np.nan)
    table: dict[str, npt.NDArray[np.generic]] = {
        "frame": np.full(n, labels.frame_index),
        "timestamp": np.full(n, labels.timestamp_ns / 1e9),
        "id": o.track_id,
        "type": CLASS_NAMES[o.semantic_class],
        "l": o.lwh_m[:, 0], "w": o.lwh_m[:, 1], "h": o.lwh_m[:, 2],
        "x": o.center_ego_m[:, 0], "y": o.center_ego_m[:, 1], "z": o.center_ego_m[:, 2],
        "rotation_z": o.yaw_ego_rad, "pitch": o.pitch_ego_rad, "roll": o.roll_ego_rad,
        "vx": o.velocity_ego_mps[:, 0], "vy": o.velocity_ego_mps[:, 1], "vz": o.velocity_ego_mps[:, 2],
        "class_id": o.semantic_class,
        "parked": o.parked.astype(np.int8),
        "distance": labels.distance_m,
        "lidar_points": labels.lidar_points,
        "radar_points": labels.radar_points,
        "seen": labels.seen.astype(np.int8),
        "ttc": nan if labels.ttc_s is None else labels.ttc_s,
        "ego_length": np.full(n, labels.ego_lw_m[0]), "ego_width": np.full(n, labels.ego_lw_m[1]),
        "path_distance": nan if labels.path_distance_m is None else labels.path_distance_m,
        "hazard_event": np.asarray(labels.hazard_event or ("",) * n, dtype=str),
        "brake_lamps": ((o.lamps & Lamp.BRAKE) > 0).astype(np.int8),
        "indicator": INDICATOR_NAMES[(o.lamps >> 2) & 3],
        "subtype": subtypes(o.semantic_class, o.lwh_m, o.track_id),
    }  # fmt: skip
    cam = labels.first_camera
    if cam is not None:
        table.update(
            alpha=cam.boxes.alpha_rad,
            left=cam.boxes.clipped_px[:, 0], top=cam.boxes.clipped_px[:, 1],
            right=cam.boxes.clipped_px[:, 2], bottom=cam.boxes.clipped_px[:, 3],
            truncated=cam.boxes.truncated,
            occluded=cam.visibility.occluded,
            camera_visible_px=cam.visibility.visible_px,
            visible_fraction=cam.visibility.fraction,
            visibility_bin=cam.visibility.visibility_bin,
            modal_left=cam.visibility.modal_px[:, 0], modal_top=cam.visibility.modal_px[:, 1],
            modal_right=cam.visibility.modal_px[:, 2], modal_bottom=cam.visibility.modal_px[:, 3],
        )  # fmt: skip
    else:
        for name in ("alpha", "left", "top", "right", "bottom", "truncated", "occluded", *CAMERA_EXTRA_COLUMNS):
            table[name] = nan
    ordered = {name: table[name] for name in COLUMNS}
    for name in labels.rig_cameras[1:]:
        other = labels.camera(name)
        if other is None:  # it did not fire in this frame
            ordered.update({f"{name}_{c}": nan for c in PER_CAMERA_COLUMNS})
            continue
        boxes, vis = other.boxes, other.visibility
        values = (boxes.alpha_rad, *boxes.clipped_px.T, boxes.truncated, vis.occluded, vis.visible_px, vis.fraction,
                  vis.visibility_bin, *vis.modal_px.T)  # fmt: skip
        ordered.update({f"{name}_{c}": v for c, v in zip(PER_CAMERA_COLUMNS, values, strict=True)})
    return ordered


def table_columns(labels: FrameLabels) -> list[str]:
    """The columns of :func:`label_table` for frames of this rig: ``COLUMNS``, then those of
    every camera after the first."""
    return COLUMNS + [f"{name}_{c}" for name in labels.rig_cameras[1:] for c in PER_CAMERA_COLUMNS]


def format_rows(table: dict[str, npt.NDArray[np.generic]]) -> list[str]:
    """CSV rows: floats with 4 decimals (timestamp 3), integers as such, NaN as empty."""
    columns = []
    for name, values in table.items():
        if values.dtype.kind == "f":
            decimals = 3 if name == "timestamp" else 4
            text = np.char.mod(f"%.{decimals}f", values)
            text = np.where(np.isfinite(values), text, "")
        else:
            text = values.astype(str)
        columns.append(text)
    if not columns or columns[0].shape[0] == 0:
        return []
    return [",".join(row) for row in zip(*columns, strict=True)]
