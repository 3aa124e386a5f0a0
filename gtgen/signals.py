"""Labels of traffic lights and signs: each one's subtype (signal_head, stop, yield,
speed_limit_<km/h>), the state a signal head shows in a frame, which lanes it governs and
whether the ego's lane is one of them. Row-aligned with the heads and plates among the frame's
labelled objects (classes traffic_light, traffic_sign); their boxes and visibility are in the
label table."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from gtgen.labels import FrameLabels
from gtgen.table import CLASS_NAMES
from networks.classes import SemanticClass
from networks.records import check_arrays
from networks.street import STREET_ID_BASE, StreetObject
from networks.vocabulary import Lamp, SignalState

SIGNAL_COLUMNS = [
    "frame", "timestamp", "id", "type", "subtype", "junction", "state", "governs_ego_lane", "lanes", "distance",
    "camera_visible_px", "visible_fraction", "seen",
]  # fmt: skip

# Box colours by state (RGB 0..1), in /gt/boxes and the summary pictures.
STATE_RGB = {Lamp.RED: (1.0, 0.1, 0.1), Lamp.YELLOW: (1.0, 0.85, 0.0), Lamp.GREEN: (0.1, 1.0, 0.3),
             Lamp.RED_YELLOW: (1.0, 0.5, 0.0), Lamp.OFF: (0.5, 0.5, 0.5)}  # fmt: skip


@dataclass(frozen=True, slots=True)
class SignalLabels:
    """``track_id: (N,) uint32`` the objects' ids; per object its subtype, its junction (SUMO
    traffic light id; '' for a sign), the state shown (red, yellow, green, red_yellow, off; ''
    for a sign), the lanes it governs (SUMO lane ids, space-separated) and ``governs_ego_lane:
    (N,) bool``."""

    track_id: npt.NDArray[np.uint32]
    subtype: tuple[str, ...]
    junction: tuple[str, ...]
    state: tuple[str, ...]
    lanes: tuple[str, ...]
    governs_ego_lane: npt.NDArray[np.bool_]

    def __post_init__(self) -> None:
        n = check_arrays(self, track_id=(np.uint32, ("N",)), governs_ego_lane=(np.bool_, ("N",))).get("N", 0)
        if not len(self.subtype) == len(self.junction) == len(self.state) == len(self.lanes) == n:
            raise ValueError("SignalLabels: subtype, junction, state and lanes need one entry per object")

    def __len__(self) -> int:
        return int(self.track_id.shape[0])

    @classmethod
    def empty(cls) -> SignalLabels:
        return cls(np.zeros(0, np.uint32), (), (), (), (), np.zeros(0, np.bool_))

    def state_of(self) -> dict[int, str]:
        """Head id -> the state it shows (signal heads only)."""
        return {int(i): s for i, s in zip(self.track_id.tolist(), self.state, strict=True) if s}


def signal_labels(
    labels: FrameLabels,
    objects: Sequence[StreetObject],
    signal_states: Mapping[str, Sequence[SignalState]],
    ego_lane: str,
) -> SignalLabels:
    """Subtype, state, lanes and ego-lane flag of every head and plate among the labelled
    objects (``objects``: the network's, in id order from :data:`STREET_ID_BASE`)."""
    o = labels.objects
    ids = o.track_id[np.isin(o.semantic_class, [SemanticClass.TRAFFIC_LIGHT, SemanticClass.TRAFFIC_SIGN])]
    mine = [objects[int(i) - STREET_ID_BASE] for i in ids]
    return SignalLabels(
        track_id=ids.astype(np.uint32),
        subtype=tuple(m.subtype for m in mine),
        junction=tuple(m.tls_id for m in mine),
        state=tuple(m.state(signal_states) for m in mine),
        lanes=tuple(" ".join(m.lanes) for m in mine),
        governs_ego_lane=np.array([ego_lane in m.lanes for m in mine], np.bool_),
    )


def signal_table(labels: FrameLabels, signals: SignalLabels) -> dict[str, npt.NDArray[np.generic]]:
    """The columns of :data:`SIGNAL_COLUMNS` for one frame (camera columns from the first camera)."""
    o = labels.objects
    order = np.argsort(o.track_id, kind="stable")
    rows = order[np.searchsorted(o.track_id[order], signals.track_id)] if len(signals) else np.zeros(0, np.intp)
    n = len(signals)
    first = labels.first_camera
    if first is not None:
        vis = first.visibility
        visible_px, fraction = vis.visible_px[rows], vis.fraction[rows]
    else:
        visible_px, fraction = np.full(n, np.nan), np.full(n, np.nan)
    return {
        "frame": np.full(n, labels.frame_index), "timestamp": np.full(n, labels.timestamp_ns / 1e9),
        "id": signals.track_id, "type": CLASS_NAMES[o.semantic_class[rows]],
        "subtype": np.asarray(signals.subtype, dtype=object).astype(str),
        "junction": np.asarray(signals.junction, dtype=object).astype(str),
        "state": np.asarray(signals.state, dtype=object).astype(str),
        "governs_ego_lane": signals.governs_ego_lane.astype(np.int8),
        "lanes": np.asarray(signals.lanes, dtype=object).astype(str),
        "distance": labels.distance_m[rows], "camera_visible_px": visible_px, "visible_fraction": fraction,
        "seen": labels.seen[rows].astype(np.int8),
    }  # fmt: skip
