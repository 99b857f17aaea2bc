"""Noise processes of the sensor models, vectorised over samples and chunk-invariant (no ROS).

Every model draws one block of standard normals per call, ``(n_samples, n_columns)``, from its own
``numpy.random.Generator``: the stream consumed per sample is fixed, so a record made in one call equals the same
record made step by step (the graph and the library runner see the same numbers).  Uniform draws (dropouts) are
the normal CDF of a column of that block, for the same reason.

Discrete forms at the sample period ``dt`` (the IEEE Std 952 / Allan-variance noise terms):

* white noise of density ``N`` (unit/sqrt(Hz)): ``N / sqrt(dt) * w_k``  (Allan deviation ``N / sqrt(tau)``);
* bias random walk ``K`` (unit/sqrt(s)): ``b_k = b_k-1 + K sqrt(dt) w_k``  (Allan deviation ``K sqrt(tau / 3)``);
* bias instability ``B`` with correlation time ``T``: a first-order Gauss-Markov process of standard deviation
  ``B``, ``b_k = a b_k-1 + B sqrt(1 - a^2) w_k``, ``a = exp(-dt / T)`` (its Allan deviation peaks near 0.62 B at
  tau ~ 1.9 T, against the 0.664 B plateau of the flicker model datasheets quote: the usual stand-in).
"""
from __future__ import annotations

import math

import numpy as np

__all__ = ["RandomWalk", "GaussMarkov", "uniform_from_normal", "stream"]


def stream(seed: int, sensor_index: int, purpose: int) -> np.random.Generator:
    """The generator of one sensor: ``purpose`` 0 = constants drawn once (turn-on biases, scale factors), 1 = the
    per-sample stream.  Seeded from ``SeedSequence([seed, sensor_index, purpose])``: independent of the others."""
    return np.random.default_rng(np.random.SeedSequence([int(seed), int(sensor_index), int(purpose)]))


def uniform_from_normal(w: np.ndarray) -> np.ndarray:
    """U(0, 1) from standard normals (their CDF)."""
    from scipy.special import ndtr  # here, not at import: scipy.special costs every node ~0.3 s at start

    return ndtr(w)


class RandomWalk:
    """``b_k = b_k-1 + sigma sqrt(dt) w_k`` per column, from ``b0``."""

    def __init__(self, sigma_per_sqrt_s: float, dt: float, b0) -> None:
        self.step_sigma = float(sigma_per_sqrt_s) * math.sqrt(dt)
        self.b = np.array(b0, dtype=float)

    def run(self, w: np.ndarray) -> np.ndarray:
        if w.shape[0] == 0:
            return np.empty((0,) + self.b.shape)
        # the recursion itself (the previous value first, then one addition per sample): the same floating-point
        # sums however the record is cut into calls
        out = np.cumsum(np.vstack([self.b[None, :], self.step_sigma * w]), axis=0)[1:]
        self.b = out[-1].copy()
        return out


class GaussMarkov:
    """First-order Gauss-Markov per column, stationary standard deviation ``sigma``, correlation time ``tau_s``;
    starts from ``b0`` (draw it from N(0, sigma^2) for a stationary start)."""

    def __init__(self, sigma: float, tau_s: float, dt: float, b0) -> None:
        self.a = math.exp(-dt / float(tau_s))
        self.c = float(sigma) * math.sqrt(max(0.0, 1.0 - self.a * self.a))
        self.b = np.array(b0, dtype=float)

    def run(self, w: np.ndarray) -> np.ndarray:
        if w.shape[0] == 0:
            return np.empty((0,) + self.b.shape)
        from scipy.signal import lfilter  # here, not at import: scipy.signal costs every node ~0.8 s at start

        out, _ = lfilter([self.c], [1.0, -self.a], w, axis=0, zi=(self.a * self.b)[None, :])
        self.b = out[-1].copy()
        return out
