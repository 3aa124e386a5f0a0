"""Errors raised while building or loading road networks and the static world."""


class NetworkError(Exception):
    """A road network or static world could not be built or loaded."""


class NetconvertError(NetworkError):
    """netconvert rejected an input network."""


class ToolNotFoundError(NetworkError):
    """A SUMO tool (netconvert, randomTrips) is missing from the installation."""


class SumoRefusedError(NetworkError):
    """SUMO does not load a network the project wrote."""
