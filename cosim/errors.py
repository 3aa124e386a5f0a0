"""Errors raised while loading scenarios or running the co-simulation."""


class CosimError(Exception):
    """A scenario could not be loaded or run."""


class ScenarioError(CosimError):
    """A scenario file or override is invalid; the message names the file and the key."""


class TrafficError(CosimError):
    """SUMO could not start or lost the ego vehicle."""


class Terminated(BaseException):
    """The process was asked to stop (SIGTERM): the run keeps what it wrote."""


class RunStoppedError(CosimError):
    """A run stopped before its last frame and kept the frames it wrote (``kept``)."""

    def __init__(self, message: str, kept: int, exit_code: int) -> None:
        super().__init__(message)
        self.kept = kept
        self.exit_code = exit_code
