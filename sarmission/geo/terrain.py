"""Pixel -> latitude/longitude on terrain: the pixel ray meets a digital elevation model (DEM).

Where :func:`~sarmission.geo.geolocate.geolocate` meets a flat plane at home altitude, a land
search over hills needs the ground itself. A :class:`Dem` holds heights on a regular grid
(GeoTIFF via rasterio, in any CRS rasterio can transform to; or an SRTM ``.hgt`` tile read
directly), interpolated bilinearly; heights and the aircraft's altitudes must share a datum
(AMSL: SRTM and most national DEMs are geoid heights, as are autopilots' AMSL altitudes).

1. The camera's altitude is home's AMSL altitude plus the autopilot's height above home
   (the DEM height at home when the log has no AMSL home). The ray ``d`` (NED) leaves the
   drone's own position, as in the flat case.
2. March along the ray in steps of half a DEM cell (slant metres) until the ray's altitude is
   at or below the terrain's (heights of the ray points from the WGS84 conversion, so the
   Earth's curvature is in), then bisect that step to a millimetre. A ray that leaves the DEM
   or reaches ``max_range_m`` first gives no fix.
3. Error model: the flat model's first-order propagation with the local terrain plane. With
   ``g = (dh/dN, dh/dE, 1)`` (the DEM gradient at the point) a small change ``dp`` of the ray
   point along the surface satisfies ``g . dp = 0``; a perturbation of the camera or the ray
   moves the point by ``P = I - d g^T / (g . d)`` applied to it. Camera position errors
   (GNSS ``sigma_g`` per horizontal axis, height ``sigma_h``) give ``P[:2] diag(sigma_g^2,
   sigma_g^2, sigma_h^2) P[:2]^T``; pointing gives ``sigma_a^2 J J^T`` with
   ``J = -t P [d]x`` (rows N, E). ``sigma_h^2 = sigma_alt^2 + sigma_home^2 + sigma_dem^2 +
   (|grad h| res / sqrt(12))^2``: the DEM's vertical accuracy, and its resolution ``res``: a
   sample stands for a cell, so where the ground lies within it is uncertain by ``res /
   sqrt(12)`` per axis, a height error of that times the slope. On flat ground ``g = e_z`` and
   this is exactly the flat model. ``error_m = sqrt(trace)`` (DRMS).
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from sarmission.geo.camera import CameraIntrinsics, pixel_rays
from sarmission.geo.geolocate import FixLimits, GeoFix, PlatformPose
from sarmission.geo.wgs84 import ned_to_geodetic

__all__ = ["Dem", "DemError", "TerrainGround", "geolocate_terrain", "read_dem"]

#: Longest slant range searched for the ground (metres).
MAX_RANGE_M = 10_000.0
#: 1-sigma of an AMSL home altitude from GNSS/barometer (metres).
HOME_AMSL_SIGMA_M = 3.0
#: 1-sigma vertical accuracy of an SRTM tile (its 16 m LE90 absolute, 10 m relative: metres).
SRTM_SIGMA_M = 6.0
#: 1-sigma vertical accuracy assumed for a GeoTIFF DEM that does not say (metres).
GEOTIFF_SIGMA_M = 2.0
_HGT_NAME = re.compile(r"([NS])(\d{2})([EW])(\d{3})", re.IGNORECASE)
_M_PER_DEG = 111_320.0


class DemError(ValueError):
    """A DEM file cannot be read (one line for the operator)."""


@dataclass
class Dem:
    """Heights ``[rows, cols]`` (NaN: void) on a grid; ``to_pixel(lat, lon)`` gives fractional
    ``(col, row)`` of the sample grid. ``resolution_m``: grid spacing; ``vertical_sigma_m``:
    1-sigma accuracy of a height; ``source`` names it."""

    heights: np.ndarray
    to_pixel: Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]
    resolution_m: float
    vertical_sigma_m: float
    source: str

    def height(self, lat: np.ndarray | float, lon: np.ndarray | float) -> np.ndarray:
        """Bilinear height at ``lat``/``lon`` (degrees); NaN outside the grid or by a void."""
        lat_a = np.atleast_1d(np.asarray(lat, dtype=float))
        lon_a = np.atleast_1d(np.asarray(lon, dtype=float))
        col, row = self.to_pixel(lat_a, lon_a)
        rows, cols = self.heights.shape
        c0 = np.floor(col)
        r0 = np.floor(row)
        inside = (c0 >= 0) & (r0 >= 0) & (c0 <= cols - 2) & (r0 <= rows - 2)
        c0i = np.where(inside, c0, 0).astype(int)
        r0i = np.where(inside, r0, 0).astype(int)
        fc, fr = col - c0, row - r0
        h = self.heights
        top = h[r0i, c0i] * (1 - fc) + h[r0i, c0i + 1] * fc
        bottom = h[r0i + 1, c0i] * (1 - fc) + h[r0i + 1, c0i + 1] * fc
        out = top * (1 - fr) + bottom * fr
        return np.where(inside, out, np.nan)

    def gradient(self, lat: float, lon: float) -> tuple[float, float]:
        """``(dh/dN, dh/dE)`` (m/m) by central differences one cell apart."""
        step = self.resolution_m / 2.0
        lats, lons, _ = ned_to_geodetic(
            np.array([step, -step, 0.0, 0.0]), np.array([0.0, 0.0, step, -step]), 0.0, lat, lon, 0.0
        )
        h = self.height(lats, lons)
        return float((h[0] - h[1]) / (2 * step)), float((h[2] - h[3]) / (2 * step))


def read_hgt(path: str | Path, vertical_sigma_m: float = SRTM_SIGMA_M) -> Dem:
    """An SRTM ``.hgt`` tile: big-endian int16 heights (-32768 void), 1201 or 3601 samples a
    side from its north-west corner, named by its south-west corner (``N43E010.hgt``)."""
    path = Path(path)
    m = _HGT_NAME.search(path.stem)
    if m is None:
        raise DemError(f"{path.name}: an SRTM tile is named by its corner, e.g. N43E010.hgt")
    lat0 = int(m.group(2)) * (1 if m.group(1).upper() == "N" else -1)
    lon0 = int(m.group(4)) * (1 if m.group(3).upper() == "E" else -1)
    try:
        raw = np.fromfile(path, dtype=">i2")
    except OSError as exc:
        raise DemError(f"{path.name}: cannot read ({exc.strerror})") from exc
    n = int(round(math.sqrt(raw.size)))
    if n * n != raw.size or n < 2:
        raise DemError(f"{path.name}: {raw.size * 2} bytes is not a square SRTM tile")
    heights = raw.reshape(n, n).astype(float)
    heights[raw.reshape(n, n) == -32768] = np.nan
    step = 1.0 / (n - 1)

    def to_pixel(lat: np.ndarray, lon: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return (lon - lon0) / step, (lat0 + 1 - lat) / step

    return Dem(
        heights,
        to_pixel,
        step * _M_PER_DEG * math.cos(math.radians(lat0 + 0.5)),
        vertical_sigma_m,
        f"SRTM tile {path.name} ({n}x{n})",
    )


def read_geotiff(path: str | Path, vertical_sigma_m: float = GEOTIFF_SIGMA_M) -> Dem:
    """A single-band GeoTIFF DEM via rasterio (nodata as voids; any CRS rasterio knows)."""
    import rasterio
    from rasterio.errors import RasterioError
    from rasterio.warp import transform as warp

    path = Path(path)
    try:
        with rasterio.open(path) as src:
            band = src.read(1, masked=True).astype(float)
            affine, crs = src.transform, src.crs
    except (RasterioError, OSError) as exc:
        raise DemError(f"{path.name}: not a readable GeoTIFF DEM ({exc})") from exc
    if crs is None:
        raise DemError(f"{path.name}: GeoTIFF without a coordinate reference system")
    heights = np.ma.filled(band, np.nan)
    inverse = ~affine
    geographic = crs.is_geographic

    def to_pixel(lat: np.ndarray, lon: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        if geographic:
            x, y = lon, lat
        else:
            xs, ys = warp("EPSG:4326", crs, lon.tolist(), lat.tolist())
            x, y = np.asarray(xs), np.asarray(ys)
        col, row = inverse @ (x, y)
        return np.asarray(col) - 0.5, np.asarray(row) - 0.5  # sample centres

    res = abs(affine.a)
    if geographic:
        res *= _M_PER_DEG * math.cos(math.radians(float(affine.f)))
    return Dem(
        heights,
        to_pixel,
        float(res),
        vertical_sigma_m,
        f"GeoTIFF {path.name} ({heights.shape[1]}x{heights.shape[0]}, {res:.1f} m)",
    )


def read_dem(path: str | Path, vertical_sigma_m: float | None = None) -> Dem:
    """A ``.hgt`` tile or a GeoTIFF, by extension; :class:`DemError` when unreadable."""
    path = Path(path)
    if not path.is_file():
        raise DemError(f"{path}: no such DEM file")
    if path.suffix.lower() == ".hgt":
        return read_hgt(path, SRTM_SIGMA_M if vertical_sigma_m is None else vertical_sigma_m)
    return read_geotiff(path, GEOTIFF_SIGMA_M if vertical_sigma_m is None else vertical_sigma_m)


#: Limits when none are given: only the grazing margin (as :class:`FixLimits` defaults).
DEFAULT_LIMITS = FixLimits()


def _no_fix(depression: float, note: str) -> GeoFix:
    return GeoFix(None, None, None, None, depression, note)


def _above_ground(
    dem: Dem, pose: PlatformPose, cam_alt: float, d: np.ndarray, s: np.ndarray
) -> np.ndarray:
    """Ray altitude minus terrain height at slant ranges ``s`` (NaN outside the DEM)."""
    lat, lon, h = ned_to_geodetic(s * d[0], s * d[1], s * d[2], pose.lat, pose.lon, cam_alt)
    return np.asarray(h) - dem.height(lat, lon)


def _covariance(
    d: np.ndarray, t: float, g: np.ndarray, pose: PlatformPose, sigma_h: float
) -> np.ndarray:
    gd = float(g @ d)
    proj = np.eye(3) - np.outer(d, g) / gd
    ph = proj[:2]
    cov = ph @ np.diag([pose.gnss_sigma_m**2, pose.gnss_sigma_m**2, sigma_h**2]) @ ph.T
    d_cross = np.array([[0.0, -d[2], d[1]], [d[2], 0.0, -d[0]], [-d[1], d[0], 0.0]])
    jac = (-t * proj @ d_cross)[:2]
    return cov + pose.attitude_sigma_rad**2 * jac @ jac.T


def geolocate_terrain(
    pixel_uv: tuple[float, float] | np.ndarray,
    intrinsics: CameraIntrinsics,
    pose: PlatformPose,
    dem: Dem,
    home: tuple[float, float, float],
    min_height_m: float = 0.0,
    max_range_m: float = MAX_RANGE_M,
    limits: FixLimits = DEFAULT_LIMITS,
) -> GeoFix:
    """Latitude/longitude of the terrain seen at pixel ``(u, v)`` (see the module docstring).

    ``home`` is the autopilot's ``(lat, lon, alt AMSL)``; with a non-finite altitude the DEM's
    height at home is used. No fix (``note`` says why) when the ray points above the horizon
    without meeting a hill, leaves the DEM, or the camera is less than ``min_height_m`` above
    the terrain below it; nor when ``limits`` refuse it, as on the plane, except that the
    grazing margin is taken from the terrain's surface where the ray meets it, not the horizon
    (a ray level with the horizon meets a hillside at a bounded range).
    """
    uv = np.asarray(pixel_uv, dtype=float).reshape(1, 2)
    if not (pose.finite() and np.all(np.isfinite(uv))):
        return _no_fix(math.nan, "pose or pixel not finite")
    if math.isfinite(home[2]):
        cam_alt, sigma_home, anchor = home[2] + pose.rel_alt_m, HOME_AMSL_SIGMA_M, "home AMSL"
    else:
        ground = float(dem.height(home[0], home[1])[0])
        if not math.isfinite(ground):
            return _no_fix(math.nan, "home altitude unknown and home is outside the DEM")
        cam_alt, sigma_home, anchor = ground + pose.rel_alt_m, dem.vertical_sigma_m, "DEM at home"
    d = pixel_rays(intrinsics, pose.camera_pose(0.0), uv)[0]
    depression = math.degrees(math.asin(max(-1.0, min(1.0, float(d[2])))))
    below = float(dem.height(pose.lat, pose.lon)[0])
    if not math.isfinite(below):
        return _no_fix(depression, "the drone is outside the DEM")
    if cam_alt - below < max(min_height_m, 0.0) or cam_alt <= below:
        return _no_fix(
            depression,
            f"drone {cam_alt - below:.1f} m above the terrain (a fix needs {min_height_m:g} m)",
        )
    step = max(dem.resolution_m / 2.0, 0.5)
    s = np.arange(0.0, max_range_m + step, step)
    f = _above_ground(dem, pose, cam_alt, d, s)
    hit = np.flatnonzero(~(f > 0.0))  # first at or below the ground, or NaN (left the DEM)
    if hit.size == 0:
        return _no_fix(depression, f"ray meets no terrain within {max_range_m:g} m")
    k = int(hit[0])
    if not math.isfinite(f[k]):
        return _no_fix(depression, "ray leaves the DEM before meeting the ground")
    lo, hi = float(s[k - 1]), float(s[k])
    while hi - lo > 1e-3:
        mid = (lo + hi) / 2.0
        if _above_ground(dem, pose, cam_alt, d, np.array([mid]))[0] > 0.0:
            lo = mid
        else:
            hi = mid
    t = (lo + hi) / 2.0
    lat, lon, _ = ned_to_geodetic(t * d[0], t * d[1], t * d[2], pose.lat, pose.lon, cam_alt)
    lat, lon = float(lat), float(lon)
    dh_n, dh_e = dem.gradient(lat, lon)
    if not (math.isfinite(dh_n) and math.isfinite(dh_e)):
        dh_n = dh_e = 0.0
    g = np.array([dh_n, dh_e, 1.0])
    if float(g @ d) <= 1e-9:
        return _no_fix(depression, "ray grazes the terrain")
    slope_sigma = math.hypot(dh_n, dh_e) * dem.resolution_m / math.sqrt(12.0)
    sigma_h = math.sqrt(
        pose.alt_sigma_m**2 + sigma_home**2 + dem.vertical_sigma_m**2 + slope_sigma**2
    )
    error = math.sqrt(float(np.trace(_covariance(d, t, g, pose, sigma_h))))
    if not all(math.isfinite(v) for v in (lat, lon, error, t)):
        return _no_fix(depression, "geolocation not finite")
    slope = math.degrees(math.atan(math.hypot(dh_n, dh_e)))
    fix = GeoFix(
        lat,
        lon,
        error,
        t,
        depression,
        f"terrain ({dem.source}, slope {slope:.0f} deg, camera from {anchor})",
    )
    incidence = math.degrees(math.asin(min(1.0, float(g @ d) / float(np.linalg.norm(g)))))
    refused = limits.refusal(fix, pose.attitude_sigma_rad, incidence)
    return _no_fix(depression, refused) if refused else fix


class TerrainGround:
    """The controller's ground model for a land search: fixes on ``dem`` instead of a plane,
    refused by ``limits`` as plane fixes are (:func:`geolocate_terrain`)."""

    def __init__(
        self, dem: Dem, max_range_m: float = MAX_RANGE_M, limits: FixLimits = DEFAULT_LIMITS
    ) -> None:
        self.dem = dem
        self.max_range_m = max_range_m
        self.limits = limits

    def locate(
        self,
        centre: tuple[float, float],
        intrinsics: CameraIntrinsics,
        pose: PlatformPose,
        home: tuple[float, float, float],
        min_height_m: float,
        limits: FixLimits | None = None,
    ) -> GeoFix:
        """The fix of pixel ``centre`` (see :func:`geolocate_terrain`); ``limits`` replace the
        ground model's own for this fix."""
        return geolocate_terrain(
            centre,
            intrinsics,
            pose,
            self.dem,
            home,
            min_height_m,
            self.max_range_m,
            self.limits if limits is None else limits,
        )
