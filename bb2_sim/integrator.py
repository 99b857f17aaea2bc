"""Fixed-step ode3 (Bogacki-Shampine) with the Simulink block semantics of the reference (SPEC 11).

One major step n -> n+1 (t_n = n h):

1. output at (t_n, x_n): the commands go through the discrete rate limiters (direct feed-through) and the
   model is evaluated with the Derivative blocks against the previous major sample -> k1, loads, outputs;
2. update: the limiters keep y_n, the Derivative blocks store (t_n, u_n);
3. k2 = f(t_n + h/2, x_n + h/2 k1), k3 = f(t_n + 3h/4, x_n + 3h/4 k2) with held actuator outputs,
   x_{n+1} = x_n + h (2/9 k1 + 1/3 k2 + 4/9 k3).

``substeps`` k > 1 (not the reference's: an option for speeds where the authors' step is numerically unstable, a
steady cruise from about 11.6 m/s at h = 0.05 s: ``data/substeps_stability.yaml``) integrates the major step as k
such ode3 steps of h/k, each a major step of the model's Derivative blocks (1 and 3 above at t_n + j h/k), with the
actuators' outputs of step 1 held: the commands, the actuators and every output stay at the rate 1/h.  k = 1 is the
reference's step, bit for bit.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Sequence

import numpy as np

from .actuators import ActuatorOutputs, Actuators
from .added_mass import DerivativeMemory
from .model import BB2Model, Evaluation


class NonFiniteStateError(FloatingPointError):
    """The simulation produced a NaN or inf state (the model diverged)."""

    def __init__(self, t: float, state: np.ndarray, what: str = "state"):
        self.t = t
        self.state = state
        names = ["x", "y", "z", "phi", "theta", "psi", "u", "v", "w", "p", "q", "r"]
        bad = [n for n, s in zip(names, state) if not np.isfinite(s)] if len(state) == 12 else []
        super().__init__(f"simulation diverged at t = {t:.2f} s: non-finite {what}"
                         + (f" ({', '.join(bad)})" if bad else ""))


@dataclass
class StepRecord:
    """What a major step logs: the state at t_n, the loads of the major evaluation, the actuators."""

    t: float
    x: np.ndarray
    commands_planes_deg: np.ndarray
    command_rps: float
    act: ActuatorOutputs
    ev: Evaluation


def check_substeps(substeps) -> int:
    """``substeps`` as an integer >= 1 (ValueError naming it otherwise)."""
    if isinstance(substeps, bool) or not isinstance(substeps, (int, np.integer)) or substeps < 1:
        raise ValueError(f"substeps must be an integer >= 1, got {substeps!r}")
    return int(substeps)


STABILITY_DATA = Path(__file__).resolve().parent / "data" / "substeps_stability.yaml"


@lru_cache(maxsize=1)
def cruise_limits() -> dict[int, tuple[float, float]]:
    """Per number of sub-steps K: (the fastest steady cruise flown, the slowest that diverged), m/s, as measured
    (``data/substeps_stability.yaml``, ``benchmarks/substeps_stability.py``)."""
    import yaml

    doc = yaml.safe_load(STABILITY_DATA.read_text())
    return {int(k): (float(v["flown_m_s"]), float(v["diverged_m_s"])) for k, v in doc["cruise"].items()}


HINT_FROM = 0.9
"""A diverged run is advised more sub-steps when it held at least this fraction of the fastest steady cruise its
sub-steps fly (below, say a capsize at low speed, the step is not the likely cause)."""
HINT_MARGIN = 1.1
"""The advice is the fewest sub-steps whose fastest steady cruise is this much above the speed the boat held (a
boat holding a speed may still be speeding up towards its cruise)."""


def substeps_for(speed_mps: float, substeps: int = 1, margin: float = HINT_MARGIN) -> int:
    """More sub-steps than ``substeps`` for a boat at ``speed_mps``: the fewest whose measured steady cruise flies
    ``margin`` times that speed; beyond the measured table, twice the larger of ``substeps`` and its largest."""
    limits = cruise_limits()
    fit = [k for k, (flown, _) in sorted(limits.items()) if k > substeps and flown >= margin * speed_mps]
    return fit[0] if fit else 2 * max(substeps, max(limits))


@lru_cache(maxsize=1)
def _cruise_m_s_per_rps() -> float:
    import yaml

    return float(yaml.safe_load(STABILITY_DATA.read_text())["cruise_m_s_per_rps"])


def cruise_speed(rps: float) -> float:
    """The ROM's steady straight-ahead speed with the propeller at ``rps``, m/s (measured with the cruise limits)."""
    return _cruise_m_s_per_rps() * float(rps)


def speed_warning(speed_mps: float, substeps: int, option: str, subject: str = "the boat") -> str:
    """Before a run: '' or one line saying that ``subject`` at ``speed_mps`` (what the run is expected to hold) is
    faster than the steady cruise ``substeps`` fly, naming ``option`` with the fewest sub-steps that fly it (none
    for sub-steps beyond the measured table)."""
    limits = cruise_limits()
    if substeps not in limits or not speed_mps > limits[substeps][0]:
        return ""
    flown = limits[substeps][0]
    more = substeps_for(speed_mps, substeps, margin=1.0)
    reach = (f"to about {limits[more][0]:.1f} m/s" if more in limits else
             "faster than measured (benchmarks/substeps_stability.py)")
    return (f"{subject} at about {speed_mps:.1f} m/s is faster than the ROM's 0.05 s step in {substeps} ode3 step(s) "
            f"flies steadily (about {flown:.1f} m/s) and will likely diverge; {option} {more} flies {reach}")


def substeps_hint(t_s: Sequence[float], speed_mps: Sequence[float], substeps: int, option: str) -> str:
    """For a run that diverged: '' or one line advising ``option`` with more ``substeps`` (:func:`substeps_for`)
    when the boat held, over its last 2 s, at least :data:`HINT_FROM` of the fastest steady cruise that
    ``substeps`` fly (``t_s``, ``speed_mps``: its logged times and speeds, the last finite ones; a boat that
    capsized at low speed gets no such hint)."""
    t = np.asarray(t_s, dtype=float)
    u = np.asarray(speed_mps, dtype=float)
    if t.size == 0:
        return ""
    held = float(np.min(u[t >= t[-1] - 2.0]))
    limits = cruise_limits()
    flown, _ = limits.get(substeps, limits[max(limits)])
    if not held >= HINT_FROM * flown:
        return ""
    more = substeps_for(held, substeps)
    measured = ", ".join(f"{d:.1f}{' m/s' * (i == 0)} with {k}" for i, (k, (_, d)) in enumerate(sorted(limits.items())))
    return (f"the boat held {held:.1f} m/s, near or past where the ROM's 0.05 s step in {substeps} ode3 step(s) "
            f"turns numerically unstable (a steady cruise diverges from about {measured}); {option} {more} "
            f"integrates it in {more}")


class Simulator:
    """Integrates a :class:`BB2Model` from x0 with ode3 at h (in ``substeps`` ode3 steps of h/substeps each; 1, the
    default, is the reference's), commands held per step."""

    def __init__(self, model: BB2Model, x0: np.ndarray, t0: float = 0.0, h: float | None = None,
                 substeps: int = 1):
        self.model = model
        self.h = float(h if h is not None else model.params.h)
        self.substeps = check_substeps(substeps)
        self.t0 = float(t0)
        self.n = 0
        self.x = np.asarray(x0, dtype=float).copy()
        if self.x.shape != (12,) or not np.all(np.isfinite(self.x)):
            raise ValueError("initial state must be 12 finite numbers [x y z phi theta psi u v w p q r]")
        self.actuators = Actuators(model.params, self.h)
        self.dmem = DerivativeMemory()

    @property
    def t(self) -> float:
        return self.t0 + self.n * self.h

    @property
    def t_next(self) -> float:
        """The time the next :meth:`step` reaches (exactly the value of :attr:`t` after it)."""
        return self.t0 + (self.n + 1) * self.h

    def step(self, planes_cmd_deg, rps_cmd: float, dmass_cmd_kg: float = 0.0) -> StepRecord:
        """Advance one major step with the given commands; returns the record of t_n.

        Raises :class:`NonFiniteStateError` (and leaves the simulator at t_n) when a stage or the new state is
        not finite: the model has diverged.
        """
        h, t, x = self.h, self.t, self.x
        planes_cmd = np.asarray(planes_cmd_deg, dtype=float)
        if planes_cmd.shape != (5,) or not np.all(np.isfinite(planes_cmd)) or not np.isfinite(rps_cmd) \
                or not np.isfinite(dmass_cmd_kg):
            raise ValueError(f"commands must be 5 finite plane angles and finite rps/ballast, got "
                             f"{planes_cmd.tolist()}, {rps_cmd}, {dmass_cmd_kg}")
        act = self.actuators.step(planes_cmd, rps_cmd, dmass_cmd_kg)
        hs = h / self.substeps  # (h itself, exactly, for the authors' single step)
        ev1, x_new = self._ode3(t, x, hs, act)
        for j in range(1, self.substeps):
            x_new = self._ode3(t + j * hs, x_new, hs, act)[1]
        rec = StepRecord(t, x.copy(), planes_cmd, float(rps_cmd), act, ev1)
        self.x = x_new
        self.n += 1
        return rec

    def _ode3(self, t: float, x: np.ndarray, h: float, act: ActuatorOutputs) -> tuple[Evaluation, np.ndarray]:
        """One ode3 step of ``h`` from (t, x), the Derivative blocks' sample stored at t: (its first evaluation,
        the new state).  Raises :class:`NonFiniteStateError` when a stage or the new state is not finite."""
        f = self.model.evaluate
        with np.errstate(all="ignore"):
            try:
                ev1 = f(t, x, act, self.dmem)
                self.dmem.store(t, ev1.urel_sections)
                k1 = ev1.xdot
                x2 = x + (h * 0.5) * k1
                self._check(t + h * 0.5, x2)
                k2 = f(t + h * 0.5, x2, act, self.dmem).xdot
                x3 = x + (h * 0.75) * k2
                self._check(t + h * 0.75, x3)
                k3 = f(t + h * 0.75, x3, act, self.dmem).xdot
            except (ValueError, OverflowError, ZeroDivisionError) as e:
                raise NonFiniteStateError(t, x, f"model evaluation ({e})") from e
            x_new = x + h * (2.0 / 9.0 * k1 + 1.0 / 3.0 * k2 + 4.0 / 9.0 * k3)
        self._check(t + h, x_new)
        return ev1, x_new

    @staticmethod
    def _check(t: float, x: np.ndarray) -> None:
        if not np.all(np.isfinite(x)):
            raise NonFiniteStateError(t, x)
