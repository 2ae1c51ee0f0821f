"""Modules bound now and imported on first use.

Some dependencies import a heavy module at import time for a feature a build never uses.
Binding a stand-in first keeps the cost out of the build, and anyone who does use the
feature in the same process (a notebook) gets the real module on first attribute access.
(``importlib.util.LazyLoader`` cannot do this: the ``import`` statement itself reads the
module's ``__spec__``, which loads it.)
"""

from __future__ import annotations

import importlib
import importlib.util
import sys
from types import ModuleType
from typing import Any


class _StandIn(ModuleType):
    """A module that imports the real one the first time an attribute it lacks is read,
    and forwards to it from then on."""

    def __getattr__(self, attribute: str) -> Any:
        real = self.__dict__.get("_real_module")
        if real is None:
            if sys.modules.get(self.__name__) is self:
                del sys.modules[self.__name__]
            real = importlib.import_module(self.__name__)
            self.__dict__["_real_module"] = real
        return getattr(real, attribute)


def bind_lazily(name: str) -> None:
    """Put a stand-in for the top-level module ``name`` into ``sys.modules`` unless it is
    imported already (or not installed): a later ``import name`` binds it at no cost, and
    the real module is imported when an attribute of it is first read."""
    if name in sys.modules:
        return
    spec = importlib.util.find_spec(name)
    if spec is None:
        return
    stand_in = _StandIn(name)
    stand_in.__spec__ = spec
    sys.modules[name] = stand_in
