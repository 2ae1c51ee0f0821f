"""National lane-marking styles and painted lines from OpenDRIVE road marks.

A road mark says *whether* a lane border is painted (``solid``, ``broken``, double lines,
``botts dots``; ``none``, ``curb``, ``grass`` are not paint); the dash pattern of broken
lines is national practice, so it comes from a :class:`MarkingStyle` preset:

======  ===================  =======================  ==================================
style   lane line dash/gap   auxiliary-lane line      source of the numbers
======  ===================  =======================  ==================================
de, at  6 m / 12 m           6 m / 6 m                RMS (DE) and RVS 05.02.13 (AT)
us      3.05 m / 9.15 m      0.9 m / 2.7 m            MUTCD 3A.06 (10 ft / 30 ft; dotted)
uk      2 m / 7 m            1 m / 1 m (approx.)      TSRGD diagrams 1005.1, 1010
fr      3 m / 10 m           3 m / 1.33 m             IISR T1 and T3 lines
======  ===================  =======================  ==================================

The numbers are the usual motorway values; every field can be overridden. Worn or
missing paint is simulated as random stretches without paint.
"""

from __future__ import annotations

from dataclasses import dataclass, fields, replace
from typing import TYPE_CHECKING

from .._errors import InputError

if TYPE_CHECKING:
    from .scenario import Markings


@dataclass(frozen=True)
class MarkingStyle:
    """How broken lines are painted (metres) and how much paint is worn off.

    ``aux_*`` is the pattern of a line next to an auxiliary (deceleration/acceleration)
    lane; ``worn_fraction`` of every painted line is missing, in stretches of
    ``worn_length_m`` (min, max); double lines are ``double_gap_m`` apart (edge to edge).
    """

    name: str = "de"
    dash_m: float = 6.0
    gap_m: float = 12.0
    aux_dash_m: float = 6.0
    aux_gap_m: float = 6.0
    dot_m: float = 0.1
    dot_gap_m: float = 1.1
    double_gap_m: float = 0.12
    worn_fraction: float = 0.02
    worn_length_m: tuple[float, float] = (5.0, 40.0)

    def __post_init__(self) -> None:
        for f in ("dash_m", "gap_m", "aux_dash_m", "aux_gap_m", "dot_m", "dot_gap_m"):
            if not getattr(self, f) > 0.0:
                raise InputError(f"marking style {self.name}: {f} must be > 0")
        if not 0.0 <= self.worn_fraction < 1.0:
            raise InputError(f"marking style {self.name}: worn_fraction must be in [0, 1)")
        lo, hi = self.worn_length_m
        if not 0.0 < lo <= hi:
            raise InputError(f"marking style {self.name}: worn_length_m must be 0 < min <= max")


def style_from_markings(
    markings: Markings, *, name: str, base: MarkingStyle | None = None
) -> MarkingStyle:
    """``base`` (default :class:`MarkingStyle`) painted with the dash patterns of a
    scenario's or a country's :class:`~roadtwin.simulate.scenario.Markings` (metres)."""
    return replace(
        base or MarkingStyle(),
        name=name,
        dash_m=markings.dash_m,
        gap_m=markings.gap_m,
        aux_dash_m=markings.aux_dash_m,
        aux_gap_m=markings.aux_gap_m,
    )


STYLES: dict[str, MarkingStyle] = {
    "de": MarkingStyle("de"),
    "at": MarkingStyle("at"),
    "us": MarkingStyle("us", dash_m=3.05, gap_m=9.15, aux_dash_m=0.9, aux_gap_m=2.7),
    "uk": MarkingStyle("uk", dash_m=2.0, gap_m=7.0, aux_dash_m=1.0, aux_gap_m=1.0),
    "fr": MarkingStyle("fr", dash_m=3.0, gap_m=10.0, aux_dash_m=3.0, aux_gap_m=1.33),
}
"""Preset styles by country code."""


def marking_style(name: str, **overrides: float) -> MarkingStyle:
    """The preset ``name`` (``de``, ``at``, ``us``, ``uk``, ``fr``) with fields overridden.

    Raises
    ------
    InputError
        Unknown preset or field.
    """
    key = name.lower()
    if key not in STYLES:
        raise InputError(f"marking style {name!r}: expected one of {sorted(STYLES)}")
    known = {f.name for f in fields(MarkingStyle)} - {"name"}
    unknown = set(overrides) - known
    if unknown:
        raise InputError(f"marking style: unknown fields {sorted(unknown)}; known {sorted(known)}")
    return replace(STYLES[key], **overrides)


PAINTED = {
    "solid": ("solid",),
    "broken": ("broken",),
    "solid solid": ("solid", "solid"),
    "broken broken": ("broken", "broken"),
    "solid broken": ("solid", "broken"),
    "broken solid": ("broken", "solid"),
    "botts dots": ("dots",),
}
"""Painted lines of each OpenDRIVE road-mark type, left line first (left of the border in
the road's +s direction); types not listed (none, curb, grass, edge, custom) are no paint."""


def dash_pattern(kind: str, style: MarkingStyle, *, aux: bool) -> tuple[float, float] | None:
    """``(dash, gap)`` of a painted line kind (None: continuous)."""
    if kind == "solid":
        return None
    if kind == "dots":
        return style.dot_m, style.dot_gap_m
    return (style.aux_dash_m, style.aux_gap_m) if aux else (style.dash_m, style.gap_m)
