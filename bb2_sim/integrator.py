"""Fixed-step ode3 (Bogacki-Shampine) with the Simulink block semantics of the reference (SPEC 11).

One major step n -> n+1 (t_n = n h):

1. output at (t_n, x_n): the commands go through the discrete rate limiters (direct feed-through) and the
   model is evaluated with the Derivative blocks against the previous major sample -> k1, loads, outputs;
2. update: the limiters keep y_n, the Derivative blocks store (t_n, u_n);
3. k2 = f(t_n + h/2, x_n + h/2 k1), k3 = f(t_n + 3h/4, x_n + 3h/4 k2) with held actuator outputs,
   x_{n+1} = x_n + h (2/9 k1 + 1/3 k2 + 4/9 k3).

``substeps`` k > 1 (not the reference's: an option for speeds where the authors' step is numerically unstable, a
steady cruise from about 11.6 m/s at h = 0.05 s: :mod:`bb2_sim.step_stability`) integrates the major step as k
such ode3 steps of h/k, each a major step of the model's Derivative blocks (1 and 3 above at t_n + j h/k), with the
actuators' outputs of step 1 held: the commands, the actuators and every output stay at the rate 1/h.  k = 1 is the
reference's step, bit for bit.
"""
from __future__ import annotations

from dataclasses import dataclass

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
