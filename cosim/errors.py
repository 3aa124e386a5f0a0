"""Errors raised while loading scenarios or running the co-simulation."""


class CosimError(Exception):
    """A scenario could not be loaded or run."""


class ScenarioError(CosimError):
    """A scenario file or override is invalid; the message names the file and the key."""


class TrafficError(CosimError):
    """SUMO could not start or lost the ego vehicle."""
