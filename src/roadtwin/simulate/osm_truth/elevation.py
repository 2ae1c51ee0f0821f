"""Heights of the truth (OSM has none): mainline grades, ramp profiles, crossing clearance.

The mainline gets straight grades joined by parabolic vertical curves
(:func:`roadtwin.simulate.alignment.elevation_profile`). A ramp starts (exit) or ends
(entry) at the mainline's height and grade at its gore, then follows its own grade; where
its plan crosses the mainline carriageway it rises over (or dips under) it with at least
``clearance_m + structure_m``, never steeper than ``ramp_max_grade_pct``.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ...fitting import fit_cubic_profile
from ...model import CubicProfile
from ..alignment import elevation_profile
from ..scenario import GradeChange
from .settings import Elevation

FloatArray = NDArray[np.float64]


def mainline_profile(length_m: float, cfg: Elevation, rng: np.random.Generator) -> CubicProfile:
    """Random grades every ``cfg.grade_spacing_m`` with vertical curves between them."""
    grades = [GradeChange(0.0, float(rng.uniform(*cfg.grade_pct)))]
    s = 0.0
    while True:
        s += float(rng.uniform(*cfg.grade_spacing_m))
        vc = float(rng.uniform(*cfg.vertical_curve_m))
        if s + vc / 2 >= length_m - 50.0:
            break
        if s - vc / 2 <= grades[-1].station_m + grades[-1].curve_length_m / 2 + 20.0:
            continue
        g = float(rng.uniform(*cfg.grade_pct))
        grades.append(GradeChange(s, g, vc))
    return elevation_profile(grades, start_z_m=cfg.start_z_m, length_m=length_m)


def _raised(sig: FloatArray, c0: float, c1: float, ramp_m: float) -> FloatArray:
    """1 on ``[c0, c1]``, smooth (cosine) to 0 over ``ramp_m`` on both sides."""
    up = np.clip((sig - (c0 - ramp_m)) / ramp_m, 0.0, 1.0)
    down = np.clip(((c1 + ramp_m) - sig) / ramp_m, 0.0, 1.0)
    f = np.minimum(up, down)
    return 0.5 - 0.5 * np.cos(np.pi * f)


def ramp_profile(
    sig: FloatArray,
    *,
    kind: str,
    z_gore: float,
    grade_gore: float,
    crossings: list[tuple[float, float, float, int]],
    cfg: Elevation,
    rng: np.random.Generator,
) -> tuple[CubicProfile, list[float]]:
    """Elevation of a ramp along its stations ``sig`` (driving order, 0..length).

    ``crossings`` are ``(sig_start, sig_end, z_main, over)`` stretches where the ramp's
    plan crosses the mainline carriageway (``over`` +1 above, -1 below). Returns the
    profile and the vertical clearance reached at each crossing (metres, deck included
    in the required value but not in the reported one).
    """
    length = float(sig[-1])
    # distance from the gore along the ramp
    d = sig if kind == "exit" else length - sig
    own = float(rng.uniform(*cfg.ramp_grade_pct)) / 100.0
    blend = np.clip(d / 150.0, 0.0, 1.0)
    slope = grade_gore + (own - grade_gore) * (blend * blend * (3 - 2 * blend))
    # integrate the slope from the gore outwards (exit forward, entry backward)
    if kind == "exit":
        z = z_gore + np.concatenate(
            [[0.0], np.cumsum(0.5 * (slope[1:] + slope[:-1]) * np.diff(sig))]
        )
    else:
        rev = slope[::-1]
        zr = np.concatenate([[0.0], np.cumsum(0.5 * (rev[1:] + rev[:-1]) * np.diff(sig))])
        z = (z_gore - zr)[::-1]
    max_g = cfg.ramp_max_grade_pct / 100.0
    reached: list[float] = []
    for c0, c1, z_main, over in crossings:
        need = z_main + over * (cfg.clearance_m + cfg.structure_m)
        sel = (sig >= c0) & (sig <= c1)
        mid = float(np.interp(0.5 * (c0 + c1), sig, z))
        worst = (float(z[sel].min()) if over > 0 else float(z[sel].max())) if sel.any() else mid
        h = need - worst
        if over * h <= 0:  # already clear
            reached.append(abs(worst - z_main) - cfg.structure_m)
            continue
        # room between the gore and the crossing for the climb
        room = float(min(c0 if kind == "exit" else length - c1, 1e9))
        ramp_m = max(abs(h) * np.pi / 2.0 / (0.85 * max_g), 40.0)
        ramp_m = min(ramp_m, max(room - 15.0, 10.0))
        z = z + h * _raised(sig, c0, c1, ramp_m)
        zc = float(np.min(z[sel]) if over > 0 else np.max(z[sel])) if sel.any() else need
        reached.append(abs(zc - z_main) - cfg.structure_m)
    prof = fit_cubic_profile(sig, z, tolerance=0.003, max_piece_m=200.0)
    return prof, reached
