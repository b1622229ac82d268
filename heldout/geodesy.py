"""Local east/north metres around a home point to latitude/longitude on WGS84.

Uses the meridian and prime-vertical radii of curvature near home: exact to centimetres over the few
hundred metres a held-out clip covers.
"""

from __future__ import annotations

import math

WGS84_A = 6378137.0
WGS84_E2 = 6.69437999014e-3


def lat_lon(home_lat: float, home_lon: float, east: float, north: float) -> tuple[float, float]:
    """Degrees latitude and longitude of a point ``east``, ``north`` metres from home.

    North goes through the meridian radius at home; east through the prime-vertical radius at
    the middle latitude of the two points.
    """
    phi = math.radians(home_lat)
    meridian = WGS84_A * (1.0 - WGS84_E2) / (1.0 - WGS84_E2 * math.sin(phi) ** 2) ** 1.5
    lat = home_lat + math.degrees(north / meridian)
    mid = math.radians((home_lat + lat) / 2)
    prime = WGS84_A / math.sqrt(1.0 - WGS84_E2 * math.sin(mid) ** 2)
    return lat, home_lon + math.degrees(east / (prime * math.cos(mid)))
