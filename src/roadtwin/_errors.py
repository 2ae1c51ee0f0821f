"""Exceptions raised by roadtwin.

Every error a user can cause by feeding bad input is an :class:`InputError`; the CLI
turns it into one line on stderr and exit code 2. A fit that cannot succeed on valid
input is a :class:`FitError`.
"""

from __future__ import annotations


class RoadtwinError(Exception):
    """Base class of all roadtwin errors."""


class InputError(RoadtwinError, ValueError):
    """Bad user input: the message names the file, row or field and what was expected."""


class FitError(RoadtwinError, RuntimeError):
    """A fit failed on input that was valid in form (too few points, degenerate geometry)."""


class InputWarning(UserWarning):
    """Input was usable but suspicious (points dropped, no ramps possible, ...)."""
