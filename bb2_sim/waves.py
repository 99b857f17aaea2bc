"""Regular deep-water waves of the BB2 ROM (SPEC 7.4): parameters per sea state, pressure and orbital velocity.

Earth frame: native, z up, z = 0 on the calm surface; the wave travels towards +x_earth.
"""
from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np

from .parameters import RomParameters


class SeaStateError(ValueError):
    """Sea state outside the table."""


@dataclass(frozen=True)
class Wave:
    """A regular wave: amplitude A (m), wavenumber k (rad/m), frequency omega (rad/s); A = 0 is calm."""

    amplitude: float = 0.0
    wavenumber: float = 0.0
    omega: float = 0.0
    phase: float = 0.0
    heading_param: float = 0.0
    sea_state: int = 0

    @property
    def calm(self) -> bool:
        return self.amplitude == 0.0

    @property
    def length(self) -> float:
        return 2 * math.pi / self.wavenumber if self.wavenumber else math.inf

    @property
    def period(self) -> float:
        return 2 * math.pi / self.omega if self.omega else math.inf


def wave_for_sea_state(sea_state: float, params: RomParameters, *, strict: bool = True) -> Wave:
    """The model's wave for an integer sea state (0 and 1 are calm, 2..7 tabulated).

    With ``strict`` a value outside 0..7 or a non-integer raises :class:`SeaStateError`; without it the
    model's own rule applies (anything not in the table is calm water).
    """
    if not math.isfinite(sea_state):
        raise SeaStateError(f"sea state must be finite, got {sea_state!r}")
    ss = int(sea_state) if float(sea_state).is_integer() else None
    table = params.sea_states
    if ss is None or (strict and not (0 <= ss <= max(table))):
        if strict:
            raise SeaStateError(f"sea state {sea_state!r} is outside the table (integers 0..{max(table)}; "
                                f"0 and 1 are calm)")
        return Wave()
    if ss not in table:
        return Wave(sea_state=ss)
    Lw, A = table[ss]
    k = 2 * math.pi / Lw
    return Wave(A, k, math.sqrt(params.g * k), params.wave_phase, params.wave_heading_param, ss)


def orbital_velocity_earth(wave: Wave, x: np.ndarray, z: np.ndarray, t: float,
                           in_phase_with_pressure: bool = False) -> np.ndarray:
    """Orbital velocity (u, v, w) in earth axes at points (x, z), shape x.shape + (3,).

    Default (quirk Q12, as implemented): the field of the elevation -A cos(kx - wt), 90 deg out of phase
    with the pressure. ``in_phase_with_pressure``: the field of A sin(kx - wt), consistent with the pressure.
    """
    x = np.asarray(x, dtype=float)
    out = np.zeros(x.shape + (3,))
    if wave.calm:
        return out
    th = wave.wavenumber * x - wave.omega * t + wave.phase
    amp = wave.amplitude * wave.omega * np.exp(wave.wavenumber * np.asarray(z, dtype=float))
    if in_phase_with_pressure:
        horiz = amp * np.sin(th)
        out[..., 2] = -amp * np.cos(th)
    else:
        horiz = -amp * np.cos(th)
        out[..., 2] = -amp * np.sin(th)
    out[..., 0] = horiz * math.cos(math.pi * wave.heading_param)
    out[..., 1] = -horiz * math.sin(math.pi * wave.heading_param)
    return out


def pressure(wave: Wave, x: np.ndarray, z: np.ndarray, t: float, rho: float, g: float) -> np.ndarray:
    """Hydrostatic + Froude-Krylov pressure at earth points (x, z): -rho g (z - A exp(kz) sin(kx - wt)), Pa."""
    z = np.asarray(z, dtype=float)
    if wave.calm:
        return (-rho * g) * z
    return (-rho * g) * (z - wave.amplitude * np.exp(wave.wavenumber * z)
                         * np.sin(wave.wavenumber * np.asarray(x, dtype=float) - wave.omega * t))
