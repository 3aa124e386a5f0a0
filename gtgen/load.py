"""Read a written dataset back: MCAP messages, point clouds and labels."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import pandas as pd
from mcap.reader import make_reader
from mcap_protobuf.decoder import DecoderFactory

from gtgen.sinks.mcap_sink import LIDAR_POINT_DTYPE


def iter_messages(path: Path, topics: list[str] | None = None) -> Iterator[tuple[str, int, Any]]:
    """``(topic, log_time_ns, decoded protobuf message)`` in log-time order."""
    with path.open("rb") as stream:
        reader = make_reader(stream, decoder_factories=[DecoderFactory()])
        for _schema, channel, message, decoded in reader.iter_decoded_messages(topics=topics):
            yield channel.topic, message.log_time, decoded


def lidar_points(cloud: Any) -> npt.NDArray[np.void]:
    """A ``foxglove.PointCloud`` written by the MCAP sink as a structured array
    with fields x, y, z, intensity, ring, class, instance."""
    if cloud.point_stride != LIDAR_POINT_DTYPE.itemsize:
        raise ValueError(f"point stride {cloud.point_stride} is not the LiDAR layout ({LIDAR_POINT_DTYPE.itemsize})")
    return np.frombuffer(cloud.data, dtype=LIDAR_POINT_DTYPE)


def load_labels(path: Path) -> pd.DataFrame:
    return pd.read_csv(path)
