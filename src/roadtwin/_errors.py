"""Exceptions raised by roadtwin.

Every error a user can cause by feeding bad input is an :class:`InputError`; the CLI
turns it into one line on stderr and exit code 2. A fit that cannot succeed on valid
input is a :class:`FitError`.
"""

from __future__ import annotations

import re


class RoadtwinError(Exception):
    """Base class of all roadtwin errors."""


class InputError(RoadtwinError, ValueError):
    """Bad user input: the message names the file, row or field and what was expected."""


class FitError(RoadtwinError, RuntimeError):
    """A fit failed on input that was valid in form (too few points, degenerate geometry)."""


class InputWarning(UserWarning):
    """Input was usable but suspicious (points dropped, no ramps possible, ...)."""


def one_line(exc: BaseException | str) -> str:
    """An exception's text on one line (CLI errors are one line)."""
    return " ".join(str(exc).split())


_QUOTED = re.compile(r"""b?'[^']*'|b?"[^"]*\"""")


def reason(exc: BaseException, *, limit: int = 160) -> str:
    """A third-party parser's exception as a short reason that quotes no file content.

    Parsers put bytes of the file they choke on into their messages (``Invalid file
    signature "b'ROOT'"``); roadtwin's messages never repeat file content, so quoted parts
    become ``'...'`` and the text is cut to ``limit`` characters.
    """
    text = _QUOTED.sub("'...'", one_line(exc)) or type(exc).__name__
    return text if len(text) <= limit else text[: limit - 3] + "..."
