"""Progress of long stages: library code reports it, whoever listens shows it.

Library code never prints (STYLE.md rule 8). A long stage wraps its work in
:func:`progress` and calls the returned ``advance(n)`` as it goes; without a listener that is
a no-op costing one function call. The CLI installs a listener with :func:`listening` (a
tqdm bar per stage, off with ``-q``; a log line per stage with ``-v``)::

    with progress("load road edges", total=n_points, unit="points") as advance:
        for chunk in chunks:
            ...
            advance(len(chunk))

The listener is held in a :class:`contextvars.ContextVar`, so threads and nested calls see
the listener of their own context.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from typing import Protocol

__all__ = ["ProgressBar", "ProgressListener", "listening", "progress"]


class ProgressBar(Protocol):
    """What a listener returns per stage (``tqdm`` objects qualify)."""

    def update(self, n: float = 1) -> object: ...

    def close(self) -> object: ...


ProgressListener = Callable[[str, "float | None", str], ProgressBar]
"""``listener(name, total, unit)`` -> a bar for the stage ``name`` (``total`` None: unknown)."""

_LISTENER: ContextVar[ProgressListener | None] = ContextVar("roadtwin_progress", default=None)


def _ignore(n: float = 1) -> None:
    return None


@contextmanager
def progress(
    name: str, *, total: float | None = None, unit: str = "it"
) -> Iterator[Callable[[float], object]]:
    """Report the progress of the stage ``name``; yields ``advance(n)``.

    Parameters
    ----------
    name
        Stage name as users read it (``"load road edges"``, ``"mainline"``).
    total
        Expected total of the ``advance`` steps, or None if unknown.
    unit
        Unit of the steps (``"points"``, ``"rows"``, ``"ramps"``).
    """
    listener = _LISTENER.get()
    if listener is None:
        yield _ignore
        return
    bar = listener(name, total, unit)
    try:
        yield bar.update
    finally:
        bar.close()


@contextmanager
def listening(listener: ProgressListener | None) -> Iterator[None]:
    """Send the :func:`progress` of stages run inside this block to ``listener``."""
    token = _LISTENER.set(listener)
    try:
        yield
    finally:
        _LISTENER.reset(token)
