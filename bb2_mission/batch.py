"""Missions flown together: one :class:`~bb2_mission.runner.MissionRunner` per mission, their ROMs one batch.

:func:`run_missions_batch` gives every mission the :class:`~bb2_mission.runner.MissionResult` that
:func:`~bb2_mission.runner.run_mission` gives it alone, bit for bit (trajectory and summary; the wall time is the
mission's share of the batch's).  Each tick, every running mission does its own half before the ROM step
(:meth:`MissionRunner.begin_tick`: state, clearances, its stack, its limits; the clearances of all boats and
their path-following laws computed together beforehand, :func:`_clearances` and
:func:`bb2_control.stacks.prepare_stacks`), then the ROMs of all of them take one
step of the exact batch ROM (:class:`bb2_sim.batch.BatchSimulator`, ``exact=True``: bit for bit the single
simulator), then each does its half after it (:meth:`MissionRunner.finish_tick`).  A mission that has ended is
retired from the batch; the others go on.

What flies together (:func:`batch_refusal` says why not): one hull, physics profile and ``substeps`` for the batch, and
the stack flying on the truth (``navigation: truth``). Each mission keeps its own sea (the authors' regular wave or
a spectrum's components) and current: the batch ROM takes them per boat.  A mission whose ROM diverges in the
batch ends in the same tick as alone, but its message says what the batch saw (a non-finite stage or state)
where the single run may name the exception: fly it alone for that message (``bb2-campaign`` does).
"""
from __future__ import annotations

import time
from typing import Any, Callable, Sequence

import numpy as np

from bb2_mission.records import MISSION_COLUMNS
from bb2_mission.runner import MissionResult, MissionRunner, MissionStep
from bb2_mission.schema import Mission
from bb2_mission.summary import EndReason, MissionEvent, summarize

__all__ = ["batch_refusal", "run_missions_batch"]


def batch_refusal(m: Mission) -> str | None:
    """Why mission ``m`` cannot fly in a batch (None: it can)."""
    if getattr(m, "navigation", "truth") != "truth":
        return f"it flies on its navigation estimate (navigation: {m.navigation})"
    return None


class _BoatView:
    """The single simulator's face of boat ``i`` of a batch, for its runner: t, x, n, h, model."""

    def __init__(self, batch: Any, i: int, model: Any) -> None:
        self._batch, self._i = batch, i
        self.model = model
        self.h = batch.h
        self.n = 0

    @property
    def t(self) -> float:
        return self._batch.t0 + self.n * self.h

    @property
    def x(self) -> np.ndarray:
        return self._batch.x[self._i]


class _ActuatorView:
    """A boat's applied actuator values of a batch step (what the mission row takes)."""

    __slots__ = ("planes_deg", "rps")

    def __init__(self, planes_deg: np.ndarray, rps: float) -> None:
        self.planes_deg, self.rps = planes_deg, rps


class _RecordView:
    __slots__ = ("act",)

    def __init__(self, act: _ActuatorView) -> None:
        self.act = act


PROGRESS_EVERY_TICKS = 50
"""How often (batch ticks) :func:`run_missions_batch` tells its ``on_progress``."""


def run_missions_batch(missions: Sequence[Mission], model: Any = None, *,
                       on_progress: Callable[[float], None] | None = None) -> list[MissionResult]:
    """Fly ``missions`` together (see the module docstring); one result per mission, in order.

    ``model``: the ROM (:class:`bb2_sim.model.BB2Model`, calm) of their hull and profile; default built from the
    first mission's.  ``on_progress(done)``, every :data:`PROGRESS_EVERY_TICKS` ticks and at the end: how many
    missions' worth of ticks are flown (each mission's ticks over its most, an ended one 1; ``len(missions)`` at
    the end) -- a campaign's progress bar between the batch's start and its rows.  Raises ValueError if a mission
    cannot fly in a batch (:func:`batch_refusal`) or the missions differ in hull or profile."""
    from bb2_control.stacks import prepare_stacks
    from bb2_sim.batch import BatchModel, BatchSimulator
    from bb2_sim.batch.environment import boat_environments
    from bb2_sim.model import BB2Model
    from bb2_sim.profiles import get_profile
    from bb2_sim.state import VehicleState

    M = list(missions)
    if not M:
        raise ValueError("batch: no missions")
    for m in M:
        why = batch_refusal(m)
        if why:
            raise ValueError(f"batch: mission {m.name!r} cannot fly in a batch: {why}")
    if len({str(m.hull) for m in M}) > 1 or len({get_profile(m.profile) for m in M}) > 1 \
            or len({m.substeps for m in M}) > 1:
        raise ValueError("batch: the missions of a batch share one hull, one physics profile and one substeps")
    t0 = time.perf_counter()
    if model is None:
        model = BB2Model(M[0].hull, profile=M[0].profile)
    elif model.profile != get_profile(M[0].profile) or model.sea is not None or not model.wave.calm:
        raise ValueError("batch: the model must be the missions' hull and profile in calm water")
    runners = [MissionRunner(m, model) for m in M]
    bm = BatchModel(model, exact=True, **boat_environments([m.environment for m in M], model.params))
    sim = BatchSimulator(bm, np.array([r.sim.x for r in runners]), h=runners[0].sim.h,
                         substeps=runners[0].sim.substeps)
    views = [_BoatView(sim, i, model) for i in range(len(M))]
    for r, v in zip(runners, views):
        r.sim = v
    rows = [_Rows(r.n_steps + 2) for r in runners]     # a row per tick: at most n_steps ticks and an ending one
    terrains = _shared_terrains(runners)
    planes = np.zeros((len(M), 5))
    rps = np.zeros(len(M))
    running = list(range(len(M)))
    loops = 0
    while running:
        if on_progress is not None and loops % PROGRESS_EVERY_TICKS == 0:
            on_progress(sum(1.0 if r.done else min(1.0, v.n / max(1, r.n_steps)) for r, v in zip(runners, views)))
        loops += 1
        ticks: dict[int, Any] = {}
        clear = _clearances(runners, running, terrains)
        states = [VehicleState.from_vector(runners[i].sim.t, runners[i].sim.x) for i in running]
        prepare_stacks([runners[i].stack for i in running], states)
        for i, state in zip(running, states):
            tick = runners[i].begin_tick(clear.get(i), state)
            if isinstance(tick, MissionStep):
                rows[i].keep(tick)
            elif tick.event is not None:
                rows[i].keep(runners[i].finish_tick(tick, None))
            else:
                ticks[i] = tick
                planes[i], rps[i] = tick.planes_deg, tick.rps
        ended = [i for i in running if i not in ticks]
        if ended:
            sim.retire(ended)
        if ticks:
            rec = sim.step(planes, rps)
            where = {int(b): j for j, b in enumerate(rec.boats)}
            diverged = set(rec.newly_diverged.tolist())
            for i, tick in ticks.items():
                if i in diverged:
                    e = sim.errors[i]
                    tick.event = MissionEvent(EndReason.DIVERGED, tick.state.t, tick.x[0:3].copy(), str(e))
                    rows[i].keep(runners[i].finish_tick(tick, None))
                    continue
                j = where[i]
                views[i].n += 1
                act = _ActuatorView(rec.act.planes_deg[j], float(rec.act.rps[j]))
                rows[i].keep(runners[i].finish_tick(tick, _RecordView(act)))
        done = [i for i in ticks if runners[i].done]
        if done:
            sim.retire(done)
        running = [i for i in running if not runners[i].done]
    if on_progress is not None:
        on_progress(float(len(M)))
    wall = (time.perf_counter() - t0) / len(M)
    out = []
    for r, rr in zip(runners, rows):
        traj = rr.columns()
        m = r.mission
        path_native = m.path.to_frame("native") if m.path.frame != "native" else m.path
        out.append(MissionResult(m, traj, summarize(r, traj, path_native, wall), path_native))
    return out


def _shared_terrains(runners: list[MissionRunner]) -> list[Any]:
    """Per runner, the terrain its clearances are interpolated on: one object for all runners whose terrains
    are equal grids (so that one call serves them), None without terrain."""
    out: list[Any] = []
    distinct: list[Any] = []
    for r in runners:
        t = r.terrain
        if t is not None:
            t = next((d for d in distinct if d.x.shape == t.x.shape and d.y.shape == t.y.shape and
                      d.z.shape == t.z.shape and np.array_equal(d.x, t.x) and np.array_equal(d.y, t.y) and
                      np.array_equal(d.z, t.z, equal_nan=True)), t)
            if t is r.terrain and all(d is not t for d in distinct):
                distinct.append(t)
        out.append(t)
    return out


def _clearances(runners: list[MissionRunner], running: list[int], terrains: list[Any]) -> dict[int, Any]:
    """The clearances of the running runners' states, as each runner's own call gives them (bit for bit), for all
    runners of a shared terrain and hull probes at once (``probe_points`` and ``clearances_at`` on the stacked
    states, the terrain interpolated once for all points)."""
    from bb2_mission.components import terrain_elevation

    out: dict[int, Any] = {}
    groups: dict[tuple[int, int], list[int]] = {}
    for i in running:
        if terrains[i] is not None:
            groups.setdefault((id(terrains[i]), id(runners[i].c.probes)), []).append(i)
    for members in groups.values():
        first = runners[members[0]]
        pts = first.probe_points(np.array([runners[i].sim.x for i in members]))
        zt = terrain_elevation(terrains[members[0]], pts[..., 0].ravel(), pts[..., 1].ravel()).reshape(pts.shape[:2])
        z0, c0, hull = first.clearances_at(pts, zt)
        for i, a, b, c in zip(members, z0.tolist(), c0.tolist(), hull.tolist()):
            out[i] = (a, b, c)
    return out


class _Rows:
    """A mission's CSV rows as they come, in one float array (what :func:`rows_to_columns` makes of them)."""

    def __init__(self, capacity: int) -> None:
        self._a = np.empty((capacity, len(MISSION_COLUMNS)))
        self._n = 0

    def keep(self, step: MissionStep) -> None:
        if step.row is not None:
            self._a[self._n] = step.row.values()
            self._n += 1

    def columns(self) -> dict[str, np.ndarray]:
        arr = self._a[:self._n]
        return {c: arr[:, k] for k, c in enumerate(MISSION_COLUMNS)}
