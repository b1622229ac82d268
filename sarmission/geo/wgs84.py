"""WGS84 <-> local NED conversions (thin, vectorised wrappers around pymap3d).

Angles in degrees, heights in metres above the WGS84 ellipsoid (or any consistent datum: the
local frame only needs ``h0`` and ``h`` on the same datum, e.g. AMSL from GLOBAL_POSITION_INT).
The NED origin is ``(lat0, lon0, h0)``, usually the home position.
"""

from __future__ import annotations

import numpy as np
import pymap3d

ArrayLike = float | np.ndarray


def ned_to_geodetic(
    n: ArrayLike, e: ArrayLike, d: ArrayLike, lat0: float, lon0: float, h0: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Local NED offsets (m) from ``(lat0, lon0, h0)`` to ``(lat_deg, lon_deg, h_m)`` arrays."""
    lat, lon, h = pymap3d.ned2geodetic(
        np.asarray(n, dtype=float),
        np.asarray(e, dtype=float),
        np.asarray(d, dtype=float),
        lat0,
        lon0,
        h0,
        deg=True,
    )
    return np.asarray(lat), np.asarray(lon), np.asarray(h)


def geodetic_to_ned(
    lat: ArrayLike, lon: ArrayLike, h: ArrayLike, lat0: float, lon0: float, h0: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(lat_deg, lon_deg, h_m)`` to local NED offsets (m) from ``(lat0, lon0, h0)``."""
    n, e, d = pymap3d.geodetic2ned(
        np.asarray(lat, dtype=float),
        np.asarray(lon, dtype=float),
        np.asarray(h, dtype=float),
        lat0,
        lon0,
        h0,
        deg=True,
    )
    return np.asarray(n), np.asarray(e), np.asarray(d)
