"""One campaign run, as a worker flies it: no ROS, only the library runner (or the maneuver runner).

:func:`run_task` is what the local process pool and the Ray tasks call; it never raises: a run that raises
is a row with status ``error`` and the exception as its message.  :func:`probe` checks a SPEC against the
mission (or maneuver) before a campaign starts, so a bad key fails at once with the key named.
"""
from __future__ import annotations

import functools
import math
import time
from pathlib import Path
from typing import Any, Callable, Sequence

from bb2_tools.campaign.errors import SpecError
from bb2_tools.campaign.figures import END_STATUS, maneuver_values, mission_values, unreached_values
from bb2_tools.campaign.spec import CampaignSpec, column_value

__all__ = ["STATUSES", "run_task", "run_tasks", "run_one", "probe", "build_mission", "maneuver_settings_of",
           "BATCH_MIN", "batched", "campaign_warnings"]

STATUSES = ("ok", "grounded", "broached", "diverged", "error")
_MAX_MESSAGE = 2000


def _one_line(text: str) -> str:
    s = " ".join(str(text).split())
    return s if len(s) <= _MAX_MESSAGE else s[: _MAX_MESSAGE - 3] + "..."


def build_mission(spec: CampaignSpec, doc: dict[str, Any]) -> Any:
    from bb2_mission.schema import mission_from_dict

    base_dir = Path(spec.base_dir) if spec.base_dir else None
    return mission_from_dict(doc, base_dir=base_dir, name=str(doc.get("name", spec.name)))


def maneuver_settings_of(spec: CampaignSpec, doc: dict[str, Any]) -> Any:
    from bb2_sim.maneuvers import maneuver_settings

    return maneuver_settings(str(spec.maneuver), **doc)


# ------------------------------------------------------------------------------------------ one run
def run_one(spec: CampaignSpec, index: int, *, on_row: Callable[[Any], None] | None = None
            ) -> tuple[dict[str, Any], Any]:
    """Fly run ``index``; returns (its results-table row, the mission/maneuver result or None).

    ``on_row`` gets every trajectory row as it is made (for ``--only INDEX --out-run DIR``).
    """
    t0 = time.perf_counter()
    row = _row_inputs(spec, index)
    figures: dict[str, Any] = {n: None for n in spec.collect}
    status, message, result = "error", "", None
    try:
        doc = spec.document(index)
        if spec.graph_dir:
            from bb2_tools.campaign.graph import run_graph_once

            status, message, figures = run_graph_once(spec, index, doc, spec.graph_dir)
        elif spec.target == "mission":
            status, message, figures, result = _fly_mission(spec, doc, on_row)
        else:
            status, message, figures, result = _fly_maneuver(spec, doc, on_row)
    except Exception as e:  # noqa: BLE001 -- a run that raises is recorded, the campaign goes on
        status, message = "error", _one_line(f"{type(e).__name__}: {e}")
    return _row_outcome(row, figures, status, message, time.perf_counter() - t0), result


def _row_inputs(spec: CampaignSpec, index: int) -> dict[str, Any]:
    """The first columns of run ``index``'s row: index, seed, every varied input."""
    row: dict[str, Any] = {"index": int(index), "seed": spec.run_seed(index)}
    kinds = {v.key: v.column_kind for v in spec.vary}
    for k, val in spec.inputs(index).items():
        row[k] = column_value(val, kinds[k])
    return row


def _row_outcome(row: dict[str, Any], figures: dict[str, Any], status: str, message: str,
                 wall_s: float) -> dict[str, Any]:
    row.update(figures)
    row["status"] = status
    row["message"] = message
    row["wall_time_s"] = wall_s
    return row


def _fly_mission(spec: CampaignSpec, doc: dict[str, Any], on_row: Callable[[Any], None] | None):
    from bb2_mission.runner import MissionRunner

    res = MissionRunner(build_mission(spec, doc)).run(on_row=on_row)
    return (*_mission_outcome(spec, res), res)


def _mission_outcome(spec: CampaignSpec, res: Any) -> tuple[str, str, dict[str, Any]]:
    """Status, message and collected figures of a flown mission (alone or in a batch)."""
    s = res.summary
    status = END_STATUS.get(str(s.end_reason), "error")
    message = _one_line(str(s.event)) if s.event is not None else ""
    if hint := res.divergence_hint("substeps:"):   # (bb2-sim mission says the same beside its error)
        message = f"{message}; {hint}"
    return status, message, mission_values(s, spec.collect)


def _fly_maneuver(spec: CampaignSpec, doc: dict[str, Any], on_row: Callable[[Any], None] | None):
    from bb2_sim.maneuvers import run_maneuver

    s = maneuver_settings_of(spec, doc)
    res = run_maneuver(s, on_row=on_row)
    return (*_maneuver_outcome(spec, s, res), res)


def _maneuver_outcome(spec: CampaignSpec, s: Any, res: Any) -> tuple[str, str, dict[str, Any]]:
    """Status, message and collected figures of a flown maneuver (alone or in a batch)."""
    from dataclasses import asdict

    from bb2_sim.metrics import figures_for

    status = "ok" if res.error is None else "diverged"
    message = "" if res.error is None else _one_line(str(res.error))
    if hint := res.divergence_hint("substeps:"):   # (bb2-sim maneuver says the same beside its error)
        message = f"{message}; {hint}"
    try:
        fig = figures_for(s.name, res.traj, **asdict(s))
    except Exception as e:  # noqa: BLE001 -- figures of a truncated run may not exist
        fig = None
        if status == "ok":
            status = "error"
        message = _one_line((message + "; " if message else "") + f"figures: {type(e).__name__}: {e}")
    if status == "ok" and fig is not None and (missed := unreached_values(str(spec.maneuver), fig, spec.collect)):
        t_end = float(res.traj["t_s"][-1])   # (the empty cells of an ok row: a run too short for them, said)
        message = f"not reached in this {t_end:g} s run: {', '.join(missed)}"
    return status, message, maneuver_values(str(spec.maneuver), fig, spec.collect)


_CACHES: dict[Any, Any] | None = None


def install_worker_caches() -> None:
    """Per-process memo of the dense Bernstein basis that every run's summary evaluates (the closest-point
    path errors sample the path at 20001 points: a (20001 x n+1) binomial pmf, ~0.3 s of a short run).  The
    cached matrix is the same function's result, read-only, so the figures are unchanged to the last digit."""
    global _CACHES
    if _CACHES is not None:
        return
    _CACHES = {}
    import collections
    import hashlib

    import numpy as np

    from bb2_planner import bernstein

    original = bernstein.basis_matrix
    lru: collections.OrderedDict[Any, Any] = collections.OrderedDict()

    def basis_matrix(n: int, tau: Any) -> Any:
        t = np.atleast_1d(np.asarray(tau, dtype=float))
        if t.size < 2000:
            return original(n, t)
        key = (int(n), t.shape, hashlib.blake2b(t.tobytes(), digest_size=16).digest())
        B = lru.get(key)
        if B is None:
            B = original(n, t)
            B.setflags(write=False)
            lru[key] = B
            while len(lru) > 4:
                lru.popitem(last=False)
        else:
            lru.move_to_end(key)
        return B

    basis_matrix.__doc__ = original.__doc__
    bernstein.basis_matrix = basis_matrix
    _CACHES["basis_matrix"] = original


def run_task(spec: CampaignSpec, index: int) -> dict[str, Any]:
    """The results row of run ``index`` (what the engines call; never raises)."""
    install_worker_caches()
    try:
        return run_one(spec, index)[0]
    except Exception as e:  # noqa: BLE001 -- e.g. a bad index: still one row
        row = {"index": int(index), "seed": spec.run_seed(index), "status": "error",
               "message": _one_line(f"{type(e).__name__}: {e}"), "wall_time_s": math.nan}
        return row


BATCH_MIN = 16
"""Fewest runs flown together: below about 20 boats the batch ROM costs more per boat than single runs."""
BATCH_MEMORY_BYTES = 512e6
"""At most this much of trajectories held by one batch (its boats' logged rows): longer runs fly in smaller
batches, or alone."""


def batched(spec: CampaignSpec) -> bool:
    """Whether the runs of ``spec`` may fly together in a batch (:func:`run_tasks`): maneuvers and missions on the
    library runner (not ``--graph``)."""
    return spec.target in ("maneuver", "mission") and not spec.graph_dir


def _mission_item(spec: CampaignSpec, i: int) -> tuple[Any, Any]:
    """Run ``i``'s mission and its batch group (hull, profile, substeps), or None when it flies alone
    (:func:`bb2_mission.batch.batch_refusal`: navigation on sensors)."""
    from bb2_mission.batch import batch_refusal

    m = build_mission(spec, spec.document(i))
    return m, ((str(m.hull), str(m.profile), m.substeps) if batch_refusal(m) is None else None)


def _maneuver_item(spec: CampaignSpec, i: int) -> tuple[Any, Any]:
    """Run ``i``'s maneuver settings and its batch group (profile, duration, substeps)."""
    s = maneuver_settings_of(spec, spec.document(i))
    return s, (s.profile, s.duration, s.substeps)


BATCH_SAMPLE = 8
"""Runs looked at, spread over the campaign, to tell whether any of them can fly in a batch (:func:`may_batch`)."""


def may_batch(spec: CampaignSpec, sample: int = BATCH_SAMPLE) -> bool:
    """Whether the runs of ``spec`` may fly together (:func:`batched`) and any of ``sample`` runs spread over the
    campaign (the first, the last, evenly between) has a batch group.  A campaign whose runs all fly alone
    (missions on their navigation estimate: :func:`bb2_mission.batch.batch_refusal`) gains nothing from chunks of
    many runs and would hold each finished run in its worker until the whole chunk is done: the engines then send
    its runs one by one (:func:`bb2_tools.campaign.engines.chunk_size`), so each lands, and counts in the progress,
    as it finishes.  Remembered on the spec."""
    if spec._may_batch is None:
        n, item_of = spec.n_runs, (_mission_item if spec.target == "mission" else _maneuver_item)
        found = False
        if batched(spec) and n > 0:
            for i in sorted({round(k * (n - 1) / max(1, sample - 1)) for k in range(min(sample, n))}):
                try:
                    found = item_of(spec, i)[1] is not None
                except Exception:  # noqa: BLE001 -- a run that does not build: its row says why, later
                    continue
                if found:
                    break
        spec._may_batch = found
    return spec._may_batch


def _batches(groups: dict[Any, list[tuple[int, Any]]], run_bytes) -> list[list[tuple[int, Any]]]:
    """The groups cut into batches of at least :data:`BATCH_MIN` runs and at most :data:`BATCH_MEMORY_BYTES` of
    trajectories (``run_bytes(key, group)``: the most one run of the group holds); a group too small for a batch
    is left out (flown alone)."""
    batches = []
    for key, group in groups.items():
        most = int(BATCH_MEMORY_BYTES // run_bytes(key, group))
        size = max(BATCH_MIN, math.ceil(len(group) / max(1, math.ceil(len(group) / max(1, most)))))
        batches += [b for b in (group[k:k + size] for k in range(0, len(group), size)) if len(b) >= BATCH_MIN] \
            if most >= BATCH_MIN else []
    return batches


def run_tasks(spec: CampaignSpec, indices: Sequence[int], on_progress: Callable[[float], None] | None = None
              ) -> list[dict[str, Any]]:
    """The results rows of runs ``indices`` (what the engines call for a chunk of runs; never raises).

    Runs that can fly together, at least :data:`BATCH_MIN` of them, fly as one batch of the batch ROM in its exact
    mode (bit for bit what each gives alone, so the same figures whatever the chunking, the engine or the number
    of workers): maneuvers of one physics profile, duration and ``substeps``, with
    :func:`bb2_sim.batch.maneuvers.run_maneuvers_batch`; missions of one hull, profile and ``substeps`` flying on the
    truth, with :func:`bb2_mission.batch.run_missions_batch` (each mission's stack still steps alone); each run in
    its own sea and current.  A run that diverged in
    the batch is flown again alone (its message is then the single run's), and so is every other run.  Each row's
    wall time is its share of its batch's.  ``on_progress(done)``: how many runs' worth of the chunk are flown so far
    (a batch's boats by their ticks, a run alone when it ends), never decreasing, ``len(indices)`` at most."""
    install_worker_caches()
    if spec.target == "mission":
        from bb2_mission.records import MISSION_COLUMNS

        def fly_missions(ms: list[Any], on_progress: Callable[[float], None] | None) -> list[Any]:
            from bb2_mission.batch import run_missions_batch

            return run_missions_batch(ms, on_progress=on_progress)

        return _fly_together(
            spec, indices, functools.partial(_mission_item, spec), fly_missions,
            # a row per 0.05 s tick of the group's longest mission
            run_bytes=lambda _key, group: (max(m.duration for _, m in group) / 0.05 + 2) * len(MISSION_COLUMNS) * 8,
            diverged=lambda res: str(res.summary.end_reason) == "diverged",
            outcome=lambda _m, res: _mission_outcome(spec, res), wall_s=lambda res: res.summary.wall_time_s,
            on_progress=on_progress)
    from bb2_sim.maneuvers import OUTPUT_COLUMNS

    def fly_maneuvers(settings: list[Any], on_progress: Callable[[float], None] | None) -> list[Any]:
        from bb2_sim.batch.maneuvers import run_maneuvers_batch

        return run_maneuvers_batch(settings, on_progress=on_progress)

    return _fly_together(
        spec, indices, functools.partial(_maneuver_item, spec), fly_maneuvers,
        run_bytes=lambda key, _group: (key[1] / 0.1 + 1) * len(OUTPUT_COLUMNS) * 8,
        diverged=lambda res: res.error is not None,
        outcome=lambda s, res: _maneuver_outcome(spec, s, res), wall_s=lambda res: res.wall_time_s,
        on_progress=on_progress)


def _fly_together(spec: CampaignSpec, indices: Sequence[int], item_of, fly, *, run_bytes, diverged, outcome,
                  wall_s, on_progress: Callable[[float], None] | None = None) -> list[dict[str, Any]]:
    """:func:`run_tasks` on its kind's pieces: ``item_of(index)`` -> (the run's item, its batch group key or None to
    fly it alone), ``fly(items, on_progress)`` -> their results together, ``run_bytes`` (see :func:`_batches`),
    ``diverged(res)`` (then flown again alone), ``outcome(item, res)`` -> (status, message, figures),
    ``wall_s(res)``."""
    told = 0.0

    def tell(done: float) -> None:
        nonlocal told
        if on_progress is not None and done > told:
            told = min(float(len(indices)), done)
            on_progress(told)

    rows: dict[int, dict[str, Any]] = {}
    groups: dict[Any, list[tuple[int, Any]]] = {}
    if batched(spec) and len(indices) >= BATCH_MIN:
        for i in indices:
            try:
                item, key = item_of(i)
            except Exception:  # noqa: BLE001 -- run alone below: its row then says why
                continue
            if key is not None:
                groups.setdefault(key, []).append((int(i), item))
    for batch in _batches(groups, run_bytes):
        before = len(rows)
        try:
            results = fly([item for _, item in batch], lambda done, before=before: tell(before + done))
        except Exception:  # noqa: BLE001 -- the batch refused or failed: every run alone below
            continue
        for (i, item), res in zip(batch, results):
            if diverged(res):
                continue                     # alone below: the single run's own message
            t1 = time.perf_counter()
            try:
                status, message, figures = outcome(item, res)
            except Exception:  # noqa: BLE001
                continue
            rows[i] = _row_outcome(_row_inputs(spec, i), figures, status, message,
                                   wall_s(res) + time.perf_counter() - t1)
    out, alone = [], 0
    for i in indices:
        if int(i) in rows:
            out.append(rows[int(i)])
            continue
        out.append(run_task(spec, i))
        alone += 1
        tell(len(rows) + alone)
    return out


# ------------------------------------------------------------------------------------------ probing
def _check(spec: CampaignSpec, doc: dict[str, Any], what: str, *, build: bool = False) -> None:
    from bb2_mission.schema import MissionError
    from bb2_sim.maneuvers import ManeuverError

    try:
        if spec.target == "mission":
            m = build_mission(spec, doc)
            if build:
                from bb2_mission.runner import MissionRunner

                MissionRunner(m)
        else:
            from bb2_sim.maneuvers import channels, inapplicable_settings

            s = maneuver_settings_of(spec, doc)
            unread = inapplicable_settings(s, doc)
            if unread:  # (as bb2-sim maneuver refuses them: they would be ignored)
                raise SpecError(f"{', '.join(unread)} not read by maneuver {s.name} ({channels(s)})")
    except SpecError as e:
        raise SpecError(f"{what}: {e}") from None
    except (MissionError, ManeuverError, ValueError, TypeError, KeyError, OSError) as e:
        msg = str(e)
        if spec.target == "mission" and msg.startswith("mission: "):
            msg = msg[len("mission: "):]
        raise SpecError(f"{what}: {_one_line(msg)}") from None


def probe(spec: CampaignSpec, max_values: int = 12) -> None:
    """Check the SPEC against the mission (or maneuver) before flying: the base alone, run 0 (built as far as
    the runner; if it fails, the varied key that alone gives the same fault is named), then every value of each
    choice / grid key on run 0 (at most ``max_values`` each).  Raises :class:`SpecError` naming the key."""
    import copy

    from bb2_tools.campaign.spec import set_dotted

    _check(spec, copy.deepcopy(spec.base), "mission" if spec.target == "mission" else "maneuver.options")
    first = spec.inputs(0)
    for v in spec.vary:                       # structure: every key can be set
        try:
            set_dotted(copy.deepcopy(spec.base), v.key, copy.deepcopy(first[v.key]))
        except SpecError as e:
            raise SpecError(f"vary.{v.key}: {e}") from None
    if spec.seed_key:
        try:
            set_dotted(copy.deepcopy(spec.base), spec.seed_key, 0)
        except SpecError as e:
            raise SpecError(f"seed_key: {e}") from None
    try:
        _check(spec, spec.document(0), "vary (run 0)", build=True)
    except SpecError as together:
        why = str(together).split(": ", 1)[-1]
        for v in spec.vary:                   # name the key that alone gives the same fault, if one does
            doc = copy.deepcopy(spec.base)
            set_dotted(doc, v.key, copy.deepcopy(first[v.key]))
            try:
                _check(spec, doc, f"vary.{v.key} = {first[v.key]!r}")
            except SpecError as alone:
                if str(alone).split(": ", 1)[-1] == why:
                    raise alone from None
        raise together from None
    for v in spec.vary:
        if v.kind in ("choice", "grid"):
            for val in v.params[1:max_values]:
                d2 = spec.document(0)
                set_dotted(d2, v.key, copy.deepcopy(val))
                _check(spec, d2, f"vary.{v.key} = {val!r}")


def campaign_warnings(spec: CampaignSpec, max_values: int = 12) -> list[str]:
    """What some runs will fly that is not what was asked, said before the campaign: a maneuver's plane commands
    beyond the planes' limit (``bb2_sim.maneuvers.saturation_warning``: those runs fly at the limit, and a sweep
    past it gives flat figures) and a sea steeper than any deep-water wave
    (``bb2_sim.environment.SeaSpec.steepness_warning``).  One line for the base document, else one per varied key
    at its extreme values (a uniform's bounds, a normal's clip, every choice / grid value, at most ``max_values``)
    on run 0's other inputs.  Warnings, not errors: such runs fly."""
    import copy

    from bb2_sim.maneuvers import saturation_warning
    from bb2_sim.parameters import load_parameters
    from bb2_tools.campaign.spec import set_dotted

    limit = float(load_parameters().act["plane_limit_deg"])

    def said_of(doc: dict[str, Any]) -> str:
        if spec.target == "maneuver":
            s = maneuver_settings_of(spec, doc)
            env = s.environment
            parts = [saturation_warning(s, limit)]
        else:
            env = build_mission(spec, doc).environment
            parts = []
        parts.append(env.sea.steepness_warning() if env is not None else "")
        return "; ".join(filter(None, parts))

    said = said_of(copy.deepcopy(spec.base))
    if said:
        return [f"{'maneuver.options' if spec.target == 'maneuver' else 'mission'}: {said}"]
    out = []
    for v in spec.vary:
        extremes = v.params if v.kind in ("uniform", "choice", "grid", "value") else (v.clip or ())
        for val in extremes[:max_values]:
            doc = spec.document(0)
            try:
                set_dotted(doc, v.key, copy.deepcopy(val))
                said = said_of(doc)
            except Exception:  # noqa: BLE001 -- a value the probe let through but that does not build: no warning
                continue
            if said:
                out.append(f"vary.{v.key} = {val!r}: {said}")
                break
    return out
