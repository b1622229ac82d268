"""The sea surface as a sum of directional wave trains, evaluated on a camera-aligned ground grid.

Trains are drawn from a wind-sea spectrum (energy ~ k^-3.5 above the peak, cut off below it, a
von Mises spread around the wind) with random phases and deep-water dispersion omega^2 = g k.
On a grid whose axes are two orthogonal ground directions, each train factorises into one phase
ramp per axis, so heights and slopes of the whole sum over the grid are one matrix product.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

GRAVITY = 9.81

#: Sea state -> (significant wave height m, peak wavelength m, sub-pixel slope variance).
SEA_STATES: dict[int, tuple[float, float, float]] = {
    1: (0.1, 4.0, 0.004),
    2: (0.3, 9.0, 0.010),
    3: (0.8, 22.0, 0.020),
    4: (1.6, 40.0, 0.032),
    5: (2.8, 60.0, 0.045),
}


@dataclass(frozen=True)
class WaveTrains:
    """``K`` trains: wavevectors ``k`` [K, 2] (east, north; rad/m), amplitudes [K] (m),
    angular frequencies [K] (rad/s) and phases [K]."""

    k: np.ndarray
    amplitude: np.ndarray
    omega: np.ndarray
    phase: np.ndarray

    def height_at(self, east: float, north: float, t: float) -> float:
        """Surface height at one point (for bobbing objects)."""
        arg = self.k[:, 0] * east + self.k[:, 1] * north - self.omega * t + self.phase
        return float(np.sum(self.amplitude * np.cos(arg)))


def draw_trains(
    rng: np.random.Generator,
    sea_state: int,
    wind_from_deg: float,
    count: int = 40,
    shortest_m: float = 0.12,
    spread_kappa: float = 4.0,
) -> WaveTrains:
    """Trains for ``sea_state`` (1-5) with the wind blowing from ``wind_from_deg``."""
    if sea_state not in SEA_STATES:
        raise ValueError(f"sea state must be one of {sorted(SEA_STATES)}, got {sea_state}")
    hs, peak_m, _ = SEA_STATES[sea_state]
    k_peak = 2 * math.pi / peak_m
    log_k = np.linspace(
        math.log(2 * math.pi / (1.6 * peak_m)), math.log(2 * math.pi / shortest_m), count
    )
    log_k += rng.uniform(-0.5, 0.5, count) * (log_k[1] - log_k[0])
    kmag = np.exp(log_k)
    density = kmag**-3.5 * np.exp(-1.25 * (k_peak / kmag) ** 2)
    energy = density * kmag  # per unit log k
    amplitude = np.sqrt(energy / energy.sum()) * hs / (4 * math.sqrt(0.5))
    towards = math.radians(wind_from_deg + 180.0)
    direction = towards + rng.vonmises(0.0, spread_kappa, count)
    k = np.stack([kmag * np.sin(direction), kmag * np.cos(direction)], axis=1)
    return WaveTrains(
        k=k,
        amplitude=amplitude,
        omega=np.sqrt(GRAVITY * kmag),
        phase=rng.uniform(0, 2 * math.pi, count),
    )


@dataclass(frozen=True)
class GroundGrid:
    """A regular grid on the ground: ``origin`` (east, north) of cell (0, 0), unit axes ``across``
    (columns) and ``along`` (rows), ``cell`` metres, ``rows`` x ``cols`` cells."""

    origin: np.ndarray
    across: np.ndarray
    along: np.ndarray
    cell: float
    rows: int
    cols: int

    def world(self) -> tuple[np.ndarray, np.ndarray]:
        """East and north of every cell, ``[rows, cols]`` each."""
        j = np.arange(self.cols) * self.cell
        i = np.arange(self.rows) * self.cell
        east = self.origin[0] + i[:, None] * self.along[0] + j[None, :] * self.across[0]
        north = self.origin[1] + i[:, None] * self.along[1] + j[None, :] * self.across[1]
        return east, north

    def index_of(self, east: np.ndarray, north: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Fractional (column, row) of world points."""
        de, dn = east - self.origin[0], north - self.origin[1]
        return (
            (de * self.across[0] + dn * self.across[1]) / self.cell,
            (de * self.along[0] + dn * self.along[1]) / self.cell,
        )


def grid_covering(
    east: np.ndarray, north: np.ndarray, heading_deg: float, cell: float, max_cells: int
) -> GroundGrid:
    """The grid aligned with ``heading_deg`` that covers the given world points, its cell
    enlarged if needed so it holds at most ``max_cells`` cells."""
    psi = math.radians(heading_deg)
    along = np.array([math.sin(psi), math.cos(psi)])
    across = np.array([math.cos(psi), -math.sin(psi)])
    s = east * across[0] + north * across[1]
    a = east * along[0] + north * along[1]
    s0, s1, a0, a1 = np.nanmin(s), np.nanmax(s), np.nanmin(a), np.nanmax(a)
    area = (s1 - s0) * (a1 - a0)
    cell = max(cell, math.sqrt(area / max_cells))
    cols, rows = int(math.ceil((s1 - s0) / cell)) + 3, int(math.ceil((a1 - a0) / cell)) + 3
    origin = (s0 - cell) * across + (a0 - cell) * along
    return GroundGrid(origin=origin, across=across, along=along, cell=cell, rows=rows, cols=cols)


def surface_on_grid(
    trains: WaveTrains, grid: GroundGrid, t: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Height and east/north slopes of the surface at every grid cell (float32 ``[rows, cols]``).

    Trains finer than two cells are left out (they would alias); the sub-pixel slope variance of
    the shading stands in for them.
    """
    kmag = np.hypot(trains.k[:, 0], trains.k[:, 1])
    keep = kmag * grid.cell < math.pi / 2
    k, amp = trains.k[keep], trains.amplitude[keep]
    origin_phase = k @ grid.origin - trains.omega[keep] * t + trains.phase[keep]
    weight = amp * np.exp(1j * origin_phase)
    k_along = k @ grid.along
    k_across = k @ grid.across
    rows = np.exp(1j * np.outer(np.arange(grid.rows) * grid.cell, k_along)).astype(np.complex64)
    cols = np.exp(1j * np.outer(k_across, np.arange(grid.cols) * grid.cell))
    right = np.concatenate(
        [
            weight[:, None] * cols,
            (1j * k[:, 0] * weight)[:, None] * cols,
            (1j * k[:, 1] * weight)[:, None] * cols,
        ],
        axis=1,
    ).astype(np.complex64)
    field = (rows @ right).real
    n = grid.cols
    return field[:, :n], field[:, n : 2 * n], field[:, 2 * n :]
