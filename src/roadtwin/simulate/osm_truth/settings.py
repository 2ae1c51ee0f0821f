"""Settings of the OSM ground-truth generator: one frozen dataclass per concern.

Every number is metres, radians or a plain count unless its name says otherwise
(``_pct`` percent, ``_deg`` degrees). Defaults are realistic values for motorways in
Europe, North America and Australia; the per-country parts (lane widths, shoulders,
marking patterns) come from :mod:`.style` unless set here.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

from ..._errors import InputError


@dataclass(frozen=True)
class ChainSelection:
    """Which carriageway of the extract becomes the mainline.

    Exactly one of ``way_id`` / ``ref`` may be set; neither picks the longest one-way
    motorway/trunk chain of the extract. ``direction`` (with ``ref``) is a compass bearing
    in degrees (0 north, 90 east) or one of ``N E S W NE NW SE SW``: the chain whose
    overall bearing is closest wins. ``start_m`` / ``length_m`` crop a window out of the
    chain (stations along the OSM line); ``length_m=None`` keeps up to ``max_length_m``.
    """

    way_id: int | None = None
    ref: str | None = None
    direction: str | float | None = None
    start_m: float = 0.0
    length_m: float | None = None
    max_length_m: float = 12_000.0
    min_length_m: float = 600.0

    def __post_init__(self) -> None:
        if self.way_id is not None and self.ref is not None:
            msg = "ChainSelection: give way_id or ref, not both"
            raise InputError(msg)
        if self.start_m < 0 or (self.length_m is not None and self.length_m <= 0):
            msg = "ChainSelection: start_m must be >= 0 and length_m > 0"
            raise InputError(msg)


@dataclass(frozen=True)
class CrossSection:
    """Lane and shoulder widths (``None`` = the country's value from :mod:`.style`).

    Lane widths wander slowly along the road (``width_wander_m`` amplitude, wavelengths
    ``wander_wavelength_m``), clipped to ``[min_lane_width_m, max_lane_width_m]``. The hard
    shoulder wanders too and is missing on ``shoulder_gaps`` stretches of
    ``shoulder_gap_length_m`` (chosen at random away from ramps), tapering out and back
    over ``shoulder_taper_m``.
    """

    lane_width_m: float | None = None
    ramp_lane_width_m: float | None = None
    inner_shoulder_m: float | None = None
    hard_shoulder_m: float | None = None
    ramp_inner_shoulder_m: float = 1.0
    ramp_hard_shoulder_m: float = 2.0
    min_lane_width_m: float = 3.0
    max_lane_width_m: float = 3.75
    width_wander_m: float = 0.12
    shoulder_wander_m: float = 0.25
    wander_wavelength_m: tuple[float, float] = (400.0, 1500.0)
    shoulder_gaps: tuple[int, int] = (0, 2)
    shoulder_gap_length_m: tuple[float, float] = (150.0, 450.0)
    shoulder_taper_m: float = 60.0
    default_lanes: dict[str, int] = field(
        default_factory=lambda: {"motorway": 2, "trunk": 2, "motorway_link": 1, "trunk_link": 1}
    )
    """Lane count of a way without a usable ``lanes`` tag (OSM's convention: a link is 1)."""

    def __post_init__(self) -> None:
        if not 0 < self.min_lane_width_m <= self.max_lane_width_m:
            msg = "CrossSection: need 0 < min_lane_width_m <= max_lane_width_m"
            raise InputError(msg)


@dataclass(frozen=True)
class LaneEvents:
    """Lane additions, drops and auxiliary lanes.

    A deceleration lane opens ``decel_length_m`` before an exit gore (of which
    ``decel_taper_m`` is the taper); an acceleration lane ends ``accel_length_m`` after an
    entry gore (``accel_taper_m`` taper). An entry followed by an exit on the same side
    within ``weave_max_m`` gets one continuous auxiliary (weaving) lane instead. A lane
    whose ``lanes`` tag ends without a ramp tapers out over ``drop_taper_m``; a lane that
    starts without a ramp opens over ``gain_taper_m``. A tag change within
    ``event_snap_m`` of a gore belongs to that ramp (exit-only lane, lane gained at an
    entry). The shoulder beside a gore re-opens (closes) over ``gore_shoulder_taper_m``.
    A tagged lane count that holds for less than ``min_tag_segment_m`` (a short way of a
    bridge tagged differently from its neighbours) is a tagging slip, not a lane: it
    takes the count of its longer neighbour (real lanes open and close over hundreds of
    metres; such a blip made lanes open and close within 35 m, their borders knotted).
    """

    decel_length_m: float = 220.0
    decel_taper_m: float = 70.0
    accel_length_m: float = 260.0
    accel_taper_m: float = 90.0
    weave_max_m: float = 750.0
    drop_taper_m: float = 180.0
    gain_taper_m: float = 100.0
    event_snap_m: float = 120.0
    gore_shoulder_taper_m: float = 120.0
    min_tag_segment_m: float = 100.0


@dataclass(frozen=True)
class RampShape:
    """Ramp discovery and geometry.

    Link ways are followed away from the mainline for up to ``max_length_m``. A ramp
    leaves its gore tangentially to the lane border, bending away on a circle of
    ``diverge_radius_m`` until it is as far out as the shoulders opening in the gore need
    (plus ``gore_gap_m``), or further where the (displaced) OSM link is (a soft maximum
    over ``softmax_m``); once the link is ``switch_m`` from the mainline the ramp follows
    it. The curvature of every reference line is kept below
    ``1 / min_radius_m``. Gores within ``end_margin_m`` of the chain's ends are left out.
    """

    max_length_m: float = 450.0
    min_length_m: float = 60.0
    diverge_radius_m: float = 400.0
    switch_m: float = 25.0
    softmax_m: float = 2.0
    gore_gap_m: float = 0.5
    min_radius_m: float = 15.0
    end_margin_m: float = 120.0
    smooth_window_m: float = 25.0
    include_motorway_branches: bool = True
    """Other motorway/trunk ways leaving or joining the chain (motorway splits) are ramps."""


@dataclass(frozen=True)
class OsmOffset:
    """How far the OSM line is off the truth: a smooth seeded displacement field.

    The truth is the OSM geometry moved by a regional shift (the imagery offset a mapper
    traced on: ``shift_m`` magnitude range, random direction) plus a wander along the road
    (``wander_m`` amplitude, wavelengths ``wander_wavelength_m``), lateral and
    longitudinal, together limited to ``[min_m, max_m]``.
    """

    shift_m: tuple[float, float] = (1.5, 3.0)
    wander_m: float = 1.2
    wander_wavelength_m: tuple[float, float] = (250.0, 900.0)
    min_m: float = 1.0
    max_m: float = 5.0


@dataclass(frozen=True)
class Elevation:
    """Heights (OSM has none): grades of ``grade_pct`` range changing every
    ``grade_spacing_m``, joined by parabolic vertical curves of ``vertical_curve_m``;
    ramps climb or fall at most ``ramp_max_grade_pct`` and clear the mainline by at least
    ``clearance_m`` (plus ``structure_m`` deck thickness) where they cross it."""

    grade_pct: tuple[float, float] = (-3.5, 3.5)
    grade_spacing_m: tuple[float, float] = (600.0, 1600.0)
    vertical_curve_m: tuple[float, float] = (250.0, 500.0)
    ramp_grade_pct: tuple[float, float] = (-4.0, 4.0)
    ramp_max_grade_pct: float = 7.0
    clearance_m: float = 5.0
    structure_m: float = 1.2
    start_z_m: float = 0.0


@dataclass(frozen=True)
class OsmTruthSettings:
    """All settings of :func:`~roadtwin.simulate.osm_truth.truth_from_osm`.

    ``traffic`` / ``country`` override what the origin's country says (``"auto"``).
    ``junctions``: ``"default"`` (connecting roads, read by every consumer) or
    ``"direct"`` (OpenDRIVE 1.7+ direct junctions). ``junction_length_m`` is the length of
    the connecting roads of a default junction.
    """

    chain: ChainSelection = field(default_factory=ChainSelection)
    cross_section: CrossSection = field(default_factory=CrossSection)
    lanes: LaneEvents = field(default_factory=LaneEvents)
    ramps: RampShape = field(default_factory=RampShape)
    offset: OsmOffset = field(default_factory=OsmOffset)
    elevation: Elevation = field(default_factory=Elevation)
    traffic: Literal["auto", "right", "left"] = "auto"
    country: str = "auto"
    junctions: Literal["default", "direct"] = "default"
    junction_length_m: float = 12.0
    mainline_smooth_window_m: float = 120.0
    fit_tolerance_m: float = 0.01
