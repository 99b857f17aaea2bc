"""ode3 for N boats with the Simulink semantics of :class:`bb2_sim.integrator.Simulator`, one major step for all.

Per boat and step, exactly as the single simulator: the commands go through the boat's rate limiters (direct
feed-through) and are held over the step; the major evaluation at (t_n, x_n) uses the Derivative memory of the
previous major sample, then stores (t_n, u_n); k2, k3 at t_n + h/2 and t_n + 3h/4; x_{n+1} = x_n + h (2/9 k1 +
1/3 k2 + 4/9 k3).

A boat whose stage or new state is not finite diverges: it is marked (:attr:`BatchSimulator.diverged`, the reason
in :attr:`BatchSimulator.errors` as the :class:`bb2_sim.integrator.NonFiniteStateError` its single run raises),
frozen at its last state (t_n, as the single simulator stays), and no longer evaluated; the other boats go on
unchanged (a step with every boat diverged raises RuntimeError).  A boat whose run has ended is retired
(:meth:`BatchSimulator.retire`): frozen the same way, without an error.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..integrator import NonFiniteStateError, check_substeps
from .actuators import BatchActuatorOutputs, BatchActuators
from .model import BatchEvaluation, BatchModel


@dataclass
class BatchStepRecord:
    """A major step: the states at t_n (N, 12; diverged boats frozen), the commands, and for the boats stepped
    (``boats``, indices) the applied actuator values and the loads of the major evaluation (rows in that order)."""

    t: float
    x: np.ndarray
    commands_planes_deg: np.ndarray
    command_rps: np.ndarray
    boats: np.ndarray
    act: BatchActuatorOutputs
    ev: BatchEvaluation
    newly_diverged: np.ndarray


class BatchSimulator:
    """Integrates a :class:`BatchModel` from x0 (N, 12) with ode3 at h (in ``substeps`` ode3 steps of h/substeps,
    as :class:`bb2_sim.integrator.Simulator`), commands held per step."""

    def __init__(self, model: BatchModel, x0: np.ndarray, t0: float = 0.0, h: float | None = None,
                 substeps: int = 1):
        self.model = model
        self.n_boats = model.n_boats
        self.h = float(h if h is not None else model.params.h)
        self.substeps = check_substeps(substeps)
        self.t0 = float(t0)
        self.n = 0
        self.x = np.array(x0, dtype=float)
        if self.x.shape != (self.n_boats, 12):
            raise ValueError(f"batch: initial states must be ({self.n_boats}, 12) "
                             f"[x y z phi theta psi u v w p q r] per boat, got {self.x.shape}")
        bad = np.flatnonzero(~np.isfinite(self.x).all(axis=1))
        if len(bad):
            raise ValueError(f"batch: initial states must be finite (boats {bad.tolist()} are not)")
        self.actuators = BatchActuators(model.params, self.n_boats, self.h)
        self.dmem = model.new_memory()
        self.diverged = np.zeros(self.n_boats, dtype=bool)
        self.retired = np.zeros(self.n_boats, dtype=bool)
        self.errors: dict[int, NonFiniteStateError] = {}
        self._rotations = None     # hinge rotations of the last step's deflections (reused per unchanged boat)

    @property
    def t(self) -> float:
        return self.t0 + self.n * self.h

    @property
    def t_next(self) -> float:
        return self.t0 + (self.n + 1) * self.h

    @property
    def active(self) -> np.ndarray:
        """Indices of the boats still integrating (neither diverged nor retired)."""
        return np.flatnonzero(~(self.diverged | self.retired))

    def retire(self, boats) -> None:
        """Stop integrating ``boats`` (indices): their runs have ended; they stay frozen at their last state and
        their commands are ignored from the next step on.  The others go on unchanged."""
        self.retired[np.asarray(boats, dtype=int)] = True

    def _commands(self, planes_cmd_deg, rps_cmd, dmass_cmd_kg) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        N = self.n_boats
        planes = np.asarray(planes_cmd_deg, dtype=float)
        if planes.shape != (N, 5):
            raise ValueError(f"batch: plane commands must be ({N}, 5) deg, got {planes.shape}")
        out = [planes]
        for name, a in (("rps", rps_cmd), ("ballast", dmass_cmd_kg)):
            a = np.asarray(a, dtype=float)
            if a.shape not in ((), (N,)):
                raise ValueError(f"batch: {name} commands must be a scalar or ({N},), got {a.shape}")
            out.append(np.broadcast_to(a, (N,)))
        live = ~(self.diverged | self.retired)
        bad = live & ~(np.isfinite(planes).all(axis=1) & np.isfinite(out[1]) & np.isfinite(out[2]))
        if bad.any():
            raise ValueError(f"batch: commands must be finite plane angles and rps/ballast (boats "
                             f"{np.flatnonzero(bad).tolist()} are not)")
        return out[0], out[1], out[2]

    def step(self, planes_cmd_deg, rps_cmd, dmass_cmd_kg=0.0) -> BatchStepRecord:
        """Advance every live boat one major step: plane commands (N, 5) deg, rps (N,) or scalar, ballast (N,)
        or scalar kg (commands of diverged or retired boats are ignored). Returns the record of t_n."""
        planes, rps, dmass = self._commands(planes_cmd_deg, rps_cmd, dmass_cmd_kg)
        h, t = self.h, self.t
        boats = None if not (self.diverged.any() or self.retired.any()) else self.active
        if boats is not None and len(boats) == 0:
            raise RuntimeError(f"batch: every boat has diverged or retired (at t = {t:.2f} s); nothing to step")
        x = self.x if boats is None else self.x[boats]
        if boats is None:
            act = self.actuators.step(planes, rps, dmass)
        else:
            act = self.actuators.step(planes[boats], rps[boats], dmass[boats], boats)
        prev = self._rotations if boats is None else None
        with np.errstate(all="ignore"):
            act.rotations = self._rotations = self.model.pressure.prepare(act.planes_deg, prev)
        f = self.model.evaluate
        rows = np.arange(len(x)) if boats is None else boats
        hs = h / self.substeps  # (h itself, exactly, for the authors' single step)
        failed: dict[int, NonFiniteStateError] = {}  # row -> the error of its first non-finite stage
        for sub in range(self.substeps):  # (a boat gone non-finite in a sub-step is carried to the end as NaN)
            ts = t + sub * hs
            with np.errstate(all="ignore"):
                ev = f(ts, x, act, self.dmem, boats)
                self.dmem.store(ts, ev.added_mass_inputs, boats)
                k1 = ev.xdot
                x2 = x + (hs * 0.5) * k1
                k2 = f(ts + hs * 0.5, x2, act, self.dmem, boats).xdot
                x3 = x + (hs * 0.75) * k2
                k3 = f(ts + hs * 0.75, x3, act, self.dmem, boats).xdot
                x_new = x + hs * (2.0 / 9.0 * k1 + 1.0 / 3.0 * k2 + 4.0 / 9.0 * k3)
            if sub == 0:
                ev1 = ev  # the major evaluation (the record's loads)
            ok = np.isfinite(x_new).all(axis=1)
            if not ok.all():
                ok2, ok3 = np.isfinite(x2).all(axis=1), np.isfinite(x3).all(axis=1)
                for j in np.flatnonzero(~ok):
                    if j not in failed:
                        tb, xb = (ts + hs * 0.5, x2[j]) if not ok2[j] else (ts + hs * 0.75, x3[j]) \
                            if not ok3[j] else (ts + hs, x_new[j])
                        failed[int(j)] = NonFiniteStateError(tb, xb.copy())
            x = x_new
        newly = np.empty(0, dtype=int)
        if not ok.all():
            for j, err in failed.items():
                self.errors[int(rows[j])] = err
            newly = rows[~ok]
            self.diverged[newly] = True
        rec = BatchStepRecord(t, self.x.copy(), planes, rps, rows, act, ev1, newly)
        if boats is None and ok.all():
            self.x = x_new
        else:
            self.x[rows[ok]] = x_new[ok]
        self.n += 1
        return rec
