"""Standard maneuvers for a batch of boats: the twin of :class:`bb2_sim.maneuvers.ManeuverCommander` (the v12
autopilot, zig-zags, constant rudder, imposed planes, constant rps or the speed PI) with one set of settings per
boat, and the batch model and simulator of a list of maneuvers.

The boats share the hull and the physics profile; each keeps its own depth, speed, references, channel logic,
sea (the authors' table, or its ``environment``'s spectrum sea) and current.
"""
from __future__ import annotations

import math
from typing import Callable, Sequence

import numpy as np

from ..maneuvers import RAD2DEG, ManeuverSettings
from ..model import BB2Model
from ..profiles import get_profile
from ..xplane import mixing_matrix
from .autopilot import BatchSpeedPI, BatchV12Autopilot
from .environment import boat_environments
from .model import BatchModel
from .simulator import BatchSimulator


class BatchZigZag:
    """Zig-zag commands +-A per boat, switched at the first major step where the monitored angle reaches +-C."""

    def __init__(self, amplitude_deg, check_deg):
        self.A = np.array(amplitude_deg, dtype=float)
        self.C = np.array(check_deg, dtype=float)
        self.sign = np.ones_like(self.A)
        self.reversals: list[list[float]] = [[] for _ in range(len(self.A))]

    def step(self, t: float, angle_deg: np.ndarray, boats: np.ndarray) -> np.ndarray:
        """Commands (deg) of the given boats (indices) from their monitored angles (deg, rows of those boats)."""
        s = self.sign[boats]
        up = (s > 0) & (angle_deg >= self.C[boats])
        down = (s < 0) & (angle_deg <= -self.C[boats])
        for j in np.flatnonzero(up | down):
            self.reversals[int(boats[j])].append(t)
        s = np.where(up, -1.0, np.where(down, 1.0, s))
        self.sign[boats] = s
        return s * self.A[boats]


class BatchManeuverCommander:
    """Per major step: states (N, 12) -> plane commands (N, 5) deg (authors' plane signs) and rps commands (N,)."""

    def __init__(self, settings: Sequence[ManeuverSettings]):
        self.settings = list(settings)
        S = self.settings
        if not S:
            raise ValueError("batch: no maneuvers")
        self.n_boats = len(S)
        arr = np.array
        self.autopilot = BatchV12Autopilot([s.z_ref for s in S], [np.radians(s.heading_ref_deg) for s in S])
        self.zigzag = BatchZigZag([s.amplitude_deg for s in S], [s.check_deg for s in S])
        self._vz = np.flatnonzero([s.vertical == "zigzag" for s in S])
        self._hz = np.flatnonzero([s.horizontal == "zigzag" for s in S])
        self._rudder = np.flatnonzero([s.horizontal == "rudder" for s in S])
        self._rudder_dh = arr([-s.rudder_deg for s in S])[self._rudder]
        self._imposed = arr([s.imposed for s in S])
        self._imposed_planes = arr([s.planes_deg for s in S], dtype=float)
        self._sail_pid = arr([s.sail_planes == "pid" for s in S])[self._vz]
        self._rps_const = arr([s.rps_command for s in S], dtype=float)
        self._pi = np.flatnonzero([s.propeller == "speed-pi" for s in S])
        self.speed_pi = None
        if len(self._pi):
            profiles = {get_profile(S[i].profile).speed_pi_feedforward for i in self._pi}
            if len(profiles) > 1:
                raise ValueError("batch: the speed PI boats need one physics profile")
            self.speed_pi = BatchSpeedPI([-S[i].speed_mps for i in self._pi], profiles.pop())
        self._M = mixing_matrix()

    def step(self, t: float, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Commands for the states x (N, 12) at time t (every boat ticks, as N single commanders would)."""
        rps = self._rps_const.copy()
        if self.speed_pi is not None:
            rps[self._pi] = self.speed_pi.step(x[self._pi, 6])
        dv_pid, dh_pd = self.autopilot.step(x[:, 2], x[:, 4], x[:, 5])
        dv, dh = dv_pid.copy(), dh_pd.copy()
        if len(self._vz):
            dv[self._vz] = self.zigzag.step(t, x[self._vz, 4] * RAD2DEG, self._vz)
        if len(self._hz):
            dh[self._hz] = self.zigzag.step(t, x[self._hz, 5] * RAD2DEG, self._hz)
        dh[self._rudder] = self._rudder_dh
        planes = dv[:, None] * self._M[:, 0] + dh[:, None] * self._M[:, 1]
        if len(self._vz):
            planes[self._vz, 4] = np.where(self._sail_pid, dv_pid[self._vz], 0.0)
        planes[self._imposed] = self._imposed_planes[self._imposed]
        return planes, rps


def batch_for_maneuvers(settings: Sequence[ManeuverSettings], model: BB2Model | None = None,
                        hull_mesh: str | None = None, exact: bool = False
                        ) -> tuple[BatchSimulator, BatchManeuverCommander]:
    """The batch simulator (boats at their maneuvers' initial states, in their sea states) and the commander of a
    list of maneuvers sharing one physics profile; ``model`` (that profile) gives the hull; ``exact``: see
    :class:`bb2_sim.batch.BatchModel`."""
    S = list(settings)
    if not S:
        raise ValueError("batch: no maneuvers")
    if len({get_profile(s.profile) for s in S}) > 1:
        raise ValueError("batch: the boats of a batch share one physics profile")
    if len({s.substeps for s in S}) > 1:
        raise ValueError("batch: the boats of a batch share one substeps")
    if model is None:
        model = BB2Model(hull_mesh, profile=S[0].profile)
    elif model.profile != get_profile(S[0].profile):
        raise ValueError(f"batch: the model's profile {model.profile.name!r} is not the maneuvers' "
                         f"{S[0].profile!r}")
    if model.sea is not None or model.current is not None:
        raise ValueError("batch: the model must be calm (each maneuver brings its own sea and current)")
    bm = BatchModel(model, exact=exact, **boat_environments([s.environment for s in S], model.params,
                                                              [s.sea_state for s in S]))
    return (BatchSimulator(bm, np.array([s.initial_state() for s in S]), substeps=S[0].substeps),
            BatchManeuverCommander(S))


def _log_rows(rec, rows: np.ndarray, params, seas: list) -> np.ndarray:
    """The trajectory rows (``OUTPUT_COLUMNS``) of the boats ``rows`` (indices into ``rec.boats``) of a batch step
    record: :func:`bb2_sim.maneuvers.record_row` on arrays, the same operations in the same order (so bit for bit
    the single run's rows); the sea's elevation per boat by the scalar function."""
    from ..maneuvers import OUTPUT_COLUMNS

    boats = rec.boats[rows]
    x = rec.x[boats]
    prop = rec.ev.prop
    n = rec.act.rps[rows]
    KT = prop.KT[rows]
    td = prop.t[rows]
    thrust_ow = KT * params.rho * n * n * params.prop_D ** 4
    out = np.empty((len(rows), len(OUTPUT_COLUMNS)))
    out[:, 0] = rec.t
    out[:, 1:4] = x[:, 0:3]
    out[:, 4:7] = x[:, 3:6] * RAD2DEG
    out[:, 7:10] = x[:, 6:9]
    out[:, 10:13] = x[:, 9:12] * RAD2DEG
    # numpy scalars as record_row's: a scalar's ** 2 is libm's pow, within an ulp of an array's exact square
    out[:, 13] = [math.sqrt(u ** 2 + v ** 2 + w ** 2) for u, v, w in x[:, 6:9]]
    out[:, 14:19] = rec.act.planes_deg[rows]
    out[:, 19:24] = rec.commands_planes_deg[boats]
    out[:, 24] = n
    out[:, 25] = prop.J[rows]
    out[:, 26] = KT
    out[:, 27] = prop.KQ[rows]
    out[:, 28] = thrust_ow
    out[:, 29] = td
    out[:, 30] = (1.0 - td) * thrust_ow
    out[:, 31] = prop.torque[rows]
    out[:, 32] = rec.act.dmass_kg[rows]
    out[:, 33] = [0.0 if seas[b] is None else float(seas[b].elevation(x[j, 0], x[j, 1], rec.t))
                  for j, b in enumerate(boats)]
    return out


PROGRESS_EVERY_STEPS = 100
"""How often (steps) :func:`run_maneuvers_batch` tells its ``on_progress``."""


def run_maneuvers_batch(settings: Sequence[ManeuverSettings], model: BB2Model | None = None, *,
                        hull_mesh: str | None = None, log_every: int = 2, exact: bool = True,
                        on_progress: Callable[[float], None] | None = None) -> list:
    """Fly the maneuvers ``settings`` together, one boat each: the batch twin of
    :func:`bb2_sim.maneuvers.run_maneuver`, returning one :class:`~bb2_sim.maneuvers.ManeuverResult` per boat
    (its trajectory, reversals and divergence as that function gives them; ``exact``: bit for bit, see
    :class:`BatchModel`).  Boats may have different durations (each is logged to its own end; the batch steps to
    the longest).  A boat that diverges stops in the same step as alone, but its error says what the batch saw (a
    non-finite stage or state), where the single run may name the exception that made it (float division by
    zero).  The wall time of each result is its share of the batch's.  Same restrictions as
    :func:`batch_for_maneuvers` (one physics profile and substeps).
    ``on_progress(done)``, every :data:`PROGRESS_EVERY_STEPS` steps and at the end: how many maneuvers' worth of
    steps are flown (each boat's steps over its own, a diverged one 1; ``len(settings)`` at the end)."""
    import time

    from ..maneuvers import OUTPUT_COLUMNS, ManeuverResult
    from ..sea.sea import AuthorsTableSea

    S = list(settings)
    t0 = time.perf_counter()
    sim, cmd = batch_for_maneuvers(S, model, hull_mesh, exact=exact)
    params = sim.model.params
    envs = sim.model.environment
    seas = [sea if sea is not None else None if w.calm else AuthorsTableSea(w, params.g)
            for w, sea in zip(envs.waves, envs.seas)]
    n_steps = np.array([int(round(s.duration / sim.h)) for s in S])
    n_rows = n_steps // log_every + 1
    traj = [np.empty((int(r), len(OUTPUT_COLUMNS))) for r in n_rows]
    logged = np.zeros(len(S), dtype=int)
    last_t = np.full(len(S), np.nan)                 # the time of each boat's last commanded step
    errors: dict = {}
    for k in range(int(n_steps.max()) + 1):
        if on_progress is not None and k % PROGRESS_EVERY_STEPS == 0:
            on_progress(float(np.sum(np.where(sim.diverged, 1.0, np.minimum(k, n_steps) / np.maximum(n_steps, 1)))))
        planes, rps = cmd.step(sim.t, sim.x)
        live = (k <= n_steps) & ~sim.diverged
        last_t[live] = sim.t
        if not live.any():
            break
        rec = sim.step(planes, rps)
        for b in rec.newly_diverged:                 # (a boat past its own end may diverge: not its run's error)
            if live[b]:
                errors[int(b)] = sim.errors[int(b)]
        if k % log_every:
            continue
        ok = live[rec.boats] & ~np.isin(rec.boats, rec.newly_diverged)
        rows = np.flatnonzero(ok)
        if len(rows):
            block = _log_rows(rec, rows, params, seas)
            for j, b in enumerate(rec.boats[rows]):
                traj[b][logged[b]] = block[j]
                logged[b] += 1
    if on_progress is not None:
        on_progress(float(len(S)))
    wall = (time.perf_counter() - t0) / len(S)
    out = []
    for b, s in enumerate(S):
        arr = traj[b][:logged[b]]
        reversals = [t for t in cmd.zigzag.reversals[b] if t <= last_t[b]] \
            if s.zigzag else []
        out.append(ManeuverResult(s, {c: arr[:, i] for i, c in enumerate(OUTPUT_COLUMNS)}, errors.get(b),
                                  reversals, wall))
    return out
