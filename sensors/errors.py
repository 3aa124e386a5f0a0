"""Errors raised by the sensor models."""


class SensorError(Exception):
    """A sensor could not be configured or could not produce a frame."""


class SensorConfigError(SensorError, ValueError):
    """A sensor specification is out of range."""
