"""Geolocation on terrain: a small synthetic DEM (GeoTIFF written with rasterio, SRTM .hgt
written as the format says) against the flat-plane geolocation and against geometry."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from sarmission.geo.camera import CameraIntrinsics
from sarmission.geo.geolocate import PlatformPose, geolocate
from sarmission.geo.terrain import (
    HOME_AMSL_SIGMA_M,
    DemError,
    TerrainGround,
    geolocate_terrain,
    read_dem,
)
from sarmission.geo.wgs84 import geodetic_to_ned

LAT0, LON0 = 43.0, 10.0
INTR = CameraIntrinsics(1920, 1080, 1000.0, 1000.0, 960.0, 540.0)
HOME = (LAT0 - 0.001, LON0, 200.0)
STEP = 1.0 / 3600  # one arc-second cells, about 30 m


def write_geotiff(path: Path, heights_of: object, crs: str = "EPSG:4326", size: int = 201) -> None:
    """A DEM of ``size`` cells a side centred on (LAT0, LON0): heights from ``heights_of(north
    m, east m)`` at each cell centre."""
    import rasterio
    from rasterio.transform import from_origin
    from rasterio.warp import transform as warp

    half = size * STEP / 2
    rows, cols = np.mgrid[0:size, 0:size]
    lat = LAT0 + half - (rows + 0.5) * STEP
    lon = LON0 - half + (cols + 0.5) * STEP
    n, e, _ = geodetic_to_ned(lat, lon, 0.0, LAT0, LON0, 0.0)
    heights = heights_of(n, e).astype("float32")
    if crs == "EPSG:4326":
        transform = from_origin(LON0 - half, LAT0 + half, STEP, STEP)
    else:  # the same grid's corner in the projected CRS, 30 m cells
        x, y = warp("EPSG:4326", crs, [LON0], [LAT0])
        transform = from_origin(x[0] - size * 15.0, y[0] + size * 15.0, 30.0, 30.0)
        rr, cc = np.mgrid[0:size, 0:size]
        xs = x[0] - size * 15.0 + (cc + 0.5) * 30.0
        ys = y[0] + size * 15.0 - (rr + 0.5) * 30.0
        lons, lats = warp(crs, "EPSG:4326", xs.ravel().tolist(), ys.ravel().tolist())
        n, e, _ = geodetic_to_ned(np.array(lats), np.array(lons), 0.0, LAT0, LON0, 0.0)
        heights = heights_of(n, e).reshape(size, size).astype("float32")
    with rasterio.open(
        path,
        "w",
        driver="GTiff",
        width=size,
        height=size,
        count=1,
        dtype="float32",
        crs=crs,
        transform=transform,
        nodata=-9999.0,
    ) as dst:
        dst.write(heights, 1)


def pose(pitch_deg: float = -50.0, yaw_deg: float = 30.0, rel_alt: float = 80.0) -> PlatformPose:
    return PlatformPose(
        LAT0,
        LON0,
        rel_alt,
        0.02,
        -0.05,
        math.radians(yaw_deg),
        gimbal_rpy=(0.0, math.radians(pitch_deg), 0.0),
        gimbal_frame="vehicle",
    )


def test_flat_dem_matches_the_flat_plane(tmp_path: Path) -> None:
    write_geotiff(tmp_path / "flat.tif", lambda n, e: np.full(n.shape, 200.0))
    dem = read_dem(tmp_path / "flat.tif", vertical_sigma_m=2.0)
    for uv in ((960, 540), (1500, 900), (100, 1000)):
        on_dem = geolocate_terrain(uv, INTR, pose(), dem, HOME)
        flat = geolocate(uv, INTR, pose(), 0.0, ground_sigma_m=math.hypot(HOME_AMSL_SIGMA_M, 2.0))
        assert on_dem.ok and flat.ok
        n, e, _ = geodetic_to_ned(on_dem.lat, on_dem.lon, 0, flat.lat, flat.lon, 0)
        assert math.hypot(n, e) < 0.01
        assert on_dem.error_m == pytest.approx(flat.error_m, rel=1e-3)


@pytest.mark.parametrize("crs", ["EPSG:4326", "EPSG:32632"])
def test_ray_meets_a_slope_where_geometry_says(tmp_path: Path, crs: str) -> None:
    """Ground rising 0.3 m per metre eastwards: a camera looking east meets it earlier than the
    plane at home altitude, exactly where the ray's height equals the ground's."""
    write_geotiff(tmp_path / "slope.tif", lambda n, e: 200.0 + 0.3 * e, crs=crs)
    dem = read_dem(tmp_path / "slope.tif")
    p = pose(pitch_deg=-40.0, yaw_deg=90.0, rel_alt=100.0)
    fix = geolocate_terrain((960, 540), INTR, p, dem, HOME)
    flat = geolocate((960, 540), INTR, p, 0.0)
    n, e, _ = geodetic_to_ned(fix.lat, fix.lon, 0, LAT0, LON0, 0)
    # ray: down = e tan(40 deg) from 300 m AMSL; ground: 200 + 0.3 e
    expected_e = 100.0 / (math.tan(math.radians(40)) + 0.3)
    assert float(e) == pytest.approx(expected_e, abs=0.5) and abs(float(n)) < 0.5
    n_flat, e_flat, _ = geodetic_to_ned(flat.lat, flat.lon, 0, LAT0, LON0, 0)
    assert float(e_flat) > float(e) + 20  # the flat plane would place it 25 m too far
    assert "slope 17 deg" in fix.note


def test_error_grows_with_slope_and_cell_size(tmp_path: Path) -> None:
    write_geotiff(tmp_path / "slope.tif", lambda n, e: 200.0 + 0.6 * n)
    write_geotiff(tmp_path / "flat.tif", lambda n, e: np.full(n.shape, 200.0))
    steep = read_dem(tmp_path / "slope.tif", vertical_sigma_m=1.0)
    flat = read_dem(tmp_path / "flat.tif", vertical_sigma_m=1.0)
    p = pose(pitch_deg=-45.0, yaw_deg=0.0, rel_alt=120.0)
    e_steep = geolocate_terrain((960, 540), INTR, p, steep, HOME).error_m
    coarse = read_dem(tmp_path / "slope.tif", vertical_sigma_m=1.0)
    coarse.resolution_m *= 10
    e_coarse = geolocate_terrain((960, 540), INTR, p, coarse, HOME).error_m
    e_flat = geolocate_terrain((960, 540), INTR, p, flat, HOME).error_m
    assert e_coarse > e_steep
    assert e_steep != pytest.approx(e_flat, rel=0.05)


def test_srtm_hgt_tile_and_no_fix_cases(tmp_path: Path) -> None:
    n = 1201
    rows, cols = np.mgrid[0:n, 0:n]
    heights = (300 + 0 * rows + 0 * cols).astype(">i2")
    heights[:10, :10] = -32768  # a void in the north-west corner
    hgt = tmp_path / "N43E010.hgt"
    heights.tofile(hgt)
    dem = read_dem(hgt)
    assert dem.vertical_sigma_m == 6.0 and 60 < dem.resolution_m < 70
    p = PlatformPose(43.5, 10.5, 50.0, 0.0, 0.0, 0.0, gimbal_rpy=(0.0, -math.pi / 2, 0.0))
    fix = TerrainGround(dem).locate((960, 540), INTR, p, (43.5, 10.5, math.nan), 5.0)
    assert fix.ok and "DEM at home" in fix.note
    n_, e_, _ = geodetic_to_ned(fix.lat, fix.lon, 0, 43.5, 10.5, 0)
    assert math.hypot(n_, e_) < 0.05  # nadir, straight below
    horizon = PlatformPose(43.5, 10.5, 50.0, 0.0, 0.0, 0.0, gimbal_rpy=(0.0, 0.1, 0.0))
    assert (
        "no terrain within"
        in geolocate_terrain((960, 540), INTR, horizon, dem, (43.5, 10.5, 300.0)).note
    )
    edge = PlatformPose(43.99, 10.5, 50.0, 0.0, 0.0, 0.0, gimbal_rpy=(0.0, -0.02, 0.0))
    assert (
        "leaves the DEM"
        in geolocate_terrain((960, 540), INTR, edge, dem, (43.99, 10.5, 300.0)).note
    )
    outside = PlatformPose(45.0, 10.5, 50.0, 0.0, 0.0, 0.0)
    assert (
        "outside the DEM"
        in geolocate_terrain((960, 540), INTR, outside, dem, (45.0, 10.5, 300.0)).note
    )
    low = PlatformPose(43.5, 10.5, 3.0, 0.0, 0.0, 0.0, gimbal_rpy=(0.0, -math.pi / 2, 0.0))
    assert (
        "a fix needs 5 m"
        in geolocate_terrain((960, 540), INTR, low, dem, (43.5, 10.5, 300.0), min_height_m=5.0).note
    )


def test_bad_dem_files_say_so_in_one_line(tmp_path: Path) -> None:
    (tmp_path / "N43E010.hgt").write_bytes(b"\0" * 1001)
    with pytest.raises(DemError, match="not a square SRTM tile"):
        read_dem(tmp_path / "N43E010.hgt")
    (tmp_path / "x.tif").write_bytes(b"not a tiff")
    with pytest.raises(DemError, match="not a readable GeoTIFF"):
        read_dem(tmp_path / "x.tif")
    with pytest.raises(DemError, match="no such DEM"):
        read_dem(tmp_path / "missing.tif")
