"""Coordinate frames: WGS84 <-> mapping frame, and the OpenDRIVE geoReference string.

The mapping frame is either ``"local"`` -- a transverse Mercator centred on the run's GPS
origin (x east, y north, metres; z metres above the origin's altitude) -- or any CRS
pyproj understands (``"EPSG:32633"``, a PROJ string, WKT), where coordinates are as given.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
from numpy.typing import ArrayLike, NDArray
from pyproj import CRS, Transformer
from pyproj.exceptions import CRSError

from ._errors import InputError


@dataclass(frozen=True)
class Origin:
    """GPS origin of the mapping frame: WGS84 degrees and metres (ellipsoidal/as given)."""

    lat_deg: float
    lon_deg: float
    alt_m: float = 0.0

    def __post_init__(self) -> None:
        if not (np.isfinite(self.lat_deg) and -90.0 <= self.lat_deg <= 90.0):
            raise InputError(f"origin: lat must be in [-90, 90] degrees, got {self.lat_deg}")
        if not (np.isfinite(self.lon_deg) and -180.0 <= self.lon_deg <= 180.0):
            raise InputError(f"origin: lon must be in [-180, 180] degrees, got {self.lon_deg}")
        if not np.isfinite(self.alt_m):
            raise InputError(f"origin: alt must be a finite number of metres, got {self.alt_m}")


def local_proj_string(origin: Origin) -> str:
    """PROJ string of the ``local`` mapping frame (transverse Mercator on the origin)."""
    return (
        f"+proj=tmerc +lat_0={origin.lat_deg:.10g} +lon_0={origin.lon_deg:.10g} +k=1 "
        "+x_0=0 +y_0=0 +ellps=WGS84 +units=m"
    )


@dataclass(frozen=True)
class MappingFrame:
    """The metric frame all of a run's data lives in.

    Parameters
    ----------
    origin
        GPS origin of the run.
    crs
        ``"local"`` or any pyproj CRS string.
    """

    origin: Origin
    crs: str = "local"

    def __post_init__(self) -> None:
        try:
            _ = self._crs
        except CRSError as exc:
            raise InputError(
                f"run.toml [frame] crs: unknown CRS {self.crs!r} (expected 'local' or a "
                f"pyproj CRS such as 'EPSG:32633'): {exc}"
            ) from None
        if not self._crs.is_projected and self.crs != "local":
            raise InputError(
                f"run.toml [frame] crs: {self.crs!r} is not a projected (metric) CRS; "
                "the mapping frame must be in metres"
            )

    @cached_property
    def _crs(self) -> CRS:
        if self.crs == "local":
            return CRS.from_proj4(local_proj_string(self.origin))
        return CRS.from_user_input(self.crs)

    @cached_property
    def geo_reference(self) -> str:
        """PROJ string for OpenDRIVE ``<geoReference>`` (without ``+no_defs``)."""
        if self.crs == "local":
            return local_proj_string(self.origin)
        # a PROJ string as given (pyproj's round trip only warns and reorders it)
        text = self.crs if self.crs.lstrip().startswith("+proj=") else self._crs.to_proj4() or ""
        return " ".join(tok for tok in text.split() if tok not in ("+no_defs", "+type=crs"))

    @cached_property
    def _to_wgs84(self) -> Transformer:
        return Transformer.from_crs(self._crs, "EPSG:4326", always_xy=True)

    @cached_property
    def _from_wgs84(self) -> Transformer:
        return Transformer.from_crs("EPSG:4326", self._crs, always_xy=True)

    @property
    def z_offset_m(self) -> float:
        """Add to mapping-frame z to get altitude: the origin's alt for ``local``, else 0."""
        return self.origin.alt_m if self.crs == "local" else 0.0

    def to_lonlat(self, x: ArrayLike, y: ArrayLike) -> tuple[NDArray, NDArray]:
        """Mapping-frame metres -> WGS84 (lon, lat) degrees."""
        lon, lat = self._to_wgs84.transform(np.asarray(x, float), np.asarray(y, float))
        return np.asarray(lon), np.asarray(lat)

    def from_lonlat(self, lon: ArrayLike, lat: ArrayLike) -> tuple[NDArray, NDArray]:
        """WGS84 (lon, lat) degrees -> mapping-frame metres."""
        x, y = self._from_wgs84.transform(np.asarray(lon, float), np.asarray(lat, float))
        return np.asarray(x), np.asarray(y)

    @cached_property
    def origin_xy(self) -> tuple[float, float]:
        """The GPS origin in mapping-frame metres ((0, 0) for ``local``)."""
        x, y = self._from_wgs84.transform(float(self.origin.lon_deg), float(self.origin.lat_deg))
        return float(x), float(y)
