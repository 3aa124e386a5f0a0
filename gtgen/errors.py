"""Errors raised while labelling or writing a dataset."""


class GtgenError(Exception):
    """Labels could not be computed or a dataset could not be written."""


class SinkError(GtgenError):
    """An output writer failed (disk full, unwritable folder, ...)."""
