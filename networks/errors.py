"""Errors raised while building or loading road networks and the static world, and how an
error line quotes what it was given."""

import reprlib


class NetworkError(Exception):
    """A road network or static world could not be built or loaded."""


class NetconvertError(NetworkError):
    """netconvert rejected an input network."""


class ToolNotFoundError(NetworkError):
    """A SUMO tool (netconvert, randomTrips) is missing from the installation."""


class SumoRefusedError(NetworkError):
    """SUMO does not load a network the project wrote."""


QUOTE_LIMIT = 200  # characters of a value an error line quotes
LINE_LIMIT = 2000  # characters of an error line


def _quoter() -> reprlib.Repr:
    quoter = reprlib.Repr()
    quoter.maxlevel, quoter.maxstring, quoter.maxother, quoter.maxlong = 2, 80, 80, 40
    quoter.maxlist = quoter.maxtuple = quoter.maxdict = quoter.maxset = quoter.maxfrozenset = 6
    return quoter


_QUOTER = _quoter()


def quoted(value: object, limit: int = QUOTE_LIMIT) -> str:
    """``repr(value)`` for an error line, at most ``limit`` characters: long strings and lists
    are cut (YAML aliases make a 40 KB file hold a value of 100 MB)."""
    text = _QUOTER.repr(value)
    return text if len(text) <= limit else text[: limit - 3] + "..."


def clipped(text: str, limit: int = LINE_LIMIT) -> str:
    """``text`` cut to ``limit`` characters, saying how long it was."""
    if len(text) <= limit:
        return text
    note = f"... ({len(text):,} characters)"
    return text[: max(limit - len(note), 0)] + note
