"""Traffic lights and signs in the frame loop: the heads and plates join each frame's agents
(so they are cast, labelled and counted like any object), each head's state comes from its
traffic light's libsumo state at that step, and the cameras draw the heads' lamps and the
signs' faces."""

from __future__ import annotations

from dataclasses import fields, replace

import numpy as np

from cosim.state import WorldState
from gtgen.labels import FrameLabels
from gtgen.signals import SignalLabels, signal_labels
from networks.classes import SemanticClass
from networks.geometry import SE3
from networks.street import STREET_ID_BASE, StreetObject
from networks.vocabulary import Lamp, sign_kind
from sensors.agents import Agents
from sensors.camera import CameraOutput
from sensors.sensor import SensorOutput
from sensors.shading import street_faces


class StreetObjects:
    """The network's signal heads and sign plates, placed into frames."""

    def __init__(self, objects: tuple[StreetObject, ...]) -> None:
        self.objects = objects
        n = len(objects)
        self._centres = np.array([o.centre_map_m for o in objects], np.float64).reshape(n, 3)
        self._yaws = np.array([o.yaw_map_rad for o in objects], np.float64)
        self._lwh = np.array([o.lwh_m for o in objects], np.float64).reshape(n, 3)
        self._ids = np.array([o.object_id for o in objects], np.uint32)
        self._classes = np.array([o.semantic_class for o in objects], np.uint8)

    def get(self, object_id: int) -> StreetObject:
        return self.objects[object_id - STREET_ID_BASE]

    def join(self, state: WorldState, radius_m: float) -> WorldState:
        """``state`` with the heads and plates within ``radius_m`` of the ego among its agents."""
        if not self.objects:
            return state
        near = np.flatnonzero(np.linalg.norm(self._centres[:, :2] - state.ego.center_map_m[:2], axis=1) <= radius_m)
        if near.size == 0:
            return state
        n = near.size
        mine = Agents(self._ids[near], self._classes[near], self._centres[near], self._lwh[near], self._yaws[near],
                      np.zeros(n), np.zeros((n, 3)), np.zeros(n, np.bool_))  # fmt: skip
        a = state.agents
        joined = Agents(*(np.concatenate([getattr(a, f.name), getattr(mine, f.name)]) for f in fields(Agents)))
        return replace(state, agents=joined)

    def labels(self, labels: FrameLabels, state: WorldState) -> SignalLabels:
        """Subtype, state, lanes and ego-lane flag of every head and plate among the labelled objects."""
        return signal_labels(labels, self.objects, state.signal_states, state.ego_lane)

    def light_cameras(
        self, outputs: tuple[SensorOutput, ...], agents: Agents, state: WorldState, map_SE3_ego: SE3
    ) -> tuple[SensorOutput, ...]:
        """The outputs with each camera told where the heads and plates in the scene are, which
        lamps are lit and what each sign shows (its image draws them)."""
        street = np.isin(agents.semantic_class, [SemanticClass.TRAFFIC_LIGHT, SemanticClass.TRAFFIC_SIGN])
        mine = np.flatnonzero(street)
        if mine.size == 0:
            return outputs
        objects = [self.get(int(i)) for i in agents.instance_id[mine]]
        shows = [Lamp(o.state(state.signal_states)) if o.is_light else sign_kind(o.subtype) for o in objects]
        out: list[SensorOutput] = []
        for o in outputs:
            if isinstance(o, CameraOutput):
                cam_SE3_map = map_SE3_ego.compose(o.spec.ego_SE3_sensor).inverse()
                faces = street_faces(agents.instance_id[mine], agents.center_map_m[mine], agents.yaw_map_rad[mine],
                                     agents.lwh_m[mine], shows, cam_SE3_map)  # fmt: skip
                o = replace(o, frame=replace(o.frame, shading=replace(o.frame.shading, faces=faces)))
            out.append(o)
        return tuple(out)
