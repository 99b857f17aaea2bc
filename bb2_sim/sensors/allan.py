"""Overlapping Allan deviation of a rate signal (no ROS): the statistic the sensor tests check noise against.

For a rate signal ``y_k`` sampled every ``dt`` (a gyro's rad/s, an accelerometer's m/s^2), with the integral
``x_j = dt * sum_{k<j} y_k`` and ``tau = m dt``::

    AVAR(tau) = sum_{j} (x_{j+2m} - 2 x_{j+m} + x_j)^2 / (2 tau^2 (N - 2m))    over all N - 2m overlapping j

(IEEE Std 952-1997 annex C; the same estimator as ``allantools.oadev``, against which it is tested).  White noise
of density ``N`` gives ``N / sqrt(tau)``, a random walk ``K`` gives ``K sqrt(tau / 3)``.
"""
from __future__ import annotations

import numpy as np

__all__ = ["overlapping_adev", "octave_m"]


def octave_m(n: int, max_fraction: float = 0.1) -> np.ndarray:
    """Averaging factors 1, 2, 4, ... up to ``max_fraction`` of the record length."""
    top = max(1, int(n * max_fraction))
    return 2 ** np.arange(int(np.log2(top)) + 1)


def overlapping_adev(y, dt: float, m=None) -> tuple[np.ndarray, np.ndarray]:
    """(tau, adev) of the rate record ``y`` (1-D, or 2-D: one column per axis) at averaging factors ``m``."""
    y = np.asarray(y, dtype=float)
    if y.ndim == 1:
        y = y[:, None]
    n = y.shape[0]
    m = octave_m(n) if m is None else np.asarray(m, dtype=int)
    x = np.vstack([np.zeros((1, y.shape[1])), np.cumsum(y, axis=0) * dt])
    out = []
    for mm in m:
        d = x[2 * mm:] - 2.0 * x[mm:-mm] + x[:-2 * mm]
        out.append(np.sqrt(np.mean(d * d, axis=0) / (2.0 * (mm * dt) ** 2)))
    adev = np.array(out)
    return m * dt, adev[:, 0] if adev.shape[1] == 1 else adev
