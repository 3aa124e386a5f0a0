"""Read a written dataset back: MCAP messages, point clouds and labels."""

from __future__ import annotations

import json
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import pandas as pd
from mcap.decoder import DecoderFactory as McapDecoderFactory
from mcap.reader import make_reader
from mcap_protobuf.decoder import DecoderFactory

from gtgen.mapgt import load_map_frame
from gtgen.objects import ObjectBoxes
from gtgen.sinks.foxglove import LIDAR_POINT_DTYPE, LIDAR_POINT_DTYPE_NO_TIME, RADAR_POINT_DTYPE
from gtgen.sinks.occupancy_messages import LIDAR_FLOW_DTYPE


class JsonDecoderFactory(McapDecoderFactory):
    """Decodes the JSON channels (``/gt/labels``) into Python objects."""

    def decoder_for(self, message_encoding: str, schema: Any) -> Callable[[bytes], Any] | None:
        return json.loads if message_encoding == "json" else None


def iter_messages(path: Path, topics: list[str] | None = None) -> Iterator[tuple[str, int, Any]]:
    """``(topic, log_time_ns, decoded message)`` in log-time order (protobuf or JSON)."""
    with path.open("rb") as stream:
        reader = make_reader(stream, decoder_factories=[DecoderFactory(), JsonDecoderFactory()])
        for _schema, channel, message, decoded in reader.iter_decoded_messages(topics=topics):
            yield channel.topic, message.log_time, decoded


def topics(path: Path) -> list[str]:
    """The topics of an MCAP file, in the order of their channels."""
    with path.open("rb") as stream:
        summary = make_reader(stream).get_summary()
    return [c.topic for c in summary.channels.values()] if summary is not None else []


def lidar_points(cloud: Any) -> npt.NDArray[np.void]:
    """A ``foxglove.PointCloud`` written by the MCAP sink as a structured array
    with fields x, y, z, intensity, ring, class, instance, t (seconds from the sweep's start;
    0 in files written before points had times), and flow_x, flow_y, flow_z in a run with occupancy."""
    if cloud.point_stride == LIDAR_FLOW_DTYPE.itemsize:  # a run with occupancy: scene flow_x, flow_y, flow_z too
        return np.frombuffer(cloud.data, dtype=LIDAR_FLOW_DTYPE)
    if cloud.point_stride == LIDAR_POINT_DTYPE_NO_TIME.itemsize:
        old = np.frombuffer(cloud.data, dtype=LIDAR_POINT_DTYPE_NO_TIME)
        out = np.zeros(old.shape[0], LIDAR_POINT_DTYPE)
        for name in LIDAR_POINT_DTYPE_NO_TIME.names or ():
            out[name] = old[name]
        return out
    if cloud.point_stride != LIDAR_POINT_DTYPE.itemsize:
        raise ValueError(f"point stride {cloud.point_stride} is not the LiDAR layout ({LIDAR_POINT_DTYPE.itemsize})")
    return np.frombuffer(cloud.data, dtype=LIDAR_POINT_DTYPE)


def radar_points(cloud: Any) -> npt.NDArray[np.void]:
    """A radar ``foxglove.PointCloud`` as a structured array (see ``RADAR_POINT_DTYPE``)."""
    if cloud.point_stride != RADAR_POINT_DTYPE.itemsize:
        raise ValueError(f"point stride {cloud.point_stride} is not the radar layout ({RADAR_POINT_DTYPE.itemsize})")
    return np.frombuffer(cloud.data, dtype=RADAR_POINT_DTYPE)


def load_labels(path: Path) -> pd.DataFrame:
    """``labels.csv`` as a table (``hazard_event``, ``indicator`` and ``subtype`` as text,
    empty: NaN)."""
    return pd.read_csv(path, dtype={"hazard_event": str, "indicator": str, "subtype": str})


def objects_from_table(rows: pd.DataFrame) -> tuple[ObjectBoxes, npt.NDArray[np.bool_]]:
    """Label rows (``labels.csv`` columns) as ego-frame boxes and their ``seen`` flags (tables
    without ``pitch`` and ``roll`` columns, from earlier versions, give level boxes)."""
    level = np.zeros(len(rows))
    boxes = ObjectBoxes(
        rows["id"].to_numpy(),
        rows["class_id"].to_numpy(),
        rows[["x", "y", "z"]].to_numpy(),
        rows[["l", "w", "h"]].to_numpy(),
        rows["rotation_z"].to_numpy(),
        rows["pitch"].to_numpy(np.float64) if "pitch" in rows else level,
        rows["roll"].to_numpy(np.float64) if "roll" in rows else level,
        rows[["vx", "vy", "vz"]].to_numpy(),
        rows["parked"].to_numpy().astype(bool),
    )
    return boxes, rows["seen"].to_numpy().astype(bool)


__all__ = [
    "iter_messages",
    "lidar_points",
    "load_labels",
    "load_map_frame",
    "objects_from_table",
    "radar_points",
    "topics",
]


def load_occupancy(run_dir: Path, frame_index: int) -> dict[str, npt.NDArray[Any]]:
    """A frame's ``occupancy/NNNNNN/labels.npz`` as arrays by name (see
    :mod:`gtgen.sinks.occupancy_sink`): ``semantics``, ``mask_lidar``, ``mask_camera``, ``flow``..."""
    with np.load(run_dir / "occupancy" / f"{frame_index:06d}" / "labels.npz") as data:
        return {name: data[name] for name in data.files}
