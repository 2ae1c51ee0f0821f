"""``roadtwin check``: find the faults users of generated OpenDRIVE maps complain about.

Own checks (:func:`check_network`, on the model):

* ``geometry_gap`` / ``geometry_kink``: position gap (mm) and heading jump (deg) between
  consecutive planView pieces of every road; ``geometry_s_mismatch`` when a piece's ``s``
  is not the previous piece's end station.
* ``link_gap`` / ``link_kink``: the same across every road link (road -> road, connecting
  road -> incoming/outgoing road, direct-junction incoming road -> linked road), using the
  contact points. Where the link carries lane links the gap is the largest distance between
  the inner and outer borders of the linked lanes (a ramp's reference line may start on a
  lane border of the mainline); otherwise it is the distance between the reference lines.
  The heading jump compares reference-line headings (reversed for end-to-end and
  start-to-start contacts).
* ``width_start``: a lane whose first width record does not start at the section's start.
* ``lane_dead_end`` (warning): a driving lane that ends (begins) at least
  ``dead_end_width_m`` wide at a lane-section border inside a road with no successor
  (predecessor): a lane that leaves at a gore without a junction, a drop without a taper.
* ``lane_shift``: a lane linked across a lane-section border whose inner or outer border
  moves there (thresholds of ``link_gap``).
* ``lane_offset_step`` (a warning): the lane offset steps at a lane-section border inside
  a road. Lanes may still meet there (a lane beside the centre widens by as much), but the
  ASAM checker evaluates the ending section with the offset record that begins at the
  border and reports gaps of the lanes linked across it
  (``contact_point_no_horizontal_gaps``); thresholds of ``link_gap``.
* ``lane_jump``: a lane border that jumps sideways inside a lane section, where a lane
  offset or width record begins whose value does not continue the one before it (a lane
  offset stepped a metre past a gore moved every lane 3 m there; esmini's car jumped);
  thresholds of ``link_gap``.
* ``lane_pinch``: a driving lane that narrows from at least ``pinch_wide_m`` to below
  ``pinch_narrow_m`` and widens back within ``pinch_length_m`` inside a lane section: two
  lanes swapping their space (a line modelled as tapering away from a neighbour that moved
  itself crossed the lane beside it; esmini's car jumped 1.6 m and stuck).
* ``lane_wide`` (a warning): a driving lane wider than ``wide_lane_m`` (6 m) anywhere,
  wider than any real lane: the lane structure was mis-inferred there (two lanes' space
  in one, or a shoulder taken for a lane).
* ``negative_width`` (sampled every metre in each lane section) and ``width_jump`` between
  consecutive lane sections for lanes that continue (lane links, or equal ids where a side
  has no links and the same lane count).
* ``dangling_link``: road/lane/junction references to things that do not exist.
* ``one_sided_link``: A names B as predecessor/successor but B does not name A (or A's
  junction) back at that contact point; a road linked to a junction the junction does not
  know.
* ``missing_lane_link``: a junction connection without ``laneLink``; a connecting road's
  lane without predecessor/successor where it has width.
* ``geo_reference``: missing (warning), not parseable by pyproj (error), ``+no_defs``
  (warning, esmini logs an error on it).

Thresholds (:class:`CheckConfig`): gaps above 1 mm are warnings, above 1 cm errors;
heading jumps above 0.01 deg are warnings, above 0.1 deg errors; width jumps above 1 mm are
warnings, above 1 cm errors; widths below -1 mm are errors (below -1 um, warnings).

External consumers (:func:`check_file`, run by :mod:`roadtwin.consumers`): SUMO
``netconvert --opendrive-files`` (errors on stderr, exit code 1 on fatal ones; skipped for
maps with ``direct`` junctions, which SUMO cannot read) and the ASAM quality checker
``qc_opendrive`` (XQAR result read with qc_baselib; issues counted per rule, level ERROR as
errors, WARNING and crashed checkers as warnings; a schema failure skips the later rules).
Each is looked up next to ``sys.executable`` first, then on ``PATH``; a missing one is
reported as ``not installed`` and the own checks still run.
"""

from __future__ import annotations

import logging
import math
import os
from collections import Counter
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np

from ._errors import InputError
from ._perf import gc_paused
from .consumers import ConsumerResult, find_tool, run_asam, run_sumo
from .model import Lane, LaneSection, Road, RoadNetwork
from .xodr import read_xodr

log = logging.getLogger(__name__)

__all__ = [
    "CheckConfig",
    "CheckReport",
    "ConsumerResult",
    "Finding",
    "check_file",
    "check_network",
    "find_tool",
    "network_stats",
    "run_asam",
    "run_sumo",
]

Severity = Literal["error", "warning"]


@dataclass(frozen=True)
class CheckConfig:
    """Thresholds of the own checks.

    Parameters
    ----------
    gap_warning_mm, gap_error_mm
        Position gap between consecutive pieces or across a link (default 1 mm / 10 mm).
    heading_warning_deg, heading_error_deg
        Heading jump (default 0.01 deg / 0.1 deg).
    width_jump_warning_mm, width_jump_error_mm
        Width change of a continuing lane between lane sections (default 1 mm / 10 mm).
    negative_width_error_mm
        Widths below minus this are errors, between it and 0 warnings (default 1 mm).
    width_sample_step_m
        Sampling step for the negative-width check (default 1 m).
    consumer_timeout_s
        Time limit of each external consumer run (default 600 s).
    """

    gap_warning_mm: float = 1.0
    gap_error_mm: float = 10.0
    heading_warning_deg: float = 0.01
    heading_error_deg: float = 0.1
    width_jump_warning_mm: float = 1.0
    width_jump_error_mm: float = 10.0
    negative_width_error_mm: float = 1.0
    zero_width_link_m: float = 1e-4
    """A lane end narrower than this (metres) counts as zero width: it must not be linked."""
    dead_end_width_m: float = 1.0
    """A driving lane ending (beginning) unlinked at least this wide (metres) is a dead end."""
    pinch_wide_m: float = 2.5
    """A driving lane at least this wide (metres) ... """
    pinch_narrow_m: float = 0.5
    """... narrower than this (metres) ..."""
    pinch_length_m: float = 30.0
    """... and as wide again within this (metres) is pinched (``lane_pinch``)."""
    wide_lane_m: float = 6.0
    """A driving lane wider than this (metres) is reported (``lane_wide``)."""
    width_sample_step_m: float = 1.0
    consumer_timeout_s: float = 600.0

    def __post_init__(self) -> None:
        if not 0 < self.gap_warning_mm <= self.gap_error_mm:
            msg = "CheckConfig: need 0 < gap_warning_mm <= gap_error_mm"
            raise InputError(msg)
        if not 0 < self.heading_warning_deg <= self.heading_error_deg:
            msg = "CheckConfig: need 0 < heading_warning_deg <= heading_error_deg"
            raise InputError(msg)
        if self.width_sample_step_m <= 0:
            msg = "CheckConfig: width_sample_step_m must be > 0"
            raise InputError(msg)
        if self.wide_lane_m <= 0:
            msg = "CheckConfig: wide_lane_m must be > 0"
            raise InputError(msg)


@dataclass(frozen=True)
class Finding:
    """One problem found in a map.

    ``road``/``junction`` name where, ``s`` the road station (metres) where known,
    ``value`` the measured number in the unit the ``code`` implies (mm, deg, m).
    """

    severity: Severity
    code: str
    message: str
    road: str | None = None
    junction: str | None = None
    s: float | None = None
    value: float | None = None

    def to_dict(self) -> dict:
        return {
            "severity": self.severity,
            "code": self.code,
            "road": self.road,
            "junction": self.junction,
            "s": self.s,
            "value": self.value,
            "message": self.message,
        }


@dataclass(frozen=True)
class CheckReport:
    """Everything ``roadtwin check`` found in one file."""

    path: str
    findings: tuple[Finding, ...]
    stats: dict[str, float | int]
    consumers: tuple[ConsumerResult, ...] = ()

    @property
    def errors(self) -> int:
        """Own errors plus every external consumer's errors."""
        own = sum(f.severity == "error" for f in self.findings)
        return own + sum(c.errors for c in self.consumers)

    @property
    def warnings(self) -> int:
        own = sum(f.severity == "warning" for f in self.findings)
        return own + sum(c.warnings for c in self.consumers)

    @property
    def ok(self) -> bool:
        """True when there are no errors."""
        return self.errors == 0

    def to_dict(self) -> dict:
        """Machine-readable report with stable keys."""
        return {
            "file": self.path,
            "ok": self.ok,
            "errors": self.errors,
            "warnings": self.warnings,
            "stats": dict(self.stats),
            "findings": [f.to_dict() for f in self.findings],
            "consumers": [c.to_dict() for c in self.consumers],
        }

    def format_text(self) -> str:
        """Human-readable report: summary lines, then one line per finding."""
        st = self.stats
        lines = [
            f"roadtwin check {self.path}",
            f"  roads {st['roads']:.0f} (connecting {st['connecting_roads']:.0f}), "
            f"junctions {st['junctions']:.0f}, geometry pieces {st['geometries']:.0f}, "
            f"lane sections {st['lane_sections']:.0f}, links {st['links_checked']:.0f}",
            f"  max gap between pieces {st['max_gap_mm']:.3f} mm, "
            f"max heading jump {st['max_heading_jump_deg']:.4f} deg",
            f"  max gap across links {st['max_link_gap_mm']:.3f} mm, "
            f"max heading jump across links {st['max_link_heading_jump_deg']:.4f} deg",
        ]
        for c in self.consumers:
            line = f"  {c.name}: {c.status}"
            if c.status in ("passed", "failed"):
                line += f" ({c.errors} errors, {c.warnings} warnings)"
            lines.append(line)
            lines.extend(f"    {m}" for m in c.messages[:20])
            if len(c.messages) > 20:
                lines.append(f"    ... {len(c.messages) - 20} more")
        for f in self.findings:
            where = []
            if f.road is not None:
                where.append(f"road {f.road}")
            if f.junction is not None:
                where.append(f"junction {f.junction}")
            if f.s is not None:
                where.append(f"s={f.s:.2f}")
            loc = f" [{', '.join(where)}]" if where else ""
            lines.append(f"  {f.severity.upper()} {f.code}{loc}: {f.message}")
        verdict = "OK" if self.ok else "FAILED"
        lines.append(f"{verdict}: {self.errors} errors, {self.warnings} warnings")
        return "\n".join(lines)


# ---------------------------------------------------------------------------
# helpers
# ---------------------------------------------------------------------------


def _wrap_deg(rad: float) -> float:
    return abs(math.degrees((rad + math.pi) % (2 * math.pi) - math.pi))


def _pose(road: Road, s: float) -> tuple[float, float, float]:
    x, y, h, _ = road.evaluate(np.array([s]))
    return float(x[0]), float(y[0]), float(h[0])


def _grade(value: float, warn: float, err: float) -> Severity | None:
    if value > err:
        return "error"
    if value > warn:
        return "warning"
    return None


def _section_at(road: Road, contact: str) -> LaneSection | None:
    if not road.lane_sections:
        return None
    return road.lane_sections[0] if contact == "start" else road.lane_sections[-1]


def _lane_ids(section: LaneSection | None) -> set[int]:
    if section is None:
        return set()
    return {lane.id for lane in (*section.left, *section.right)}


def _lane_border_points(road: Road, s: float, lane_id: int) -> np.ndarray:
    """Inner and outer border points ``(2, 2)`` of ``lane_id`` at station ``s``."""
    inner_id = lane_id - 1 if lane_id > 0 else lane_id + 1
    t = np.array(
        [
            road.lane_border_t(np.array([s]), inner_id)[0],
            road.lane_border_t(np.array([s]), lane_id)[0],
        ]
    )
    return road.to_xy(np.array([s, s]), t)


# ---------------------------------------------------------------------------
# own checks
# ---------------------------------------------------------------------------


class _Checker:
    def __init__(self, network: RoadNetwork, config: CheckConfig) -> None:
        self.net = network
        self.cfg = config
        self.findings: list[Finding] = []
        self.stats: dict[str, float | int] = {
            "max_gap_mm": 0.0,
            "max_heading_jump_deg": 0.0,
            "max_link_gap_mm": 0.0,
            "max_link_heading_jump_deg": 0.0,
            "roads": len(network.roads),
            "connecting_roads": sum(r.junction != "-1" for r in network.roads),
            "junctions": len(network.junctions),
            "direct_junctions": sum(j.type == "direct" for j in network.junctions),
            "geometries": sum(len(r.geometry) for r in network.roads),
            "lane_sections": sum(len(r.lane_sections) for r in network.roads),
            "links_checked": 0,
        }
        self._links_done: set[tuple] = set()

    def add(self, severity, code, message, **kw) -> None:
        self.findings.append(Finding(severity, code, message, **kw))

    # -- geometry ----------------------------------------------------------

    def geometry(self, road: Road) -> None:
        cfg = self.cfg
        for g in road.geometry:
            if not g.length > 0:
                self.add(
                    "error",
                    "geometry_length",
                    f"geometry piece at s={g.s0:.3f} has length {g.length} <= 0",
                    road=road.id,
                    s=g.s0,
                    value=g.length,
                )
        if abs(road.geometry[0].s0) > 1e-6:
            self.add(
                "warning",
                "geometry_s_mismatch",
                f"first geometry piece starts at s={road.geometry[0].s0:.6f}, not 0",
                road=road.id,
                s=road.geometry[0].s0,
                value=road.geometry[0].s0,
            )
        for a, b in zip(road.geometry[:-1], road.geometry[1:], strict=False):
            xa, ya, ha = a.end_pose()
            gap_mm = 1000.0 * math.hypot(b.x0 - xa, b.y0 - ya)
            kink = _wrap_deg(b.hdg - ha)
            self.stats["max_gap_mm"] = max(self.stats["max_gap_mm"], gap_mm)
            self.stats["max_heading_jump_deg"] = max(self.stats["max_heading_jump_deg"], kink)
            sev = _grade(gap_mm, cfg.gap_warning_mm, cfg.gap_error_mm)
            if sev:
                self.add(
                    sev,
                    "geometry_gap",
                    f"gap of {gap_mm:.1f} mm between geometry pieces at s={b.s0:.3f}",
                    road=road.id,
                    s=b.s0,
                    value=gap_mm,
                )
            sev = _grade(kink, cfg.heading_warning_deg, cfg.heading_error_deg)
            if sev:
                self.add(
                    sev,
                    "geometry_kink",
                    f"heading jumps by {kink:.4f} deg between geometry pieces at s={b.s0:.3f}",
                    road=road.id,
                    s=b.s0,
                    value=kink,
                )
            ds_mm = 1000.0 * abs(b.s0 - (a.s0 + a.length))
            if ds_mm > cfg.gap_warning_mm:
                self.add(
                    "error" if ds_mm > cfg.gap_error_mm else "warning",
                    "geometry_s_mismatch",
                    f"piece starts at s={b.s0:.4f} but the previous one ends at "
                    f"s={a.s0 + a.length:.4f} ({ds_mm:.1f} mm)",
                    road=road.id,
                    s=b.s0,
                    value=ds_mm,
                )

    # -- widths ------------------------------------------------------------

    def _lane_shift(self, road: Road, s: float, la: Lane, lb: Lane) -> None:
        """A lane linked across a lane-section border whose borders move there (an
        unlinked lane inside it changed width, the lane offset stepped): a car in it
        jumps sideways (ASAM contact_point_no_horizontal_gaps)."""
        before, at = np.array([max(s - 1e-7, 0.0)]), np.array([s])
        step = 1 if la.id > 0 else -1
        gaps = []
        for ida, idb in ((la.id, lb.id), (la.id - step, lb.id - step)):
            ta = (
                road.lane_border_t(before, ida)[0]
                if ida != 0
                else road.lane_offset.value(before)[0]
            )
            tb = road.lane_border_t(at, idb)[0] if idb != 0 else road.lane_offset.value(at)[0]
            gaps.append(abs(tb - ta))
        gap_mm = 1000.0 * float(np.nanmax(gaps))
        self._border_gap(
            "lane_shift",
            gap_mm,
            f"lane {la.id} -> {lb.id} moves sideways by {gap_mm:.1f} mm at the lane section "
            f"at s={s:.2f}",
            road,
            s,
        )

    def _border_gap(self, code: str, gap_mm: float, message: str, road: Road, s: float) -> None:
        """A finding ``code`` graded by the ``link_gap`` thresholds, where ``gap_mm`` (mm)
        reaches them."""
        sev = _grade(gap_mm, self.cfg.gap_warning_mm, self.cfg.gap_error_mm)
        if sev:
            self.add(sev, code, message, road=road.id, s=s, value=gap_mm)

    def widths(self, road: Road) -> None:
        cfg = self.cfg
        secs = road.lane_sections
        for sec, s_end in road.sections_with_ends():
            span = max(s_end - sec.s0, 0.0)
            n = max(2, math.ceil(span / cfg.width_sample_step_m) + 1)
            ds = np.linspace(0.0, span, n)
            for lane in (*sec.left, *sec.right):
                first = lane.width.pieces[0].s0 if lane.width.pieces else 0.0
                if first > 1e-6:
                    # the width is undefined before its first record: consumers differ
                    # (extrapolate, zero, refuse)
                    self.add(
                        "warning" if first < 1e-3 else "error",
                        "width_start",
                        f"lane {lane.id}'s first width record starts at sOffset {first:.4f} m, "
                        "not 0: its width is undefined before",
                        road=road.id,
                        s=float(sec.s0),
                        value=float(first),
                    )
                w = lane.width.value(ds)
                self._zero_width_links(road, sec, lane, w, ds)
                widest = int(np.argmax(w)) if lane.type == "driving" else -1
                if widest >= 0 and w[widest] > cfg.wide_lane_m:
                    self.add(
                        "warning",
                        "lane_wide",
                        f"driving lane {lane.id} is {w[widest]:.2f} m wide at "
                        f"s={sec.s0 + ds[widest]:.2f}: wider than any real lane",
                        road=road.id,
                        s=float(sec.s0 + ds[widest]),
                        value=float(w[widest]),
                    )
                k = int(np.argmin(w))
                if w[k] < -1e-6:
                    sev: Severity = (
                        "error" if w[k] < -cfg.negative_width_error_mm / 1000.0 else "warning"
                    )
                    self.add(
                        sev,
                        "negative_width",
                        f"lane {lane.id} has negative width {w[k]:.4f} m at s={sec.s0 + ds[k]:.2f}",
                        road=road.id,
                        s=float(sec.s0 + ds[k]),
                        value=float(w[k]),
                    )
        for k in range(len(secs) - 1):
            a, b = secs[k], secs[k + 1]
            len_a = b.s0 - a.s0
            for side_a, side_b in ((a.left, b.left), (a.right, b.right)):
                has_links = any(ln.successor is not None for ln in side_a) or any(
                    ln.predecessor is not None for ln in side_b
                )
                pairs: list[tuple[Lane, Lane]] = []
                by_id_b = {ln.id: ln for ln in side_b}
                by_id_a = {ln.id: ln for ln in side_a}
                if has_links:
                    for ln in side_a:
                        if ln.successor is not None and ln.successor in by_id_b:
                            pairs.append((ln, by_id_b[ln.successor]))
                    for ln in side_b:
                        if ln.predecessor is not None and ln.predecessor in by_id_a:
                            pair = (by_id_a[ln.predecessor], ln)
                            if pair not in pairs:
                                pairs.append(pair)
                elif len(side_a) == len(side_b):
                    pairs = [(ln, by_id_b[ln.id]) for ln in side_a if ln.id in by_id_b]
                for la, lb in pairs:
                    if has_links:
                        self._lane_shift(road, b.s0, la, lb)
                    wa = float(la.width.value(np.array([len_a]))[0])
                    wb = float(lb.width.value(np.array([0.0]))[0])
                    jump_mm = 1000.0 * abs(wa - wb)
                    sev = _grade(jump_mm, cfg.width_jump_warning_mm, cfg.width_jump_error_mm)
                    if sev:
                        self.add(
                            sev,
                            "width_jump",
                            f"lane {la.id} -> {lb.id} width jumps from {wa:.3f} m to "
                            f"{wb:.3f} m at the lane section at s={b.s0:.2f}",
                            road=road.id,
                            s=b.s0,
                            value=jump_mm,
                        )
            self._dead_ends(road, a, b, len_a)
            # lane links inside the road must resolve
            ids_b, ids_a = _lane_ids(b), _lane_ids(a)
            for ln in (*a.left, *a.right):
                if ln.successor is not None and ln.successor not in ids_b:
                    self.add(
                        "error",
                        "dangling_link",
                        f"lane {ln.id} names successor lane {ln.successor}, which the next "
                        f"lane section (s={b.s0:.2f}) does not have",
                        road=road.id,
                        s=b.s0,
                    )
            for ln in (*b.left, *b.right):
                if ln.predecessor is not None and ln.predecessor not in ids_a:
                    self.add(
                        "error",
                        "dangling_link",
                        f"lane {ln.id} names predecessor lane {ln.predecessor}, which the "
                        f"previous lane section (s={a.s0:.2f}) does not have",
                        road=road.id,
                        s=b.s0,
                    )

    def lane_jumps(self, road: Road) -> None:
        """``lane_jump``: every lane border just before and at each station inside a lane
        section where a lane offset or width record begins (one finding per station, the
        largest jump)."""
        offsets = np.array([p.s0 for p in road.lane_offset.pieces[1:]], dtype=float)
        for sec, s_end in road.sections_with_ends():
            lanes = (*sec.left, *sec.right)
            widths = [sec.s0 + np.array([p.s0 for p in ln.width.pieces[1:]]) for ln in lanes]
            at = np.unique(np.concatenate([offsets, *widths]))
            at = at[(at > sec.s0 + 1e-6) & (at < s_end - 1e-6)]
            if not at.size or not lanes:
                continue
            before, after = at - 1e-7, at
            worst = np.zeros(at.size)
            for lane_id in [0, *(ln.id for ln in lanes)]:
                jump = np.abs(
                    road.lane_border_t(after, lane_id) - road.lane_border_t(before, lane_id)
                )
                worst = np.maximum(worst, np.nan_to_num(jump))
            for s_k, jump_m in zip(at, worst, strict=True):
                jump_mm = 1000.0 * float(jump_m)
                self._border_gap(
                    "lane_jump",
                    jump_mm,
                    f"lane borders jump sideways by {jump_mm:.1f} mm at s={s_k:.2f} inside "
                    f"the lane section at s={sec.s0:.2f}",
                    road,
                    float(s_k),
                )

    def lane_offset_steps(self, road: Road) -> None:
        """``lane_offset_step``: the lane offset's step (mm) at each lane-section border
        inside ``road``; a warning from ``gap_warning_mm`` (the map's borders may be
        continuous; the ASAM checker's reading of them is not: melbourne-1019-s11 with a
        noisier sensor, a 0.5 m step made up for by the inner shoulder's width)."""
        borders = np.array([sec.s0 for sec in road.lane_sections[1:]], dtype=float)
        if not borders.size:
            return
        step_mm = 1000.0 * np.abs(
            road.lane_offset.value(borders) - road.lane_offset.value(borders - 1e-7)
        )
        for s_k, mm in zip(borders, step_mm, strict=True):
            if mm >= self.cfg.gap_warning_mm:
                self.add(
                    "warning",
                    "lane_offset_step",
                    f"the lane offset steps by {mm:.1f} mm at the lane section at "
                    f"s={s_k:.2f}; the ASAM checker reads the section's end with the new "
                    "offset and reports gaps of the lanes linked across it",
                    road=road.id,
                    s=float(s_k),
                    value=float(mm),
                )

    def lane_pinches(self, road: Road) -> None:
        """``lane_pinch``: driving lanes narrowing to almost nothing and widening back
        inside a lane section (sampled every half metre; one finding per lane and section,
        the narrowest station)."""
        cfg = self.cfg
        for sec, s_end in road.sections_with_ends():
            ds = np.arange(0.0, s_end - sec.s0, 0.5)
            if ds.size < 3:
                continue
            for ln in (*sec.left, *sec.right):
                if ln.type != "driving":
                    continue
                w = ln.width.value(ds)
                wide = np.flatnonzero(w >= cfg.pinch_wide_m)
                if wide.size < 2:
                    continue
                # narrow stations with a wide one within pinch_length_m before and after
                before = np.searchsorted(wide, np.arange(ds.size), side="right") - 1
                after = np.searchsorted(wide, np.arange(ds.size), side="left")
                ok = (before >= 0) & (after < wide.size)
                span = np.full(ds.size, np.inf)
                span[ok] = ds[wide[after[ok]]] - ds[wide[before[ok]]]
                pinched = (w < cfg.pinch_narrow_m) & (span <= cfg.pinch_length_m)
                if not pinched.any():
                    continue
                i = int(np.flatnonzero(pinched)[np.argmin(w[pinched])])
                s_k = float(sec.s0 + ds[i])
                self.add(
                    "error",
                    "lane_pinch",
                    f"driving lane {ln.id} narrows to {float(w[i]):.2f} m at s={s_k:.2f} and "
                    f"is {cfg.pinch_wide_m:g} m wide again within {float(span[i]):.1f} m, "
                    f"inside the lane section at s={sec.s0:.2f}",
                    road=road.id,
                    s=s_k,
                    value=float(w[i]),
                )

    def _dead_ends(self, road: Road, a: LaneSection, b: LaneSection, len_a: float) -> None:
        """A driving lane that ends at full width inside a road with no successor (or
        begins so with no predecessor): a car in it has nowhere to go (a lane that leaves
        at a gore with no junction, a lane drop without a taper)."""
        wide = self.cfg.dead_end_width_m
        for lanes, end, link, ds, s in (
            ((*a.left, *a.right), "ends", "successor", len_a, b.s0),
            ((*b.left, *b.right), "begins", "predecessor", 0.0, b.s0),
        ):
            for ln in lanes:
                if ln.type != "driving" or getattr(ln, link) is not None:
                    continue
                w = float(ln.width.value(np.array([ds]))[0])
                if w >= wide:
                    where = "nowhere to go" if end == "ends" else "no way in"
                    self.add(
                        "warning",
                        "lane_dead_end",
                        f"driving lane {ln.id} {end} {w:.2f} m wide at s={s:.2f} with no "
                        f"{link}: a car in it has {where}",
                        road=road.id,
                        s=s,
                        value=w,
                    )

    def _zero_width_links(self, road: Road, sec: LaneSection, lane: Lane, w, ds) -> None:
        """A lane that starts (ends) at zero width must have no predecessor (successor):
        the spec's rule for lanes that appear or disappear, which the ASAM checker enforces
        and simulators rely on when they route onto a lane."""
        zero = self.cfg.zero_width_link_m
        for end, link, width, s in (
            ("starts", lane.predecessor, w[0], sec.s0),
            ("ends", lane.successor, w[-1], sec.s0 + ds[-1]),
        ):
            if link is not None and abs(float(width)) < zero:
                kind = "predecessor" if end == "starts" else "successor"
                self.add(
                    "error",
                    "zero_width_link",
                    f"lane {lane.id} {end} at zero width ({1000.0 * float(width):.1f} mm) at "
                    f"s={s:.2f} but has {kind} lane {link}; a lane that appears or ends must "
                    "not be linked at its zero-width end",
                    road=road.id,
                    s=float(s),
                    value=float(width),
                )

    # -- links -------------------------------------------------------------

    def _measure_link(
        self,
        road: Road,
        contact: str,
        other: Road,
        other_contact: str,
        lane_pairs: list[tuple[int, int]],
        *,
        junction: str | None = None,
    ) -> None:
        """Gap/kink between ``road`` at ``contact`` and ``other`` at ``other_contact``."""
        key = tuple(sorted([(road.id, contact), (other.id, other_contact)]))
        if key in self._links_done:
            return
        self._links_done.add(key)
        self.stats["links_checked"] += 1
        s_a = 0.0 if contact == "start" else road.length
        s_b = 0.0 if other_contact == "start" else other.length
        xa, ya, ha = _pose(road, s_a)
        xb, yb, hb = _pose(other, s_b)
        same_direction = contact != other_contact
        kink = _wrap_deg(hb - ha if same_direction else hb - ha + math.pi)
        gap_mm = 1000.0 * math.hypot(xb - xa, yb - ya)
        basis = "reference lines"
        if lane_pairs:
            ids_a = _lane_ids(_section_at(road, contact))
            ids_b = _lane_ids(_section_at(other, other_contact))
            valid = [(la, lb) for la, lb in lane_pairs if la in ids_a and lb in ids_b]
            if valid:
                gaps = []
                for la, lb in valid:
                    pa = _lane_border_points(road, s_a, la)
                    pb = _lane_border_points(other, s_b, lb)
                    gaps.append(float(np.max(np.hypot(*(pa - pb).T))))
                gap_mm = 1000.0 * max(gaps)
                basis = "linked lane borders"
        self.stats["max_link_gap_mm"] = max(self.stats["max_link_gap_mm"], gap_mm)
        self.stats["max_link_heading_jump_deg"] = max(self.stats["max_link_heading_jump_deg"], kink)
        cfg = self.cfg
        sev = _grade(gap_mm, cfg.gap_warning_mm, cfg.gap_error_mm)
        where = f"road {road.id} {contact} -> road {other.id} {other_contact}"
        if sev:
            self.add(
                sev,
                "link_gap",
                f"gap of {gap_mm:.1f} mm across the link {where} ({basis})",
                road=road.id,
                junction=junction,
                s=s_a,
                value=gap_mm,
            )
        sev = _grade(kink, cfg.heading_warning_deg, cfg.heading_error_deg)
        if sev:
            self.add(
                sev,
                "link_kink",
                f"heading jumps by {kink:.4f} deg across the link {where}",
                road=road.id,
                junction=junction,
                s=s_a,
                value=kink,
            )

    def _points_back(self, other: Road, other_contact: str, road: Road) -> bool:
        link = other.predecessor if other_contact == "start" else other.successor
        if link is None:
            return False
        if link.element_type == "road":
            return link.element_id == road.id
        return link.element_id == road.junction or self._junction_knows(link.element_id, road)

    def _junction_knows(self, junction_id: str, road: Road) -> bool:
        j = self.net.id_to_junction.get(junction_id)
        if j is None:
            return False
        for c in j.connections:
            if road.id in (c.incoming_road, c.connecting_road):
                return True
        for r in self.net.roads:
            if r.junction == junction_id:
                for link in (r.predecessor, r.successor):
                    if link and link.element_type == "road" and link.element_id == road.id:
                        return True
        return False

    def links(self, road: Road) -> None:
        net = self.net
        for contact, link in (("start", road.predecessor), ("end", road.successor)):
            if link is None:
                continue
            kind = "predecessor" if contact == "start" else "successor"
            if link.element_type == "road":
                other = net.id_to_road.get(link.element_id)
                if other is None:
                    self.add(
                        "error",
                        "dangling_link",
                        f"{kind} is road {link.element_id}, which does not exist",
                        road=road.id,
                    )
                    continue
                other_contact = link.contact_point
                if other_contact is None:
                    self.add(
                        "warning",
                        "link_contact_point",
                        f"{kind} road {other.id} has no contactPoint; assuming "
                        f"{'end' if contact == 'start' else 'start'}",
                        road=road.id,
                    )
                    other_contact = "end" if contact == "start" else "start"
                if not self._points_back(other, other_contact, road):
                    self.add(
                        "error",
                        "one_sided_link",
                        f"{kind} is road {other.id} ({other_contact}), but road {other.id} "
                        f"does not link back to road {road.id}"
                        + (f" or junction {road.junction}" if road.junction != "-1" else ""),
                        road=road.id,
                    )
                sec = _section_at(road, contact)
                pairs: list[tuple[int, int]] = []
                if sec is not None:
                    for ln in (*sec.left, *sec.right):
                        target = ln.predecessor if contact == "start" else ln.successor
                        if target is not None:
                            pairs.append((ln.id, target))
                    other_ids = _lane_ids(_section_at(other, other_contact))
                    for la, lb in pairs:
                        if lb not in other_ids:
                            self.add(
                                "error",
                                "dangling_link",
                                f"lane {la} names {kind} lane {lb} of road {other.id}, which "
                                f"does not exist at its {other_contact}",
                                road=road.id,
                            )
                if not pairs:
                    # the other road may carry the lane links (e.g. connecting roads)
                    osec = _section_at(other, other_contact)
                    if osec is not None:
                        for ln in (*osec.left, *osec.right):
                            t = ln.predecessor if other_contact == "start" else ln.successor
                            if t is not None:
                                pairs.append((t, ln.id))
                jid = road.junction if road.junction != "-1" else None
                self._measure_link(road, contact, other, other_contact, pairs, junction=jid)
            else:
                j = net.id_to_junction.get(link.element_id)
                if j is None:
                    self.add(
                        "error",
                        "dangling_link",
                        f"{kind} is junction {link.element_id}, which does not exist",
                        road=road.id,
                    )
                    continue
                if not self._junction_knows(j.id, road):
                    self.add(
                        "error",
                        "one_sided_link",
                        f"{kind} is junction {j.id}, but no connection or connecting road of "
                        f"junction {j.id} involves road {road.id}",
                        road=road.id,
                        junction=j.id,
                    )
        if road.junction != "-1":
            j = net.id_to_junction.get(road.junction)
            if j is None:
                self.add(
                    "error",
                    "dangling_link",
                    f"road belongs to junction {road.junction}, which does not exist",
                    road=road.id,
                )
            else:
                if j.type == "default" and not any(
                    c.connecting_road == road.id for c in j.connections
                ):
                    self.add(
                        "warning",
                        "unused_connecting_road",
                        f"connecting road of junction {j.id} is used by no connection",
                        road=road.id,
                        junction=j.id,
                    )
                self._connector_lane_links(road)

    def _connector_lane_links(self, road: Road) -> None:
        if not road.lane_sections:
            return
        first, last = road.lane_sections[0], road.lane_sections[-1]
        checks = []
        if road.predecessor is not None:
            checks.append(("start", first, 0.0))
        if road.successor is not None:
            checks.append(("end", last, road.length - last.s0))
        for contact, sec, ds in checks:
            for ln in (*sec.left, *sec.right):
                if ln.type not in ("driving", "entry", "exit", "onRamp", "offRamp"):
                    continue
                target = ln.predecessor if contact == "start" else ln.successor
                width = float(ln.width.value(np.array([ds]))[0])
                if target is None and width > 1e-3:
                    self.add(
                        "warning",
                        "missing_lane_link",
                        f"lane {ln.id} of connecting road has no "
                        f"{'predecessor' if contact == 'start' else 'successor'} link at its "
                        f"{contact} (width {width:.2f} m)",
                        road=road.id,
                        junction=road.junction,
                    )

    def junction(self, j) -> None:
        net = self.net
        ids = Counter(c.id for c in j.connections)
        for cid, n in ids.items():
            if n > 1:
                self.add(
                    "error",
                    "duplicate_id",
                    f"connection id {cid} used {n} times",
                    junction=j.id,
                )
        for c in j.connections:
            inc = net.id_to_road.get(c.incoming_road)
            tgt = net.id_to_road.get(c.connecting_road)
            label = "linkedRoad" if j.type == "direct" else "connectingRoad"
            if inc is None:
                self.add(
                    "error",
                    "dangling_link",
                    f"connection {c.id}: incomingRoad {c.incoming_road} does not exist",
                    junction=j.id,
                )
            if tgt is None:
                self.add(
                    "error",
                    "dangling_link",
                    f"connection {c.id}: {label} {c.connecting_road} does not exist",
                    junction=j.id,
                )
            if not c.lane_links:
                self.add(
                    "error",
                    "missing_lane_link",
                    f"connection {c.id} ({c.incoming_road} -> {c.connecting_road}) has no laneLink",
                    junction=j.id,
                    road=c.connecting_road,
                )
            if inc is None or tgt is None:
                continue
            if j.type == "default" and tgt.junction != j.id:
                self.add(
                    "error",
                    "one_sided_link",
                    f"connection {c.id}: connecting road {tgt.id} has junction="
                    f"{tgt.junction}, not {j.id}",
                    junction=j.id,
                    road=tgt.id,
                )
            # which end of the incoming road touches the junction
            inc_contact = None
            if inc.successor is not None and inc.successor.element_id in (j.id, tgt.id):
                inc_contact = "end"
            if inc.predecessor is not None and inc.predecessor.element_id in (j.id, tgt.id):
                inc_contact = "start" if inc_contact is None else inc_contact
            if inc_contact is None:
                self.add(
                    "error",
                    "one_sided_link",
                    f"connection {c.id}: incoming road {inc.id} does not link to junction {j.id}",
                    junction=j.id,
                    road=inc.id,
                )
                continue
            ids_in = _lane_ids(_section_at(inc, inc_contact))
            ids_to = _lane_ids(_section_at(tgt, c.contact_point))
            for ll in c.lane_links:
                if ll.from_lane not in ids_in or ll.to_lane not in ids_to:
                    self.add(
                        "error",
                        "dangling_link",
                        f"connection {c.id}: laneLink {ll.from_lane} -> {ll.to_lane} names a "
                        f"lane that road {inc.id} ({inc_contact}) or road {tgt.id} "
                        f"({c.contact_point}) does not have",
                        junction=j.id,
                    )
            if j.type == "direct":
                pairs = [(ll.from_lane, ll.to_lane) for ll in c.lane_links]
                self._measure_link(inc, inc_contact, tgt, c.contact_point, pairs, junction=j.id)
                if not self._points_back(tgt, c.contact_point, inc):
                    self.add(
                        "error",
                        "one_sided_link",
                        f"connection {c.id}: linked road {tgt.id} does not link to junction "
                        f"{j.id} at its {c.contact_point}",
                        junction=j.id,
                        road=tgt.id,
                    )

    def geo_reference(self) -> None:
        geo = self.net.header.geo_reference.strip()
        if not geo:
            self.add("warning", "geo_reference", "header has no geoReference")
            return
        if "+no_defs" in geo:
            self.add(
                "warning",
                "geo_reference",
                "geoReference contains +no_defs (esmini logs an error on it)",
            )
        from pyproj import CRS
        from pyproj.exceptions import CRSError

        try:
            CRS.from_user_input(geo)
        except CRSError as exc:
            self.add(
                "error",
                "geo_reference",
                f"geoReference {geo[:80]!r} is not a CRS pyproj understands: {exc}",
            )

    def ids(self) -> None:
        for kind, items in (("road", self.net.roads), ("junction", self.net.junctions)):
            for rid, n in Counter(x.id for x in items).items():
                if n > 1:
                    self.add("error", "duplicate_id", f"{kind} id {rid} used {n} times")

    def run(self) -> None:
        self.ids()
        self.geo_reference()
        for road in self.net.roads:
            self.geometry(road)
            self.widths(road)
            self.lane_jumps(road)
            self.lane_offset_steps(road)
            self.lane_pinches(road)
            self.links(road)
        for j in self.net.junctions:
            self.junction(j)


def _analyse(network: RoadNetwork, config: CheckConfig | None) -> _Checker:
    checker = _Checker(network, config or CheckConfig())
    with gc_paused():  # linear on maps of 10^5 roads (see roadtwin._perf)
        checker.run()
    return checker


def check_network(network: RoadNetwork, *, config: CheckConfig | None = None) -> list[Finding]:
    """Own checks of a road network (see the module docstring); errors and warnings."""
    return list(_analyse(network, config).findings)


def network_stats(
    network: RoadNetwork, *, config: CheckConfig | None = None
) -> dict[str, float | int]:
    """Counts and maxima: ``max_gap_mm``, ``max_heading_jump_deg``, ``max_link_gap_mm``,
    ``max_link_heading_jump_deg``, ``roads``, ``junctions``, ... (reported even when fine)."""
    return dict(_analyse(network, config).stats)


def check_file(
    path: str | os.PathLike, *, external: bool = True, config: CheckConfig | None = None
) -> CheckReport:
    """Read an OpenDRIVE file, run the own checks and (``external=True``) the consumers.

    Raises
    ------
    InputError
        The file cannot be read as OpenDRIVE.
    """
    path = Path(path)
    network = read_xodr(path)
    checker = _analyse(network, config)
    consumers: tuple[ConsumerResult, ...] = ()
    if external:
        timeout_s = (config or CheckConfig()).consumer_timeout_s
        consumers = (
            run_sumo(path, network, timeout_s=timeout_s),
            run_asam(path, timeout_s=timeout_s),
        )
    report = CheckReport(str(path), tuple(checker.findings), dict(checker.stats), consumers)
    log.info(
        "checked %s: %d errors, %d warnings, max gap %.3f mm",
        path,
        report.errors,
        report.warnings,
        checker.stats["max_gap_mm"],
    )
    return report
