"""Wave components of a linear sea: amplitude (m), omega (rad/s), direction (rad, travelling towards, native
earth frame, 0 = +x_E) and phase (rad), with the deep-water wavenumber k = omega^2 / g.

The elevation is  eta(x, y, t) = sum_i a_i cos(k_i (x cos mu_i + y sin mu_i) - omega_i t + eps_i).

Built from a spectrum (:func:`discretise`), as one regular wave (:func:`regular_components`) or read from a
CSV component list (:func:`read_components_csv`; columns amplitude_m, omega_rad_s, direction_deg, phase_deg).
"""
from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..constants import G_M_S2
from .data import sea_data
from .errors import SeaInputError, finite
from .spreading import Cos2sSpreading

CSV_COLUMNS = ("amplitude_m", "omega_rad_s", "direction_deg", "phase_deg")


@dataclass(frozen=True)
class WaveComponents:
    """Arrays of equal length n >= 1 (see the module docstring for the convention)."""

    amplitude: np.ndarray
    omega: np.ndarray
    direction: np.ndarray
    phase: np.ndarray
    g: float = G_M_S2

    def __post_init__(self):
        arrs = [np.atleast_1d(np.asarray(a, dtype=float)).copy() for a in
                (self.amplitude, self.omega, self.direction, self.phase)]
        n = len(arrs[0])
        if n < 1 or any(a.ndim != 1 or len(a) != n for a in arrs):
            raise SeaInputError("wave components need 1-D amplitude, omega, direction, phase of one length >= 1")
        for name, a in zip(("amplitude", "omega", "direction", "phase"), arrs):
            if not np.all(np.isfinite(a)):
                raise SeaInputError(f"wave component {name}s must be finite")
        if np.any(arrs[0] < 0):
            raise SeaInputError("wave component amplitudes must be >= 0")
        if np.any(arrs[1] <= 0):
            raise SeaInputError("wave component frequencies omega must be > 0")
        for name, a in zip(("amplitude", "omega", "direction", "phase"), arrs):
            a.setflags(write=False)
            object.__setattr__(self, name, a)
        object.__setattr__(self, "g", finite("g", self.g, positive=True))

    def __len__(self) -> int:
        return len(self.amplitude)

    @property
    def wavenumber(self) -> np.ndarray:
        return self.omega ** 2 / self.g

    @property
    def hs(self) -> float:
        """4 sqrt(m0) of the components (m)."""
        return 4.0 * math.sqrt(float(np.sum(self.amplitude ** 2)) / 2.0)


def regular_components(amplitude: float, period: float, direction_deg: float = 0.0, phase_deg: float = 0.0,
                       g: float = G_M_S2) -> WaveComponents:
    """One regular wave a cos(k (x cos mu + y sin mu) - omega t + eps)."""
    a = finite("amplitude", amplitude, nonnegative=True)
    T = finite("period", period, positive=True)
    return WaveComponents([a], [2 * math.pi / T], [math.radians(finite("direction", direction_deg))],
                          [math.radians(finite("phase", phase_deg))], g)


def discretise(spec, n: int, *, seed: int | None = 0, method: str = "equal_energy",
               spreading: Cos2sSpreading | None = None, mean_direction_deg: float = 0.0,
               n_directions: int | None = None, jitter: float | None = None,
               omega_range_over_wp: tuple[float, float] | None = None, g: float = G_M_S2) -> WaveComponents:
    """N components of the spectrum ``spec`` (see ``sea_spectra.yaml`` -> ``discretisation``).

    method ``equal_energy`` (bins of equal energy) or ``equal_domega`` (bins of equal width); in both the
    component's omega is drawn within its bin (``jitter`` fraction of it; 0 = bin centre, which repeats the
    record after 2 pi / d omega for equal widths) and its amplitude is sqrt(2 m0_bin). Long-crested seas
    travel towards ``mean_direction_deg``; with ``spreading`` every component gets a direction drawn in
    equal-probability strata of D (shuffled over the frequencies), or with ``n_directions`` = M every
    frequency bin is split into M directional components (N * M in all). Phases are uniform from ``seed``.
    """
    try:
        n = int(n)
    except (TypeError, ValueError) as exc:
        raise SeaInputError(f"number of components must be an integer >= 1, got {n!r}") from exc
    if n < 1:
        raise SeaInputError(f"number of components must be >= 1, got {n}")
    d = sea_data()["discretisation"]
    jitter = finite("jitter", d["jitter"] if jitter is None else jitter, nonnegative=True)
    if jitter > 1:
        raise SeaInputError(f"jitter is a fraction of the bin, <= 1, got {jitter}")
    lo, hi = omega_range_over_wp or d["omega_range_over_wp"]
    lo, hi = finite("omega range low", lo, positive=True), finite("omega range high", hi, positive=True)
    if hi <= lo:
        raise SeaInputError(f"omega range must be increasing, got {lo}, {hi}")
    rng = np.random.default_rng(seed)
    wp = spec.omega_p
    w = np.linspace(lo * wp, hi * wp, int(d["fine_grid_points"]))
    S = spec(w)
    cum = np.concatenate([[0.0], np.cumsum((S[1:] + S[:-1]) * np.diff(w) / 2.0)])
    if method == "equal_energy":
        edges = np.interp(np.linspace(0.0, cum[-1], n + 1), cum, w)
    elif method == "equal_domega":
        edges = np.linspace(w[0], w[-1], n + 1)
    else:
        raise SeaInputError(f"discretisation method must be 'equal_energy' or 'equal_domega', got {method!r}")
    m0_bin = np.diff(np.interp(edges, w, cum))
    omega = 0.5 * (edges[1:] + edges[:-1]) + jitter * (rng.random(n) - 0.5) * np.diff(edges)
    amp = np.sqrt(2.0 * m0_bin)
    mean = math.radians(finite("mean direction", mean_direction_deg))
    if spreading is None:
        direction = np.full(n, mean)
    elif n_directions is None:
        direction = rng.permutation(spreading.strata(n, rng, jitter)[0])
    else:
        m = int(n_directions)
        if m < 1:
            raise SeaInputError(f"n_directions must be >= 1, got {n_directions!r}")
        dirs = np.array([spreading.strata(m, rng, jitter)[0] for _ in range(n)])   # (n, m)
        omega = np.repeat(omega, m)
        amp = np.repeat(amp / math.sqrt(m), m)
        direction = dirs.reshape(-1)
    phase = rng.uniform(0.0, 2.0 * math.pi, len(omega))
    return WaveComponents(amp, omega, direction, phase, g)


def read_components_csv(path: str | Path, g: float = G_M_S2) -> WaveComponents:
    """A user component list: a CSV with the header ``amplitude_m, omega_rad_s, direction_deg, phase_deg``."""
    with open(path, newline="") as fh:
        rows = list(csv.DictReader(fh))
    if not rows:
        raise SeaInputError(f"{path}: no wave components")
    missing = [c for c in CSV_COLUMNS if c not in rows[0]]
    if missing:
        raise SeaInputError(f"{path}: missing column(s) {', '.join(missing)} (need {', '.join(CSV_COLUMNS)})")
    try:
        vals = np.array([[float(r[c]) for c in CSV_COLUMNS] for r in rows])
    except (TypeError, ValueError) as exc:
        raise SeaInputError(f"{path}: non-numeric wave component value ({exc})") from exc
    return WaveComponents(vals[:, 0], vals[:, 1], np.radians(vals[:, 2]), np.radians(vals[:, 3]), g)


def write_components_csv(path: str | Path, comps: WaveComponents) -> None:
    """Write ``comps`` in the format :func:`read_components_csv` reads (degrees, full precision)."""
    with open(path, "w", newline="") as fh:
        wr = csv.writer(fh)
        wr.writerow(CSV_COLUMNS)
        for a, w, mu, e in zip(comps.amplitude, comps.omega, np.degrees(comps.direction), np.degrees(comps.phase)):
            wr.writerow([repr(float(a)), repr(float(w)), repr(float(mu)), repr(float(e))])
