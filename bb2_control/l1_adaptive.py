"""Sampled-data SISO L1 adaptive augmentation with piecewise-constant adaptation (SPEC 5).

One channel augments a baseline "autopilot + vehicle" loop that follows a reference ``u_ad`` and
produces a measured output ``y`` (a body rate for the 2022 rate loop, depth or heading for the 2023
depth/heading loop).  Every ``Ts`` the channel

1. predicts ``y_hat = Cm x_hat``,
2. estimates the lumped uncertainty ``sigma = g_sigma (y_hat - y)`` (held over the tick),
3. outputs ``u_ad = Kg rho - Co x_u`` (old ``x_u``),
4. updates the low-pass state ``x_u <- Eo x_u + Go expm(-Am Ts) sigma``,
5. updates the predictor ``x_hat <- Em x_hat + Gamma (Bm u_ad + sigma)``.

The design objects (``Kg``, ``P``, ``Lambda``, ``Phi``, ``g_sigma``, a minimal realisation of
``O(s) = C(s) M(s)^-1 Cm (sI - Am)^-1`` and the zero-order-hold matrices) are computed once by
:func:`design_channel` from the desired system ``M`` (state space, or transfer function), the
low-pass filter ``C(s)`` and ``Ts``.  Numbers live in ``bb2_control/data/l1_configs.yaml``.

Notation follows Martin et al. 2022 (arXiv 2212.09821, "Controller") and SPEC 5.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from operator import mul
from typing import Any, Mapping, Sequence

import numpy as np

from bb2_control.errors import ControlConfigError, NonFiniteInputError

__all__ = [
    "L1DesignError",
    "NonFiniteInputError",
    "L1Design",
    "design_channel",
    "design_from_config",
    "L1Channel",
    "L1Augmentation",
]


class L1DesignError(ControlConfigError):
    """The desired system / filter / sample time do not define a valid L1 channel."""


def _mat(x: Any, name: str) -> np.ndarray:
    a = np.atleast_2d(np.asarray(x, dtype=float))
    if not np.all(np.isfinite(a)):
        raise L1DesignError(f"{name} has non-finite entries: {a!r}")
    return a


def _zoh(A: np.ndarray, B: np.ndarray, Ts: float) -> tuple[np.ndarray, np.ndarray]:
    """(expm(A Ts), int_0^Ts expm(A t) dt B) from one exponential of [[A, B], [0, 0]] Ts."""
    from scipy import linalg  # (each process that designs a channel; see design_channel)

    n, m = A.shape[0], B.shape[1]
    big = np.zeros((n + m, n + m))
    big[:n, :n] = A
    big[:n, n:] = B
    E = linalg.expm(big * Ts)
    return E[:n, :n], E[:n, n:]


def _poly(x: Sequence[float], name: str) -> np.ndarray:
    p = np.trim_zeros(np.atleast_1d(np.asarray(x, dtype=float)), "f")
    if p.size == 0 or not np.all(np.isfinite(p)):
        raise L1DesignError(f"{name} must be a non-zero finite polynomial, got {x!r}")
    return p


def _observer_form(nums: list[np.ndarray], den: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Observer canonical form of a strictly proper 1 x m row ``[nums_j / den]``."""
    a = den / den[0]
    n = a.size - 1
    A = np.zeros((n, n))
    A[:, 0] = -a[1:]
    A[:-1, 1:] = np.eye(n - 1)
    B = np.zeros((n, len(nums)))
    for j, num in enumerate(nums):
        num = np.trim_zeros(num / den[0], "f")
        if num.size > n:
            raise L1DesignError("O(s) is not strictly proper: the filter C(s) needs a higher relative degree")
        B[n - num.size:, j] = num
    C = np.zeros((1, n))
    C[0, 0] = 1.0
    return A, B, C


def _controllable_part(A: np.ndarray, B: np.ndarray, C: np.ndarray, tol: float = 1e-10):
    """Restrict an (observable) realisation to its controllable subspace: a minimal realisation."""
    from scipy import linalg

    n = A.shape[0]
    ctrb = np.hstack([np.linalg.matrix_power(A, i) @ B for i in range(n)])
    T = linalg.orth(ctrb, rcond=tol)
    if T.shape[1] == n:
        return A, B, C
    return T.T @ A @ T, T.T @ B, C @ T


@dataclass(frozen=True)
class L1Design:
    """Constant matrices of one sampled-data SISO L1 channel (SPEC 5.2-5.3).

    Am, Bm, Cm: desired system M(s) = Cm (sI - Am)^-1 Bm (n_m states, one input, one output).
    Kg: -(Cm Am^-1 Bm)^-1.  P: Am' P + P Am = -Q.  sqrtP, D, Lam (Lambda), Phi, Phiinv as in the paper.
    g_sigma: (n_m, 1) adaptation gain, sigma = g_sigma (y_hat - y).
    Ao, Bo, Co: minimal realisation of O(s).  Em = expm(Am Ts), Gamma = int_0^Ts expm(Am t) dt,
    Eo = expm(Ao Ts), Go = int_0^Ts expm(Ao t) dt Bo, Em_inv = expm(-Am Ts).
    """

    Ts: float
    Am: np.ndarray
    Bm: np.ndarray
    Cm: np.ndarray
    Kg: float
    P: np.ndarray
    sqrtP: np.ndarray
    D: np.ndarray
    Lam: np.ndarray
    Phi: np.ndarray
    Phiinv: np.ndarray
    g_sigma: np.ndarray
    Ao: np.ndarray
    Bo: np.ndarray
    Co: np.ndarray
    Em: np.ndarray
    Gamma: np.ndarray
    Eo: np.ndarray
    Go: np.ndarray
    Em_inv: np.ndarray
    C_num: np.ndarray = field(repr=False)
    C_den: np.ndarray = field(repr=False)

    @property
    def n_m(self) -> int:
        return self.Am.shape[0]

    @property
    def n_o(self) -> int:
        return self.Ao.shape[0]


def ss2tf_siso(A: Any, B: Any, C: Any) -> tuple[np.ndarray, np.ndarray]:
    """``scipy.signal.ss2tf(A, B, C, 0)`` of a single-input single-output system: (num of shape (1, n + 1), den),
    by the same operations on numpy's ``poly`` (equal to the last digit: ``tests/control/test_l1_adaptive.py``),
    without importing scipy.signal, which costs every process that designs an L1 channel (the autopilot node) ~0.35 s
    of CPU on this machine.  num = poly(A - B C) - poly(A): the numerator of C (sI - A)^-1 B."""
    A, B, C = (np.atleast_2d(np.asarray(x)) for x in (A, B, C))
    den = np.poly(A)
    num = np.empty((1, A.shape[0] + 1), (A[:, 0] + B[:, 0] + C[0, :] + 0.0).dtype)
    num[0] = np.poly(A - np.dot(B, C)) + (0.0 - 1) * den
    return num, den


def design_channel(
    C_num: Sequence[float],
    C_den: Sequence[float],
    Ts: float,
    *,
    M_ss: tuple[Any, Any, Any] | None = None,
    M_tf: tuple[Sequence[float], Sequence[float]] | None = None,
    Q: Any = None,
) -> L1Design:
    """Build the constant matrices of one L1 channel.

    Args:
        C_num, C_den: low-pass filter C(s) (strictly proper, stable, C(0) = 1), coefficients in s,
            highest power first.
        Ts: sample time, s.
        M_ss: desired system realisation (Am, Bm, Cm).  It matters: P, Lambda and Phi depend on it.
        M_tf: desired system (num, den); used (controller canonical form of scipy.signal.tf2ss)
            when ``M_ss`` is not given, otherwise checked against ``M_ss``.
        Q: positive-definite Lyapunov weight, identity by default.

    Raises:
        L1DesignError: on any violated design assumption (A_m not Hurwitz, C(0) != 1, C not strictly
            proper or unstable, O(s) improper, realisation not matching M_tf, Ts <= 0).
    """
    from scipy import linalg  # here, not at import: every node imports this module (a mission names its stack);
    # scipy.linalg costs ~0.2 s of CPU in each process, and only the autopilot (and path following) design channels

    Ts = float(Ts)
    if not np.isfinite(Ts) or Ts <= 0:
        raise L1DesignError(f"Ts must be a positive number of seconds, got {Ts!r}")
    if M_ss is None and M_tf is None:
        raise L1DesignError("give the desired system as M_ss=(Am, Bm, Cm) or M_tf=(num, den)")
    if M_ss is not None:
        Am, Bm, Cm = (_mat(x, n) for x, n in zip(M_ss, ("Am", "Bm", "Cm")))
    else:
        from scipy import signal  # here, not at import: scipy.signal (and the scipy.stats it imports) costs a
        # process ~0.35 s of CPU on this machine; the shipped channels give M_ss

        Am, Bm, Cm, _ = signal.tf2ss(_poly(M_tf[0], "M num"), _poly(M_tf[1], "M den"))
    nm = Am.shape[0]
    if Am.shape != (nm, nm) or Bm.shape != (nm, 1) or Cm.shape != (1, nm):
        raise L1DesignError(f"M must be SISO: got Am {Am.shape}, Bm {Bm.shape}, Cm {Cm.shape}")
    if not np.all(np.real(np.linalg.eigvals(Am)) < 0):
        raise L1DesignError(f"Am must be Hurwitz, eigenvalues {np.linalg.eigvals(Am)}")
    numM, denM = ss2tf_siso(Am, Bm, Cm)
    numM = np.trim_zeros(np.real(numM[0]), "f")
    denM = np.real(denM)
    if M_ss is not None and M_tf is not None:
        n_tf, d_tf = _poly(M_tf[0], "M num"), _poly(M_tf[1], "M den")
        if d_tf.size != denM.size or not (np.allclose(d_tf / d_tf[0], denM, rtol=1e-9, atol=1e-12)
                                          and np.allclose(n_tf / d_tf[0], numM, rtol=1e-9, atol=1e-12)):
            raise L1DesignError("M_ss does not realise M_tf (or is not minimal)")
    if numM.size > 1 and np.any(np.real(np.roots(numM)) >= 0):
        raise L1DesignError(f"M(s) has non-minimum-phase zeros {np.roots(numM)}")

    Cn, Cd = _poly(C_num, "C num"), _poly(C_den, "C den")
    if Cn.size >= Cd.size:
        raise L1DesignError("C(s) must be strictly proper")
    if not np.all(np.real(np.roots(Cd)) < 0):
        raise L1DesignError(f"C(s) must be stable, poles {np.roots(Cd)}")
    if not np.isclose(np.polyval(Cn, 0.0) / np.polyval(Cd, 0.0), 1.0, rtol=1e-9):
        raise L1DesignError(f"C(0) must be 1, got {np.polyval(Cn, 0.0) / np.polyval(Cd, 0.0)}")

    Kg = float(-np.linalg.inv(Cm @ np.linalg.solve(Am, Bm)).item())

    Qm = np.eye(nm) if Q is None else _mat(Q, "Q")
    P = linalg.solve_continuous_lyapunov(Am.T, -Qm)
    sqrtP = np.real(linalg.sqrtm(P))
    if nm > 1:
        D = linalg.null_space(Cm @ np.linalg.inv(sqrtP)).T
        Lam = np.vstack([Cm, D @ sqrtP])
    else:
        D = np.zeros((0, 1))
        Lam = Cm.copy()

    Em, Gamma = _zoh(Am, np.eye(nm), Ts)
    Phi = Lam @ Gamma
    Phiinv = np.linalg.inv(Phi)
    LAL = Lam @ Am @ np.linalg.inv(Lam)
    e1 = np.zeros((nm, 1))
    e1[0, 0] = 1.0
    g_sigma = -Phiinv @ linalg.expm(LAL * Ts) @ e1

    # O(s) = C(s) M(s)^-1 Cm (sI - Am)^-1 = Cn * row_j / (Cd * numM), row_j / det(sI - Am) = Cm adj(sI - Am) e_j
    row_nums = []
    for j in range(nm):
        rn, _ = ss2tf_siso(Am, np.eye(nm)[:, [j]], Cm)
        row_nums.append(np.real(rn[0]))
    O_den = np.polymul(Cd, numM)
    O_nums = [np.polymul(Cn, rn) for rn in row_nums]
    Ao, Bo, Co = _controllable_part(*_observer_form(O_nums, O_den))

    Eo, Go = _zoh(Ao, Bo, Ts)
    return L1Design(Ts=Ts, Am=Am, Bm=Bm, Cm=Cm, Kg=Kg, P=P, sqrtP=sqrtP, D=D, Lam=Lam, Phi=Phi,
                    Phiinv=Phiinv, g_sigma=g_sigma, Ao=Ao, Bo=Bo, Co=Co, Em=Em, Gamma=Gamma, Eo=Eo,
                    Go=Go, Em_inv=linalg.expm(-Am * Ts), C_num=Cn, C_den=Cd)


def design_from_config(channel: Mapping[str, Any], Ts: float) -> L1Design:
    """Design a channel from a data mapping with ``M_ss`` {Am, Bm, Cm} and/or ``M_tf`` {num, den} and ``C_tf``."""
    try:
        C = channel["C_tf"]
        M_ss = channel.get("M_ss")
        M_tf = channel.get("M_tf")
        return design_channel(
            C["num"], C["den"], Ts,
            M_ss=None if M_ss is None else (M_ss["Am"], M_ss["Bm"], M_ss["Cm"]),
            M_tf=None if M_tf is None else (M_tf["num"], M_tf["den"]),
            Q=channel.get("Q"),
        )
    except KeyError as exc:
        raise L1DesignError(f"L1 channel config lacks key {exc}") from None


def _rows(a: np.ndarray) -> tuple[tuple[float, ...], ...]:
    """A matrix as a tuple of its rows of Python floats (the channel's tick runs on floats)."""
    return tuple(tuple(float(v) for v in row) for row in np.atleast_2d(a))


def _times(rows: tuple[tuple[float, ...], ...], x: list[float]) -> list[float]:
    """rows @ x on floats (each product summed left to right)."""
    return [sum(map(mul, row, x)) for row in rows]


class L1Channel:
    """One sampled-data SISO L1 channel; call :meth:`step` exactly once every ``design.Ts``.

    With ``adaptive=False`` the channel passes the reference through (``u_ad = rho``) and its states
    are frozen; switching adaptation on re-initialises them from the next measurement (SPEC 5.3).

    The tick runs on Python floats (the design's matrices as rows of floats; each product summed left to right):
    for these sizes (n_m = 1, n_o = 3 in the paper's channels) a quarter of the cost of numpy's small matrix
    products, equal to them to round-off. ``x_u``, ``x_hat`` and ``sigma_hat`` read as (n, 1) arrays.
    """

    def __init__(self, design: L1Design, adaptive: bool = True) -> None:
        self.design = design
        d = design
        self._Cm, self._Co, self._Eo, self._Go = _rows(d.Cm), _rows(d.Co), _rows(d.Eo), _rows(d.Go)
        self._Em, self._Gamma, self._Em_inv = _rows(d.Em), _rows(d.Gamma), _rows(d.Em_inv)
        self._Bm = [r[0] for r in _rows(d.Bm)]
        self._g_sigma = [r[0] for r in _rows(d.g_sigma)]
        self._Kg = float(d.Kg)
        self._scalar_predictor = d.n_m == 1
        self._adaptive = bool(adaptive)
        self.reset()

    @property
    def adaptive(self) -> bool:
        return self._adaptive

    @adaptive.setter
    def adaptive(self, on: bool) -> None:
        if bool(on) and not self._adaptive:
            self._initialised = False
        self._adaptive = bool(on)

    @property
    def x_u(self) -> np.ndarray:
        """Low-pass filter state (n_o, 1)."""
        return np.array(self._x_u).reshape(-1, 1)

    @property
    def x_hat(self) -> np.ndarray:
        """State predictor (n_m, 1)."""
        return np.array(self._x_hat).reshape(-1, 1)

    @property
    def sigma_hat(self) -> np.ndarray:
        """Uncertainty estimate of the last tick (n_m, 1)."""
        return np.array(self._sigma_hat).reshape(-1, 1)

    def reset(self, y0: float | None = None) -> None:
        """Clear the states; ``x_hat = Cm^+ y0`` is set from ``y0`` or from the first measurement."""
        d = self.design
        self._x_u = [0.0] * d.n_o
        self._x_hat = [0.0] * d.n_m
        self._sigma_hat = [0.0] * d.n_m
        self.u_ad = float("nan")
        self._initialised = False
        if y0 is not None:
            self._init_from(float(y0))

    def _init_from(self, y0: float) -> None:
        Cm = self.design.Cm
        self._x_hat = [float(v) for v in (Cm.T @ np.linalg.solve(Cm @ Cm.T, np.array([[y0]]))).ravel()]
        self._x_u = [0.0] * self.design.n_o
        self._initialised = True

    @property
    def y_hat(self) -> float:
        """Predictor output Cm x_hat for the current tick."""
        return sum(map(mul, self._Cm[0], self._x_hat))

    def step(self, reference: float, y: float) -> float:
        """One tick: reference rho and measurement y (same units) -> u_ad, held until the next tick.

        Raises:
            NonFiniteInputError: if ``reference`` or ``y`` is NaN or infinite (states are unchanged).
        """
        rho, y = float(reference), float(y)
        if not (math.isfinite(rho) and math.isfinite(y)):
            raise NonFiniteInputError(f"L1 channel input is not finite: reference={rho}, y={y}")
        if not self._adaptive:
            self.u_ad = rho
            return rho
        if not self._initialised:
            self._init_from(y)
        if self._scalar_predictor:                       # n_m = 1 (the paper's channels), written out
            x_u = self._x_u
            (cm,), (g,), (em,), (gam,), (emi,), (bm,) = self._Cm[0], self._g_sigma, self._Em[0], self._Gamma[0], \
                self._Em_inv[0], self._Bm
            xh = self._x_hat[0]
            sg = g * (cm * xh - y)
            u = self._Kg * rho - sum(map(mul, self._Co[0], x_u))
            m = emi * sg
            self._x_u = [sum(map(mul, row, x_u)) + go * m for row, (go,) in zip(self._Eo, self._Go)]
            self._x_hat = [em * xh + gam * (bm * u + sg)]
            self._sigma_hat = [sg]
            self.u_ad = u
            return u
        e = self.y_hat - y
        sigma = [g * e for g in self._g_sigma]
        u = self._Kg * rho - sum(map(mul, self._Co[0], self._x_u))
        drive = _times(self._Go, _times(self._Em_inv, sigma))
        self._x_u = [a + b for a, b in zip(_times(self._Eo, self._x_u), drive)]
        inp = [b * u + sg for b, sg in zip(self._Bm, sigma)]
        self._x_hat = [a + b for a, b in zip(_times(self._Em, self._x_hat), _times(self._Gamma, inp))]
        self._sigma_hat = sigma
        self.u_ad = u
        return u


class L1Augmentation:
    """Named independent SISO channels (e.g. ``q``/``r`` or ``depth``/``heading``) sharing one Ts."""

    def __init__(self, channels: Mapping[str, L1Channel]) -> None:
        if not channels:
            raise L1DesignError("an L1 augmentation needs at least one channel")
        self.channels = dict(channels)

    @classmethod
    def from_config(cls, config: Mapping[str, Any], adaptive: bool = True) -> "L1Augmentation":
        """From a configuration mapping ``{Ts, channels: {name: {...} | {same_as: other}}}``."""
        try:
            Ts = float(config["Ts_s"])
            chans = config["channels"]
        except KeyError as exc:
            raise L1DesignError(f"L1 configuration lacks key {exc}") from None
        designs: dict[str, L1Design] = {}
        for name, ch in chans.items():
            if "same_as" not in ch:
                designs[name] = design_from_config(ch, Ts)
        for name, ch in chans.items():
            if "same_as" in ch:
                if ch["same_as"] not in designs:
                    raise L1DesignError(f"L1 channel {name!r}: same_as {ch['same_as']!r} is not a channel")
                designs[name] = designs[ch["same_as"]]
        order = list(chans)
        return cls({n: L1Channel(designs[n], adaptive) for n in order})

    @property
    def adaptive(self) -> bool:
        return all(c.adaptive for c in self.channels.values())

    @adaptive.setter
    def adaptive(self, on: bool) -> None:
        for c in self.channels.values():
            c.adaptive = on

    def reset(self) -> None:
        for c in self.channels.values():
            c.reset()

    def step(self, references: Mapping[str, float], measurements: Mapping[str, float]) -> dict[str, float]:
        """One tick of every channel: ``{name: reference}``, ``{name: y}`` -> ``{name: u_ad}``.

        All inputs are checked before any channel is updated, so a bad input leaves every state unchanged.
        """
        for n in self.channels:
            if n not in references or n not in measurements:
                raise L1DesignError(f"L1 step needs a reference and a measurement for channel {n!r}")
            r, y = float(references[n]), float(measurements[n])
            if not (math.isfinite(r) and math.isfinite(y)):
                raise NonFiniteInputError(f"L1 channel {n!r} input is not finite: reference={r}, y={y}")
        return {n: c.step(references[n], measurements[n]) for n, c in self.channels.items()}
