"""Keeping big inputs linear.

Reading a map builds hundreds of thousands of small frozen dataclasses that never form
reference cycles. CPython's cyclic garbage collector still walks all live objects in its
older generations again and again while they are being created, which made reading and
checking a 120,000-road map grow faster than linearly. :func:`gc_paused` switches the
collector off for such a block (reference counting still frees everything).
"""

from __future__ import annotations

import gc
from collections.abc import Iterator
from contextlib import contextmanager

__all__ = ["gc_paused"]


@contextmanager
def gc_paused() -> Iterator[None]:
    """Disable the cyclic garbage collector inside the block (restored afterwards)."""
    was_enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if was_enabled:
            gc.enable()
