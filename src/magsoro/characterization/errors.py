"""Errors raised by the characterisation tools."""

from magsoro.errors import MagsoroError


class CharacterizationDataError(MagsoroError, ValueError):
    """A measurement file (or in-memory data set) cannot be used as given.

    The message names the file and the column at fault, so the user can fix the data without reading code.
    It is also a :class:`ValueError`, since bad input values are what it reports.
    """
