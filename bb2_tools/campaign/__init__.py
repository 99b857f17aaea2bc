"""Campaigns: Monte Carlo draws and grids of missions or maneuvers, flown in parallel (``bb2-campaign``).

The SPEC (YAML; unknown keys are an error, every fault is one message naming the field, exit status 2)::

    name: canyon_mc                      # default: the SPEC file's stem
    description: free text
    mission: missions/canyon.yaml        # a mission file (beside the SPEC, in the working directory, or one of
                                         # the project's missions/ -- canyon, canyon.yaml, missions/canyon.yaml --
                                         # from any directory), ``extends`` merged; or instead:
    # maneuver: {name: turning-circle, options: {rudder_deg: 20, duration: 300}}
    seed: 7                              # campaign seed (integer >= 0; default 0)
    samples: 200                         # draws of the distributions (default 1); each is crossed with the grid
    sampling: random                     # random (default) | latin_hypercube (of the distributions)
    vary:                                # dotted keys of the mission document (or of the maneuver options)
      sea_state: {choice: [0, 3, 5]}     #   choice: one of the values, equally likely
      initial.offset_m.2: {uniform: [-5, 5]}            #   uniform: [low, high); a numeric part indexes a list
      stack.guidance.d_m: {normal: [250, 25], clip: [150, 350]}   #   normal: [mean, sd], clipped if asked
      adaptation: [true, false]          #   a list is a grid: every value with every draw
      duration_s: 120                    #   a scalar (or {value: x}) is a constant override
    seed_key: sea.seed                   # optional: the dotted key that receives each run's own seed
    collect: [rms_vertical, rms_horizontal, min_clearance]   # default: the whole summary

**Runs.** ``runs = samples x grid points``; run ``index = sample * n_grid + grid point`` (the last grid key
varies fastest).  The distributions are drawn by inverse CDF from a (samples x distributions) matrix of unit
draws seeded by the campaign seed alone (plain random or a Latin hypercube), so every run's inputs, and its
own seed ``SeedSequence([seed, index])`` (32 bits; written into ``seed_key`` if given), depend only on the SPEC
and the index: a run is reproducible alone (``--only INDEX --out-run DIR``) and the results do not depend on
the engine, the number of workers or the order in which runs finish.

**Overrides.** Each run's document is the mission file's document (``extends`` merged) with each dotted key
set (mappings created as needed); it is then validated and loaded by
:func:`bb2_mission.schema.mission_from_dict` (relative files beside the mission file), so any mission field,
initial state (``initial.*``), limit, profile (``profile``), sea / current field of the mission schema, or
stack gain can be varied.  ``sea.hs`` varied on a mission with no sea (or a ``sea:`` block naming no spectrum,
component list or sea state) flies a Pierson-Moskowitz sea (JONSWAP with a ``sea.tp``), each run with its own wave
phases (``seed_key: sea.seed`` unless given): :func:`bb2_tools.campaign.spec.default_sea`, said as notes and kept
in ``campaign.yaml``.  A stack given by name becomes ``{base: NAME}`` first, so
``stack.autopilot.K_q_deg_per_radps`` or ``stack.guidance.d_m`` overrides one gain of the named stack.
Maneuvers: the keys are the maneuver settings of ``bb2_sim.maneuvers.ManeuverSettings`` (``rudder_deg``,
``speed_mps``, ``depth``, ``sea_state``, ``profile``, ``duration``, ...) and a mission's ``sea:`` / ``current:``
blocks (``sea.hs``, ``current.speed_mps``; :func:`bb2_sim.maneuvers.with_sea`, as ``bb2-sim maneuver``'s sea and
current options).  Before flying, every varied key is
set, run 0 is built (a failure names the key that alone gives the same fault, else the mission's own message
names the field), and every value of each choice / grid is checked on run 0: a bad key stops the campaign at
once.

**Figures** (:mod:`bb2_tools.campaign.figures`): those ``bb2-sim mission`` / ``bb2-sim maneuver`` print,
same values for the same inputs; mission summary fields by name (``rms_vertical_m``) or without the unit
suffix (``rms_vertical``); maneuver figures by field name (SI, radians), without the unit suffix, or
``*_deg`` / ``*_deg_s`` in the printed degrees.

**Status**: ``ok`` (path finished or duration reached), ``grounded``, ``broached``, ``diverged``, ``error``
(the stack failed, the run raised, or its figures could not be computed), with the message.

**Output** in ``--out DIR``: ``runs.jsonl`` (the journal, one line per finished run as it lands),
``results.parquet`` and ``results.csv`` (one row per run, by index: ``index, seed``, every varied key, every
collected figure, ``status, message, wall_time_s``; NaN is null / empty), ``campaign.yaml`` (the resolved
SPEC and the software version) and ``report.html``.

**Engines** (:mod:`bb2_tools.campaign.engines`): ``local`` (a process pool) or ``ray`` (a Ray cluster); the
default worker is the library runner (:mod:`bb2_tools.campaign.worker`, no ROS); ``--graph`` flies each run
through the ROS 2 graph in lockstep on its own domain (:mod:`bb2_tools.campaign.graph`).
"""
from __future__ import annotations

from bb2_tools.campaign.errors import SpecError

__all__ = ["SpecError"]
