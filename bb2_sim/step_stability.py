"""Where the ROM's fixed step holds: the fastest steady cruise each number of ode3 sub-steps flies, and the advice
built on it.

The explicit ode3 step of 0.05 s / K (:mod:`bb2_sim.integrator`, ``substeps`` K) is numerically unstable above a
speed that grows with K; :func:`cruise_limits` are those speeds as measured (``data/substeps_stability.yaml``,
``benchmarks/substeps_stability.py``).  Before a run, :func:`speed_warning` says when the speed it will hold is above
what its sub-steps fly; after a divergence, :func:`substeps_hint` advises the sub-steps for the speed it held.  Both
name the fewest sub-steps that fly it (:func:`substeps_for`).
"""
from __future__ import annotations

from functools import lru_cache
from pathlib import Path
from typing import Any, Sequence

import numpy as np

DATA = Path(__file__).resolve().parent / "data" / "substeps_stability.yaml"


@lru_cache(maxsize=1)
def _data() -> dict[str, Any]:
    from bb2_sim.yaml_files import load as load_yaml

    return load_yaml(DATA.read_text())


def cruise_limits() -> dict[int, tuple[float, float]]:
    """Per number of sub-steps K: (the fastest steady cruise flown, the slowest that diverged), m/s, as measured."""
    return {int(k): (float(v["flown_m_s"]), float(v["diverged_m_s"])) for k, v in _data()["cruise"].items()}


def hint_from() -> float:
    """A diverged run is advised more sub-steps when it held at least this fraction of the fastest steady cruise its
    sub-steps fly (below, say a capsize at low speed, the step is not the likely cause)."""
    return float(_data()["advice"]["from_fraction_of_cruise"])


def hint_margin() -> float:
    """After a divergence the advice is the fewest sub-steps whose fastest steady cruise is this many times the speed
    the boat held (a boat holding a speed may still be speeding up towards its cruise)."""
    return float(_data()["advice"]["cruise_margin"])


def cruise_speed(rps: float) -> float:
    """The ROM's steady straight-ahead speed with the propeller at ``rps``, m/s (measured with the cruise limits)."""
    return float(_data()["cruise_m_s_per_rps"]) * float(rps)


def substeps_for(speed_mps: float, substeps: int = 1, margin: float | None = None) -> int:
    """More sub-steps than ``substeps`` for a boat at ``speed_mps``: the fewest whose measured steady cruise flies
    ``margin`` (default :func:`hint_margin`) times that speed; beyond the measured table, twice the larger of
    ``substeps`` and its largest."""
    limits = cruise_limits()
    need = (hint_margin() if margin is None else float(margin)) * speed_mps
    fit = [k for k, (flown, _) in sorted(limits.items()) if k > substeps and flown >= need]
    return fit[0] if fit else 2 * max(substeps, max(limits))


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


def substeps_hint(t_s: Sequence[float], speed_mps: Sequence[float], substeps: int, option: str,
                  toward_mps: float = 0.0) -> str:
    """For a run that diverged: '' or one line advising ``option`` with more ``substeps`` (:func:`substeps_for`)
    when the boat held, over its last 2 s, at least :func:`hint_from` of the fastest steady cruise that
    ``substeps`` fly (``t_s``, ``speed_mps``: its logged times and speeds, the last finite ones; a boat that
    capsized at low speed gets no such hint).  ``toward_mps``: the steady speed the run was heading for (the
    cruise of its propeller command, :func:`cruise_speed`); when faster than the speed held, the advice is for it
    (a boat diverging while it speeds up would diverge again, faster, with the sub-steps for the speed it held)."""
    t = np.asarray(t_s, dtype=float)
    u = np.asarray(speed_mps, dtype=float)
    if t.size == 0:
        return ""
    held = float(np.min(u[t >= t[-1] - 2.0]))
    limits = cruise_limits()
    flown, _ = limits.get(substeps, limits[max(limits)])
    if not held >= hint_from() * flown:
        return ""
    toward = float(toward_mps) if float(toward_mps) > hint_margin() * held else 0.0
    more = substeps_for(max(held, toward), substeps, margin=1.0 if toward else None)
    measured = ", ".join(f"{d:.1f}{' m/s' * (i == 0)} with {k}" for i, (k, (_, d)) in enumerate(sorted(limits.items())))
    heading = f" on its way to about {toward:.1f} m/s (the steady cruise of its propeller command)" if toward else ""
    beyond = "" if more in limits else " or more (faster than measured: benchmarks/substeps_stability.py)"
    return (f"the boat held {held:.1f} m/s{heading}, near or past where the ROM's 0.05 s step in {substeps} ode3 "
            f"step(s) turns numerically unstable (a steady cruise diverges from about {measured}); {option} {more} "
            f"integrates it in {more}{beyond}")
