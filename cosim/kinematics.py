"""SUMO's conventions -> the project's frames (pure functions, vectorised).

SUMO angles are degrees clockwise from north; positions are the front bumper at
ground level; slope is degrees, nose-up positive.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from networks.geometry import wrap_angle

F64 = npt.NDArray[np.float64]


def sumo_angle_to_yaw(angle_deg: npt.ArrayLike) -> F64:
    """Clockwise-from-north degrees -> counter-clockwise-from-east radians in [-pi, pi)."""
    return wrap_angle(np.radians(90.0 - np.asarray(angle_deg, dtype=np.float64)))


def heading_vectors(yaw_rad: npt.ArrayLike, pitch_rad: npt.ArrayLike) -> F64:
    """``(N, 3)`` unit forward vectors."""
    yaw = np.asarray(yaw_rad, dtype=np.float64)
    pitch = np.asarray(pitch_rad, dtype=np.float64)
    return np.stack([np.cos(pitch) * np.cos(yaw), np.cos(pitch) * np.sin(yaw), np.sin(pitch)], axis=-1)


def up_vectors(yaw_rad: npt.ArrayLike, pitch_rad: npt.ArrayLike) -> F64:
    """``(N, 3)`` unit up vectors of boxes pitched nose-up by ``pitch_rad``."""
    yaw = np.asarray(yaw_rad, dtype=np.float64)
    pitch = np.asarray(pitch_rad, dtype=np.float64)
    return np.stack([-np.sin(pitch) * np.cos(yaw), -np.sin(pitch) * np.sin(yaw), np.cos(pitch)], axis=-1)


def front_bumper_to_center(
    front_xyz_m: npt.ArrayLike, yaw_rad: npt.ArrayLike, pitch_rad: npt.ArrayLike, length_m: npt.ArrayLike,
    height_m: npt.ArrayLike,
) -> F64:  # fmt: skip
    """Box centres: half a length behind the front bumper, half a height above the ground."""
    front = np.asarray(front_xyz_m, dtype=np.float64).reshape(-1, 3)
    length = np.asarray(length_m, dtype=np.float64).reshape(-1, 1)
    height = np.asarray(height_m, dtype=np.float64).reshape(-1, 1)
    return front - heading_vectors(yaw_rad, pitch_rad) * length / 2.0 + up_vectors(yaw_rad, pitch_rad) * height / 2.0


SUMO_BLINKER_RIGHT, SUMO_BLINKER_LEFT, SUMO_BLINKER_EMERGENCY, SUMO_BRAKELIGHT = 1, 2, 4, 8
"""Bits of SUMO's vehicle signals (``libsumo.vehicle.getSignals``) read here."""
FLASH_HZ = 1.5
"""Indicators flash 90 times a minute (UN ECE R48 allows 60-120), lit half of each period."""


def lamps_of(
    sumo_signals: npt.ArrayLike, has_lamps: npt.ArrayLike, parked: npt.ArrayLike, time_s: float,
    track_id: npt.ArrayLike,
) -> npt.NDArray[np.uint8]:  # fmt: skip
    """``(N,)`` :class:`sensors.agents.Lamp` bits from SUMO's signals: lights on for vehicles
    with lamps that are not parked, brake lamps and indicators as SUMO sets them (hazard lights
    flash both sides), the indicators lit half of each 1/1.5 s period, each vehicle's period
    starting at its own phase (from its track id)."""
    from sensors.agents import Lamp

    sig = np.asarray(sumo_signals, np.int64)
    on = np.asarray(has_lamps, np.bool_) & ~np.asarray(parked, np.bool_)
    out = np.where(on, int(Lamp.LIGHTS), 0)
    out |= np.where(on & (sig & SUMO_BRAKELIGHT > 0), int(Lamp.BRAKE), 0)
    hazard = sig & SUMO_BLINKER_EMERGENCY > 0
    out |= np.where(on & ((sig & SUMO_BLINKER_LEFT > 0) | hazard), int(Lamp.LEFT), 0)
    out |= np.where(on & ((sig & SUMO_BLINKER_RIGHT > 0) | hazard), int(Lamp.RIGHT), 0)
    phase = (np.asarray(track_id, np.float64) * 0.618034) % 1.0
    lit = (time_s * FLASH_HZ + phase) % 1.0 < 0.5
    out |= np.where(on & lit & (out & (Lamp.LEFT | Lamp.RIGHT) > 0), int(Lamp.FLASH), 0)
    return np.asarray(out, np.uint8)
