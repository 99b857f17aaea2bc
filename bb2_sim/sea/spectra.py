"""Wave frequency spectra S(omega) (one-sided, m^2 s/rad; omega in rad/s): JONSWAP, Pierson-Moskowitz, ITTC.

Formulas, constants and sources are in ``bb2_sim/data/sea_spectra.yaml`` (key ``spectra``). Every spectrum
is a callable ``S(omega)`` with its ``hs`` (m, = 4 sqrt(m0)) and ``tp`` (s, = 2 pi / omega_p).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..constants import G_M_S2
from .data import sea_data
from .errors import SeaInputError, finite


def _pm_shape(omega: np.ndarray, hs: float, wp: float) -> np.ndarray:
    """5/16 Hs^2 wp^4 w^-5 exp(-5/4 (wp/w)^4); 0 at omega <= 0."""
    w = np.asarray(omega, dtype=float)
    out = np.zeros_like(w)
    pos = w > 0
    r = wp / w[pos]
    out[pos] = (5.0 / 16.0) * hs * hs * r ** 4 / w[pos] * np.exp(-1.25 * r ** 4)
    return out


@dataclass(frozen=True)
class ITTCSpectrum:
    """ITTC two-parameter / Bretschneider spectrum (the PM shape with free Hs and Tp)."""

    hs: float
    tp: float
    name: str = field(default="ittc", init=False)

    def __post_init__(self):
        object.__setattr__(self, "hs", finite("Hs", self.hs, positive=True))
        object.__setattr__(self, "tp", finite("Tp", self.tp, positive=True))

    @property
    def omega_p(self) -> float:
        return 2.0 * math.pi / self.tp

    def __call__(self, omega) -> np.ndarray:
        return _pm_shape(omega, self.hs, self.omega_p)


class BretschneiderSpectrum(ITTCSpectrum):
    """Same formula as :class:`ITTCSpectrum` (the names are used interchangeably)."""


@dataclass(frozen=True)
class PiersonMoskowitzSpectrum:
    """Fully developed sea: S = alpha g^2 w^-5 exp(-5/4 (wp/w)^4), wp fixed by Hs (alpha from the data)."""

    hs: float
    g: float = G_M_S2
    name: str = field(default="pierson_moskowitz", init=False)

    def __post_init__(self):
        object.__setattr__(self, "hs", finite("Hs", self.hs, positive=True))
        object.__setattr__(self, "g", finite("g", self.g, positive=True))

    @property
    def alpha(self) -> float:
        return float(sea_data()["spectra"]["pierson_moskowitz"]["alpha"])

    @property
    def omega_p(self) -> float:
        return (16.0 * self.alpha / 5.0) ** 0.25 * math.sqrt(self.g / self.hs)

    @property
    def tp(self) -> float:
        return 2.0 * math.pi / self.omega_p

    def __call__(self, omega) -> np.ndarray:
        # alpha g^2 = 5/16 Hs^2 wp^4 by the definition of wp: the same shape as ITTC
        return _pm_shape(omega, self.hs, self.omega_p)


@dataclass(frozen=True)
class JonswapSpectrum:
    """JONSWAP: the PM shape times the peak enhancement gamma^r, renormalised to the given Hs exactly."""

    hs: float
    tp: float
    gamma: float = 3.3
    name: str = field(default="jonswap", init=False)

    def __post_init__(self):
        object.__setattr__(self, "hs", finite("Hs", self.hs, positive=True))
        object.__setattr__(self, "tp", finite("Tp", self.tp, positive=True))
        gamma = finite("gamma", self.gamma)
        d = sea_data()["spectra"]["jonswap"]
        if gamma < float(d["gamma_min"]):
            raise SeaInputError(f"JONSWAP gamma must be >= {d['gamma_min']}, got {gamma!r}")
        object.__setattr__(self, "gamma", gamma)
        object.__setattr__(self, "_sig", (float(d["sigma_a"]), float(d["sigma_b"])))
        w = np.linspace(0.05, 20.0, 40001) * self.omega_p
        raw = self._raw(w)
        m0 = float(np.sum((raw[1:] + raw[:-1]) * np.diff(w)) / 2.0)
        object.__setattr__(self, "norm", (self.hs / 4.0) ** 2 / m0)

    @property
    def omega_p(self) -> float:
        return 2.0 * math.pi / self.tp

    def _raw(self, omega) -> np.ndarray:
        w = np.asarray(omega, dtype=float)
        wp = self.omega_p
        sig = np.where(w <= wp, self._sig[0], self._sig[1])
        return _pm_shape(w, 1.0, wp) * self.gamma ** np.exp(-((w - wp) ** 2) / (2.0 * sig ** 2 * wp ** 2))

    def __call__(self, omega) -> np.ndarray:
        return self.norm * self._raw(omega)


def spectrum(name: str, **kw):
    """A spectrum by name: ``jonswap`` (hs, tp, gamma), ``pierson_moskowitz`` (hs), ``ittc``/``bretschneider``."""
    key = str(name).lower().replace("-", "_")
    table = {"jonswap": JonswapSpectrum, "pierson_moskowitz": PiersonMoskowitzSpectrum, "pm": PiersonMoskowitzSpectrum,
             "ittc": ITTCSpectrum, "bretschneider": BretschneiderSpectrum, "ittc_bretschneider": ITTCSpectrum}
    if key not in table:
        raise SeaInputError(f"unknown spectrum {name!r} (one of {', '.join(sorted(table))})")
    return table[key](**kw)
