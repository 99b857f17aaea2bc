"""The figures of a recorded run (:func:`analyze`): typed records, and the flat named figures printed and written.

Definitions (those of :mod:`bb2_mission`, so analysis and runner agree by construction):

* a *tick* is a recorded state that the ROM stepped from: every state but the last one (the runner
  logs the rows t_0 .. t_{N-1} and ends with the simulator at t_N, which the simulator node also
  publishes);  messages are matched to ticks by their header stamp (integer nanoseconds);
* ``rms/max_vertical_m``, ``rms/max_horizontal_m``: the stack's own errors (``path_error`` y = left,
  z = up) over the ticks, RMS and max |e| (:func:`bb2_mission.MissionSummary`);
* ``*_closest_m``: from the closest path point, :func:`bb2_mission.path_errors_closest`;
* ``rms_nav_error_m``, ``max_nav_error_m``, ``max_nav_heading_error_deg`` (a bag with
  ``/bb2/nav/state_native``: the stack flew on the navigation estimate): the estimate's position error and
  heading error against the state at the ticks, as the runner's summary;
* ground clearance: ``z - z_terrain(x, y)`` of the CG (vertical, native) and of the lowest hull probe when
  the mission's terrain is known (``mission=``, or the bag's ``custom_data`` ``mission_file``, or the
  simulator's ``/bb2/status`` ``mission_file``); else the altimeter's minimum (``/bb2/altitude``);
* the end: a bag whose ``/bb2/mission/progress`` reaches 1 (the path follower's virtual time at the path's
  end: the runner's ``finished``) is analysed up to that tick and the state after it, as the runner ends
  there; what the graph recorded after (the launcher stops on the progress it sees) is left out, with a note;
* mission time: the time of the last analysed state; real-time factor: sim time over the wall time of the
  states' DDS source timestamps (else the simulator's status value);
* maneuver figures (``maneuver=`` or ``custom_data`` ``maneuver``): :func:`bb2_sim.metrics.figures_for`
  on the maneuver CSV columns rebuilt from the bag.

The figures are typed records (:class:`RunFigures` of :class:`RunTimes`, :class:`PathErrorStats`,
:class:`ClearanceFigures`, :class:`TrajectoryFigures`, :class:`CommandFigures` of :class:`SignalStats` and
:class:`PlaneStats`); a figure that could not be computed is ``None``.  :meth:`RunFigures.named` flattens
them into the named figures that ``bb2-analyze`` prints and writes (``figures.json``, the report), in a
fixed order, leaving out the ``None`` ones: ``mission_time_s``, ``rms_vertical_m``, ``dV_max_abs_rad``,
``planes_d3_max_abs_rad``, ``maneuver.tactical_diameter_m``, ...  Figures are SI (m, s, rad, rev/s);
:func:`format_figure` shows names ending in ``_rad``/``_rad_s`` in degrees and fractions in percent.
"""
from __future__ import annotations

import dataclasses
import json
import math
from dataclasses import asdict, dataclass, field
from typing import TYPE_CHECKING, Any, Mapping

import numpy as np

from bb2_mission.summary import navigation_errors, rms_max

from bb2_tools.bag_run import T_NAV, T_PATH, T_PATH_ERROR, AnalysisError, BagRun, Series

if TYPE_CHECKING:
    from bb2_sim.metrics import Figures as ManeuverFigures

__all__ = ["RunTimes", "PathErrorStats", "ClearanceFigures", "TrajectoryFigures", "SignalStats", "PlaneStats",
           "CommandFigures", "RunFigures", "Analysis", "analyze", "compare", "format_figure"]

RAD2DEG = 180.0 / math.pi
TWO_PI = 2.0 * math.pi
_EPOCH_2001_NS = 978_307_200 * 1_000_000_000  # a publish time after this is a wall-clock time


# ------------------------------------------------------------------------------------------ figures
def _present(pairs: Mapping[str, float | None]) -> dict[str, float]:
    """The pairs whose value was computed (not None), as floats."""
    return {k: float(v) for k, v in pairs.items() if v is not None}


@dataclass(frozen=True)
class RunTimes:
    """How long the analysed run is."""

    mission_time_s: float                   #: s, time of the last analysed state
    recorded_time_s: float                  #: s, last minus first recorded state time (before the cut at the end)
    ticks: int                              #: states the ROM stepped from (every analysed state but the last)

    def named(self) -> dict[str, float]:
        return _present({"mission_time_s": self.mission_time_s, "recorded_time_s": self.recorded_time_s,
                         "ticks": self.ticks})


@dataclass(frozen=True)
class PathErrorStats:
    """RMS and max |e| over the ticks of the vertical (> 0 above) and horizontal (> 0 left) path errors, m.

    NaN where no tick has a finite error (as the mission runner's summary)."""

    rms_vertical_m: float
    max_vertical_m: float
    rms_horizontal_m: float
    max_horizontal_m: float

    def named(self, kind: str = "") -> dict[str, float]:
        """``rms_vertical{kind}_m``, ...: ``kind`` is "" for the stack's own errors, "_closest" for the others."""
        return _present({f"rms_vertical{kind}_m": self.rms_vertical_m, f"max_vertical{kind}_m": self.max_vertical_m,
                         f"rms_horizontal{kind}_m": self.rms_horizontal_m,
                         f"max_horizontal{kind}_m": self.max_horizontal_m})


@dataclass(frozen=True)
class ClearanceFigures:
    """Minimum ground clearance: from the mission's terrain (over the ticks) or, without it, the altimeter."""

    min_clearance_m: float | None = None        #: m, CG height above the terrain under it (vertical)
    min_clearance_t_s: float | None = None      #: s, tick time of that minimum
    min_hull_clearance_m: float | None = None   #: m, of the lowest hull probe
    min_altitude_m: float | None = None         #: m, minimum of /bb2/altitude (terrain unknown)
    min_altitude_t_s: float | None = None       #: s, stamp of that minimum

    def named(self) -> dict[str, float]:
        return _present({f.name: getattr(self, f.name) for f in dataclasses.fields(self)})


@dataclass(frozen=True)
class TrajectoryFigures:
    """Of every analysed state."""

    mean_speed_m_s: float                   #: m/s, mean of |(u, v, w)|
    max_depth_m: float                      #: m, max of -z
    min_depth_m: float                      #: m, min of -z

    def named(self) -> dict[str, float]:
        return _present({f.name: getattr(self, f.name) for f in dataclasses.fields(self)})


@dataclass(frozen=True)
class SignalStats:
    """Statistics of one sampled signal over its finite samples, in ``unit`` ("rad", "rad_s" or "rps").

    The rates are in ``unit`` per second (from consecutive samples); ``None``: not computed (a single sample,
    or no limit given)."""

    unit: str                               #: unit of the values: "rad", "rad_s" (rad/s) or "rps" (rev/s)
    mean: float                             #: [unit]
    max_abs: float                          #: [unit]
    rms_rate: float | None = None           #: [unit/s]
    max_abs_rate: float | None = None       #: [unit/s]
    saturated_fraction: float | None = None  #: of the samples at the position limit, 0..1

    def named(self, prefix: str) -> dict[str, float]:
        """``{prefix}_mean_{unit}``, ``{prefix}_max_abs_{unit}``, ``{prefix}_rms_rate_{unit}_s``, ..."""
        u = self.unit
        return _present({f"{prefix}_mean_{u}": self.mean, f"{prefix}_max_abs_{u}": self.max_abs,
                         f"{prefix}_rms_rate_{u}_s": self.rms_rate, f"{prefix}_max_abs_rate_{u}_s": self.max_abs_rate,
                         f"{prefix}_saturated_fraction": self.saturated_fraction})


@dataclass(frozen=True)
class PlaneStats:
    """The five plane angles delta_1..delta_5 (commanded or actual), rad."""

    max_abs_rad: float                      #: rad, max |delta| over the five
    max_abs_each_rad: tuple[float, ...]     #: rad, max |delta_i| of each plane, i = 1..5
    any_saturated_fraction: float           #: of the samples with any plane at the position limit, 0..1
    max_abs_rate_rad_s: float | None = None  #: rad/s, max |d delta_i / dt| (None: a single sample)
    any_rate_limited_fraction: float | None = None  #: of the steps with any plane at the rate limit (actual only)

    def named(self, prefix: str) -> dict[str, float]:
        out = {f"{prefix}_max_abs_rad": self.max_abs_rad}
        out.update({f"{prefix}_d{i + 1}_max_abs_rad": v for i, v in enumerate(self.max_abs_each_rad)})
        out.update({f"{prefix}_any_saturated_fraction": self.any_saturated_fraction,
                    f"{prefix}_max_abs_rate_rad_s": self.max_abs_rate_rad_s,
                    f"{prefix}_any_rate_limited_fraction": self.any_rate_limited_fraction})
        return _present(out)


@dataclass(frozen=True)
class CommandFigures:
    """Statistics of the commands and actuator states (``None``: the topic is not in the bag)."""

    q_c: SignalStats | None = None          #: pitch-rate command of the path follower, rad/s (native)
    r_c: SignalStats | None = None          #: yaw-rate command, rad/s (native)
    dV: SignalStats | None = None           #: deltaV command of the autopilot, rad
    dH: SignalStats | None = None           #: deltaH command, rad
    planes_cmd: PlaneStats | None = None    #: commanded plane angles
    planes: PlaneStats | None = None        #: actual plane angles (with the rate limit)
    propeller_cmd: SignalStats | None = None  #: commanded shaft speed, rev/s (with the rps limit)
    propeller: SignalStats | None = None    #: actual shaft speed, rev/s

    def named(self) -> dict[str, float]:
        """Each signal's figures prefixed with the field's name, in field order."""
        out: dict[str, float] = {}
        for f in dataclasses.fields(self):
            stats = getattr(self, f.name)
            if stats is not None:
                out.update(stats.named(f.name))
        return out


@dataclass(frozen=True)
class RunEnd:
    """How the recorded run ended, by the mission runner's rules: ``reason`` an :class:`bb2_mission.EndReason`
    value -- ``finished`` (progress 1), ``duration``, ``grounded`` / ``broached`` (the first tick that breaks the
    mission's limits, :func:`bb2_mission.limit_event`; the runner stops there, the graph flies on),
    ``diverged`` (the simulator said so, or a state is not finite), and in a graph's bag alone ``stalled`` (its
    simulator stopped on the failsafe after ``stall_timeout_s``: no controller answered) or ``stopped`` (the
    recording ends before the mission's duration, the simulator never finished: the graph or its recorder was
    stopped) -- at
    ``t_s`` (s; None: unknown), and for a failure the ``message`` the runner gives (``grounded at t = 12.35 s, CG
    at ...: lowest hull point ...``).  Limits are checked only when the mission is known."""

    reason: str
    t_s: float | None = None
    message: str = ""

    @property
    def completed(self) -> bool:
        """The runner's ``completed``: the stack finished the path."""
        return self.reason == "finished"

    def line(self) -> str:
        return self.message or self.reason + ("" if self.t_s is None else f" at t = {self.t_s:.2f} s")

    def as_dict(self) -> dict[str, Any]:
        return {"reason": self.reason, "t_s": self.t_s, "completed": self.completed, "message": self.message}


@dataclass(frozen=True)
class RunFigures:
    """Every figure of one analysed run (see the module docstring for the definitions)."""

    times: RunTimes
    path_error: PathErrorStats | None       #: the stack's own errors (None: no /bb2/guidance/path_error)
    path_error_closest: PathErrorStats | None  #: from the closest path point (None: no path)
    final_progress: float | None            #: last /bb2/mission/progress (None: not recorded)
    clearance: ClearanceFigures
    trajectory: TrajectoryFigures
    commands: CommandFigures
    real_time_factor: float                 #: sim time / wall time (NaN: unknown)
    maneuver: ManeuverFigures | None = None  #: bb2_sim.metrics figures of a maneuver run
    end: RunEnd = RunEnd("")                #: how the run ended (reason "" for a maneuver bag)
    #: the navigation estimate's errors at the ticks (navigation: sensors; None on the truth): the runner's
    #: rms_nav_error_m, max_nav_error_m, max_nav_heading_error_deg
    navigation: Mapping[str, float] | None = None

    def named(self) -> dict[str, float]:
        """The named figures (as printed and written by ``bb2-analyze``), in their fixed order."""
        out = self.times.named()
        if self.path_error is not None:
            out.update(self.path_error.named())
        if self.path_error_closest is not None:
            out.update(self.path_error_closest.named("_closest"))
        out.update(_present({"final_progress": self.final_progress}))
        out.update(self.navigation or {})
        out.update(self.clearance.named())
        out.update(self.trajectory.named())
        out.update(self.commands.named())
        out["real_time_factor"] = float(self.real_time_factor)
        if self.maneuver is not None:
            out.update(_maneuver_named(self.maneuver))
        return out


def _maneuver_named(figures: ManeuverFigures) -> dict[str, float]:
    """``maneuver.<field>`` (``maneuver.<field>[i]`` for tuples) of the numeric maneuver figures."""
    out: dict[str, float] = {}
    for k, v in figures.to_dict().items():
        if isinstance(v, tuple):
            for i, vi in enumerate(v):
                if isinstance(vi, (int, float)) and not isinstance(vi, bool):
                    out[f"maneuver.{k}[{i}]"] = float(vi)
        elif isinstance(v, (int, float)) and not isinstance(v, bool):
            out[f"maneuver.{k}"] = float(v)
    return out


# ------------------------------------------------------------------------------------------ analysis
@dataclass
class Analysis:
    """The figures of one run and the arrays behind them (native frames, SI)."""

    run: BagRun
    figures: RunFigures
    tick: np.ndarray                        #: bool mask over run.t: states the ROM stepped from
    e_vertical: np.ndarray                  #: m, stack's errors at the ticks (NaN where not recorded)
    e_horizontal: np.ndarray
    e_vertical_closest: np.ndarray          #: m, at the ticks
    e_horizontal_closest: np.ndarray
    clearance: np.ndarray                   #: m, CG vertical clearance at every state (NaN if unknown)
    hull_clearance: np.ndarray
    terrain_z: np.ndarray
    mission: Any = None
    maneuver: str | None = None
    maneuver_traj: dict[str, np.ndarray] | None = None
    warnings: list[str] = field(default_factory=list)
    rtf_source: str = "unknown"             #: where the real-time factor comes from

    @property
    def label(self) -> str:
        return self.run.label

    @property
    def named_figures(self) -> dict[str, float]:
        """:meth:`RunFigures.named`: name -> value, as printed and written."""
        return self.figures.named()

    @property
    def maneuver_figures(self) -> ManeuverFigures | None:
        return self.figures.maneuver


def compare(a: Analysis, b: Analysis) -> list[tuple[str, float, float, float]]:
    """(figure, value A, value B, B - A) for every named figure of either run (NaN where one lacks it)."""
    fa, fb = a.named_figures, b.named_figures
    names = list(fa) + [k for k in fb if k not in fa]
    out = []
    for k in names:
        va, vb = fa.get(k, math.nan), fb.get(k, math.nan)
        out.append((k, va, vb, vb - va if math.isfinite(va) and math.isfinite(vb) else math.nan))
    return out


_UNIT_SUFFIXES = (("_rps_s", "rev/s^2", 1.0), ("_rps", "rev/s", 1.0), ("_rad_s_s", "deg/s^2", RAD2DEG),
                  ("_rad_s", "deg/s", RAD2DEG), ("_rad", "deg", RAD2DEG), ("_m_s", "m/s", 1.0), ("_m", "m", 1.0),
                  ("_s", "s", 1.0), ("_fraction", "%", 100.0), ("_deg", "deg", 1.0))


def format_figure(name: str, value: float) -> tuple[str, str, str]:
    """(label, value text, unit) of a named figure in display units: radians become degrees, fractions percent."""
    base = name.split("[")[0]
    for suffix, unit, factor in _UNIT_SUFFIXES:
        if base.endswith(suffix):
            label = name.replace(suffix, "", 1) if not name.startswith("maneuver.") else name
            return label, _fmt(value * factor), unit
    return name, _fmt(value), ""


def _fmt(v: float) -> str:
    if v is None or not math.isfinite(v):
        return "n/a"
    if v == int(v) and abs(v) < 1e6:
        return str(int(v))
    if v != 0 and (abs(v) >= 1e5 or abs(v) < 1e-3):
        return f"{v:.4g}"
    return f"{v:.4f}".rstrip("0").rstrip(".") if abs(v) < 100 else f"{v:.2f}"


# ------------------------------------------------------------------------------------------ computing
def analyze(run: BagRun, *, mission: Any = None, maneuver: str | None = None,
            maneuver_settings: Mapping[str, Any] | None = None) -> Analysis:
    """Compute the figures of a decoded bag (see the module docstring for every definition).

    ``mission``: a :class:`bb2_mission.Mission`, a mission file or shipped name, or None (from the bag);
    ``maneuver``: a maneuver name (default: the bag's ``custom_data`` ``maneuver``) whose figures to compute,
    with ``maneuver_settings`` over the catalogue's and the bag's.  :class:`AnalysisError` on bad options."""
    from bb2_sim.parameters import load_parameters
    from bb2_mission import path_errors_closest

    warnings = list(run.warnings)
    recorded_time_s = float(run.t[-1] - run.t[0])
    run = _until_finished(run, warnings)
    n = len(run.t)
    tick = np.ones(n, bool)
    tick[-1] = False  # the last state was not stepped from (runner rows t_0 .. t_{N-1})
    ticks_ns = run.stamps_ns[tick]
    P = run.x[tick, 0:3]

    mission = _resolve_mission(run, mission, warnings)
    path, samples = run.path, run.path_samples
    if path is None and mission is not None:
        path = mission.path.to_frame("native") if mission.path.frame != "native" else mission.path
        samples = path.sample(2001)[1]
        warnings.append(f"the bag has no path topic: using the path of mission {mission.name!r}")
    elif path is not None and mission is not None:
        mp = mission.path.to_frame("native") if mission.path.frame != "native" else mission.path
        same = mp.span == path.span and np.array_equal(np.asarray(mp.control_points), np.asarray(path.control_points))
        if not same:
            warnings.append(f"the bag's path differs from the path of mission {mission.name!r}: "
                            "analysing against the bag's")

    times = RunTimes(mission_time_s=float(run.t[-1]), recorded_time_s=recorded_time_s, ticks=int(tick.sum()))

    # path errors: the stack's own (p_T of /bb2/guidance/path_error) and from the closest path point
    e = run.path_error.at_stamps(ticks_ns)
    e_h, e_v = e[:, 1], e[:, 2]
    stack_errors = None
    if len(run.path_error):
        missing = int(np.isnan(e_v).sum())
        if missing:
            warnings.append(f"{T_PATH_ERROR}: {missing} of {len(ticks_ns)} ticks have no path error "
                            "(statistics over the recorded ones)")
        stack_errors = _error_stats(e_v, e_h)
    else:
        warnings.append(f"no {T_PATH_ERROR} in the bag: only closest-point path errors")
    if path is not None:
        eh_c, ev_c = path_errors_closest(path, P)
    elif samples is not None:
        eh_c, ev_c = _closest_errors_samples(samples, P)
        warnings.append(f"closest-point errors from the {T_PATH} samples ({len(samples)} points): "
                        "resolution-limited, not the exact Bernstein path")
    else:
        eh_c = ev_c = np.full(len(P), np.nan)
        warnings.append("no path in the bag (and no mission): no closest-point path errors")
    closest_errors = _error_stats(ev_c, eh_c) if np.isfinite(ev_c).any() else None
    final_progress = float(run.progress.v[-1, 0]) if len(run.progress) else None
    navigation = _navigation_errors(run, tick, warnings) if len(run.nav_state) else None

    # ground clearance
    zt = cl = hull = np.full(n, np.nan)
    clearance = ClearanceFigures()
    terrain = getattr(mission, "terrain", None)
    probes = _hull_probes(mission, warnings) if mission is not None else None
    if terrain is not None:
        vals = np.array([_clearances(terrain, probes, xi) for xi in run.x])
        zt, cl, hull = vals[:, 0], vals[:, 1], vals[:, 2]
        clt, hullt = cl[tick], hull[tick]
        if np.isfinite(clt).any():
            k = int(np.nanargmin(clt))
            clearance = dataclasses.replace(clearance, min_clearance_m=float(clt[k]),
                                            min_clearance_t_s=float(run.t[tick][k]))
        if np.isfinite(hullt).any():
            clearance = dataclasses.replace(clearance, min_hull_clearance_m=float(np.nanmin(hullt)))
    elif len(run.altitude):
        a = run.altitude.v[:, 0]
        if np.isfinite(a).any():
            k = int(np.nanargmin(a))
            clearance = ClearanceFigures(min_altitude_m=float(a[k]), min_altitude_t_s=float(run.altitude.t[k]))
        warnings.append("terrain unknown (give --mission): ground clearance from the altimeter (/bb2/altitude)")

    # trajectory
    x = run.x
    trajectory = TrajectoryFigures(mean_speed_m_s=float(np.mean(np.linalg.norm(x[:, 6:9], axis=1))),
                                   max_depth_m=float(np.max(-x[:, 2])), min_depth_m=float(np.min(-x[:, 2])))

    # commands and planes
    act = load_parameters().act
    lim = math.radians(float(act["plane_limit_deg"]))
    rate_lim = math.radians(float(act["plane_rate_deg_s"]))
    rps_limit = float(act["rps_limits"][1])
    rc, vh = run.rate_cmd, run.vh_cmd
    commands = CommandFigures(
        q_c=_signal_stats(rc.t, rc.col(0), unit="rad_s") if len(rc) else None,
        r_c=_signal_stats(rc.t, rc.col(1), unit="rad_s") if len(rc) else None,
        dV=_signal_stats(vh.t, vh.col(0), unit="rad") if len(vh) else None,
        dH=_signal_stats(vh.t, vh.col(1), unit="rad") if len(vh) else None,
        planes_cmd=_planes_stats(run.planes_cmd, lim, None),
        planes=_planes_stats(run.planes, lim, rate_lim),
        # shaft speed in rev/s, the ROM's unit
        propeller_cmd=(_signal_stats(run.prop_cmd.t, run.prop_cmd.col(0) / TWO_PI, unit="rps", limit=rps_limit)
                       if len(run.prop_cmd) else None),
        propeller=(_signal_stats(run.prop.t, run.prop.col(0) / TWO_PI, unit="rps", limit=rps_limit)
                   if len(run.prop) else None))

    rtf, rtf_source = _real_time_factor(run)
    if not math.isfinite(rtf):
        warnings.append("real-time factor unknown (no wall-clock publish times, no simulator status)")

    # maneuver
    maneuver = maneuver or run.custom_data.get("maneuver") or None
    man_figs = man_traj = None
    if maneuver_settings and not maneuver:  # (they were ignored without a word)
        raise AnalysisError("maneuver settings apply to a maneuver's figures: name the maneuver (--maneuver NAME; "
                            "the bag names none)")
    if maneuver_settings:
        from dataclasses import fields

        from bb2_sim.maneuvers import ManeuverSettings
        from bb2_sim.metrics import FIGURE_SETTINGS
        from bb2_sim.names import unknown_keys_hint

        known = {*FIGURE_SETTINGS, *(f.name for f in fields(ManeuverSettings))}
        if unknown := sorted(set(maneuver_settings) - known):
            raise AnalysisError(f"unknown maneuver setting(s) {unknown}{unknown_keys_hint(unknown, known)}; the "
                                f"figures read: {', '.join(FIGURE_SETTINGS)}")
    if maneuver:
        from bb2_sim import metrics
        from bb2_sim.maneuvers import ManeuverError, maneuver_settings as settings_of

        settings: dict[str, Any] = {}
        try:
            settings = asdict(settings_of(maneuver))
        except (ManeuverError, KeyError, TypeError, ValueError):
            pass  # a name metrics knows without a catalogue entry
        if run.custom_data.get("maneuver_settings"):
            try:
                settings.update(json.loads(run.custom_data["maneuver_settings"]))
            except json.JSONDecodeError as exc:
                warnings.append(f"custom_data maneuver_settings is not JSON ({exc}): ignored")
        settings.update(maneuver_settings or {})
        man_traj = _maneuver_traj(run)
        try:
            man_figs = metrics.figures_for(maneuver, man_traj, **settings)
        except metrics.TrajectoryError as exc:
            if maneuver_settings is not None or "maneuver" not in run.custom_data:
                raise AnalysisError(f"maneuver {maneuver!r}: {exc}") from None
            warnings.append(f"maneuver figures of {maneuver!r} not computed: {exc}")
        if man_figs is not None:
            _say_unreached(maneuver, man_figs, man_traj, settings, warnings)

    # a maneuver bag has no mission end; a mission's run analysed with a maneuver's figures keeps its own
    end = RunEnd("") if maneuver and "maneuver" in run.custom_data else \
        _run_end(run, tick, mission, probes, cl, hull, warnings)
    figures = RunFigures(times=times, path_error=stack_errors, path_error_closest=closest_errors,
                         final_progress=final_progress, clearance=clearance, trajectory=trajectory,
                         commands=commands, real_time_factor=rtf, maneuver=man_figs, end=end,
                         navigation=navigation)
    return Analysis(run=run, figures=figures, tick=tick, e_vertical=e_v, e_horizontal=e_h,
                    e_vertical_closest=np.asarray(ev_c, float), e_horizontal_closest=np.asarray(eh_c, float),
                    clearance=cl, hull_clearance=hull, terrain_z=zt, mission=mission, maneuver=maneuver,
                    maneuver_traj=man_traj, warnings=warnings, rtf_source=rtf_source)


# ------------------------------------------------------------------------------------------ the parts
def _navigation_errors(run: BagRun, tick: np.ndarray, warnings: list[str]) -> dict[str, float]:
    """The errors of the navigation estimate (``/bb2/nav/state_native``) against the state at the ticks, as the
    runner's summary computes them: position (m, RMS and max) and heading (deg, max)."""
    est = run.nav_state.at_stamps(run.stamps_ns[tick])
    x = run.x[tick]
    ok = np.isfinite(est[:, 0])
    if not ok.all():
        warnings.append(f"{T_NAV}: {int((~ok).sum())} of {len(ok)} ticks have no navigation estimate "
                        "(statistics over the recorded ones)")
    e, dpsi = navigation_errors(est, x)
    rms, mx = rms_max(e)
    return {"rms_nav_error_m": rms, "max_nav_error_m": mx, "max_nav_heading_error_deg": rms_max(dpsi)[1]}


def _error_stats(e_vertical: np.ndarray, e_horizontal: np.ndarray) -> PathErrorStats:
    rv, mv = rms_max(e_vertical)
    rh, mh = rms_max(e_horizontal)
    return PathErrorStats(rms_vertical_m=rv, max_vertical_m=mv, rms_horizontal_m=rh, max_horizontal_m=mh)


def _closest_errors_samples(samples: np.ndarray, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`bb2_mission.path_errors_closest` for a sampled path (tangent by finite differences)."""
    from scipy.spatial import cKDTree

    _, k = cKDTree(samples).query(p)
    d = np.gradient(samples, axis=0)[k]
    t1 = d / np.linalg.norm(d, axis=1, keepdims=True)
    h = np.c_[-d[:, 1], d[:, 0], np.zeros(len(d))]
    t2 = h / np.maximum(np.linalg.norm(h, axis=1, keepdims=True), 1e-12)
    t3 = np.cross(t1, t2)
    e = p - samples[k]
    return np.einsum("ij,ij->i", e, t2), np.einsum("ij,ij->i", e, t3)


def _resolve_mission(run: BagRun, mission: Any, warnings: list[str]) -> Any:
    """The mission object: given, else from the bag's custom_data / the simulator's status (if loadable)."""
    from bb2_mission import Mission, MissionError, load_mission

    if isinstance(mission, Mission):
        return mission
    if mission is not None:
        try:
            return load_mission(mission)
        except MissionError as exc:
            raise AnalysisError(f"--mission: {exc}") from None
    for where, value in (("custom_data mission_file", run.custom_data.get("mission_file")),
                         ("/bb2/status mission_file", run.status_value("mission_file")),
                         ("custom_data mission", run.custom_data.get("mission"))):
        if not value:
            continue
        try:
            return load_mission(value)
        except MissionError as exc:
            warnings.append(f"the bag names a mission ({where} = {value!r}) that cannot be loaded here: {exc}")
    return None


def _clearances(terrain: Any, probes: Any, x: np.ndarray) -> tuple[float, float, float]:
    """(terrain z under the CG, CG clearance, lowest hull probe clearance): the runner's definition."""
    pts = x[0:3].reshape(1, 3) if probes is None else np.vstack([x[0:3], probes.world(x)])
    inside = terrain.contains(pts)
    zt = np.full(len(pts), np.nan)
    if inside.any():
        zt[inside] = terrain.elevation(pts[inside, 0], pts[inside, 1])
    cl = pts[:, 2] - zt
    hull = float(np.nanmin(cl[1:])) if len(cl) > 1 and np.isfinite(cl[1:]).any() else math.nan
    return float(zt[0]), float(cl[0]), hull


def _run_end(run: BagRun, tick: np.ndarray, mission: Any, probes: Any, cl: np.ndarray, hull: np.ndarray,
             warnings: list[str]) -> RunEnd:
    """:class:`RunEnd` of a mission bag (already cut at progress 1 by :func:`_until_finished`)."""
    from bb2_mission import limit_event
    from bb2_mission.components import broaching_limit

    sim_state = run.status_value("state", "bb2/simulator")
    if sim_state == "diverged":  # at the last state it stepped from (the runner's)
        return RunEnd("diverged", float(run.t[-1]) if len(run.t) else None,
                      "diverged: " + (run.status_value("error", "bb2/simulator") or "(no detail)"))
    if sim_state == "stalled":  # the simulator stopped on its failsafe (its stall_timeout_s): no controller answered
        return RunEnd("stalled", float(run.t[-1]) if len(run.t) else None,
                      run.status_value("error", "bb2/simulator") or "stalled: the simulator stopped on its failsafe")
    bad = np.flatnonzero(~np.isfinite(run.x).all(axis=1))
    if len(bad):
        t = float(run.t[bad[0]])
        return RunEnd("diverged", t, f"diverged at t = {t:.2f} s: the recorded state is not finite")
    if mission is not None:
        lim = mission.limits
        if lim.max_cg_z_m is None and probes is None:
            max_z = math.inf
            warnings.append("no hull probes: broaching not checked")
        else:
            max_z = broaching_limit(mission, probes)
        with np.errstate(invalid="ignore"):
            broken = tick & ((np.isfinite(hull) & (hull < lim.min_hull_clearance_m)) | (run.x[:, 2] > max_z))
        if broken.any():
            k = int(np.flatnonzero(broken)[0])
            ev = limit_event(lim, max_z, float(run.t[k]), run.x[k], float(hull[k]), float(cl[k]))
            later = int(tick[k + 1:].sum())
            warnings.append(f"the run {ev.kind} at t = {ev.t:.2f} s ({ev.detail}): the mission runner ends there; "
                            f"the figures also cover the {later} recorded tick(s) after it")
            return RunEnd(str(ev.kind), float(ev.t), str(ev))
    if len(run.progress) and float(run.progress.v[-1, 0]) >= 1.0:
        return RunEnd("finished", float(run.t[-1]))
    return _stopped_early(run, mission, sim_state) or RunEnd("duration", float(run.t[-1]))


def _stopped_early(run: BagRun, mission: Any, sim_state: str | None) -> RunEnd | None:
    """``stopped``: a graph's run whose recording ends before the mission's duration, the path not flown and the
    simulator never saying ``finished`` -- the graph was stopped (``--timeout``, Ctrl-C, a node that failed, a
    stall) or its recorder was (the gap warnings say so) -- said with where and, if so, that the simulator was
    stepping on its failsafe (``sim_state``: the simulator's last ``state``); None otherwise."""
    if not len(run.t) or sim_state == "finished":
        return None
    try:  # what the simulator ran to (its duration_s parameter may replace the mission's), else the mission's
        duration = float(run.status_value("duration_s", "bb2/simulator") or "nan")
    except ValueError:
        duration = math.nan
    if not math.isfinite(duration) and mission is not None:
        duration = mission.duration
    t_end = float(run.t[-1])
    step = float(np.median(np.diff(run.t))) if len(run.t) > 1 else 0.0
    if not (math.isfinite(duration) and t_end < duration - 1.5 * step):
        return None
    progress = f"; progress {float(run.progress.v[-1, 0]):.3f}" if len(run.progress) else ""
    failsafe = (f"; the simulator was stepping on its failsafe ({run.status_value('failsafe_reason', 'bb2/simulator')})"
                if run.status_value("failsafe", "bb2/simulator") == "true" else "")
    return RunEnd("stopped", t_end, f"stopped at t = {t_end:.2f} s, before the mission's end (duration {duration:g} s"
                                    f"{progress}): the recording ends there (the graph or its recorder was "
                                    f"stopped){failsafe}")


def _hull_probes(mission: Any, warnings: list[str]) -> Any:
    try:
        from bb2_sim.model import BB2Model
        from bb2_mission import HullProbes

        return HullProbes(BB2Model(mission.hull, profile=mission.profile, sea_state=mission.sea_state).surfaces)
    except Exception as exc:  # the CG clearance is still computed
        warnings.append(f"hull probes unavailable ({type(exc).__name__}: {exc}): CG clearance only")
        return None


def _signal_stats(t: np.ndarray, v: np.ndarray, *, unit: str, limit: float | None = None) -> SignalStats | None:
    """mean, max |v|, RMS and max rate, and the fraction of samples at the position limit (None: no finite v)."""
    ok = np.isfinite(v)
    t, v = t[ok], v[ok]
    if v.size == 0:
        return None
    rms_rate = max_abs_rate = saturated = None
    if v.size > 1:
        rate = np.diff(v) / np.diff(t)
        rms_rate = float(np.sqrt(np.mean(rate ** 2)))
        max_abs_rate = float(np.max(np.abs(rate)))
    if limit is not None:
        saturated = float(np.mean(np.abs(v) >= limit * (1 - 1e-6)))
    return SignalStats(unit=unit, mean=float(np.mean(v)), max_abs=float(np.max(np.abs(v))), rms_rate=rms_rate,
                       max_abs_rate=max_abs_rate, saturated_fraction=saturated)


def _planes_stats(s: Series, limit_rad: float, rate_limit_rad_s: float | None) -> PlaneStats | None:
    """Max |delta| (all, each), the fraction at the limit; max rate and the fraction at the rate limit."""
    if not len(s):
        return None
    v = s.v
    max_rate = rate_limited = None
    if len(s) > 1:
        rate = np.diff(v, axis=0) / np.diff(s.t)[:, None]
        max_rate = float(np.nanmax(np.abs(rate)))
        if rate_limit_rad_s is not None:
            rate_limited = float(np.mean(np.any(np.abs(rate) >= rate_limit_rad_s * (1 - 1e-6), axis=1)))
    return PlaneStats(max_abs_rad=float(np.nanmax(np.abs(v))),
                      max_abs_each_rad=tuple(float(np.nanmax(np.abs(v[:, i]))) for i in range(5)),
                      any_saturated_fraction=float(np.mean(np.any(np.abs(v) >= limit_rad * (1 - 1e-6), axis=1))),
                      max_abs_rate_rad_s=max_rate, any_rate_limited_fraction=rate_limited)


def _real_time_factor(run: BagRun) -> tuple[float, str]:
    pub = run.state_publish_ns
    if len(pub) > 1 and pub.min() > _EPOCH_2001_NS and np.any(pub != run.stamps_ns):
        wall = (int(pub.max()) - int(pub.min())) * 1e-9
        if wall > 0:
            return float((run.t[-1] - run.t[0]) / wall), "states' DDS source timestamps"
    v = run.status_value("real_time_factor", "bb2/simulator")
    try:
        if v is not None and math.isfinite(float(v)):
            return float(v), "simulator status (last measured)"
    except ValueError:
        pass
    return math.nan, "unknown"


def _say_unreached(maneuver: str, figures: Any, traj: dict[str, np.ndarray], settings: dict[str, Any],
                   warnings: list[str]) -> None:
    """Warn of the maneuver figures that are n/a because the recording did not reach them (too short for a crossing
    or a steady phase), apart from those n/a because the bag does not record their quantity (thrust, torque: no
    contract topic), which are the figures that come out finite once those columns are filled."""
    missed = figures.unreached_fields()
    if not missed:
        return
    absent = [c for c, v in traj.items() if c != "t_s" and not np.isfinite(v).any()]
    if absent:
        from bb2_sim import metrics

        filled = metrics.figures_for(maneuver, {**traj, **{c: np.zeros_like(traj[c]) for c in absent}}, **settings)
        missed = [f for f in missed if f in filled.unreached_fields()]
    if missed:
        t_s = traj["t_s"]
        warnings.append(f"maneuver figures of {maneuver!r} not reached in this {t_s[-1] - t_s[0]:.1f} s recording "
                        f"(n/a): {', '.join(missed)}")


def _maneuver_traj(run: BagRun) -> dict[str, np.ndarray]:
    """The maneuver CSV columns (bb2_sim.maneuvers.CSV_COLUMNS) rebuilt from the bag (NaN where absent)."""
    from bb2_sim.maneuvers import CSV_COLUMNS

    x, t = run.x, run.t
    traj = {c: np.full(len(t), np.nan) for c in CSV_COLUMNS}
    traj["t_s"] = t.copy()
    for j, c in enumerate(("x_m", "y_m", "z_m")):
        traj[c] = x[:, j].copy()
    for j, c in enumerate(("phi_deg", "theta_deg", "psi_deg"), start=3):
        traj[c] = x[:, j] * RAD2DEG
    for j, c in enumerate(("u_m_s", "v_m_s", "w_m_s"), start=6):
        traj[c] = x[:, j].copy()
    for j, c in enumerate(("p_deg_s", "q_deg_s", "r_deg_s"), start=9):
        traj[c] = x[:, j] * RAD2DEG
    traj["U_m_s"] = np.linalg.norm(x[:, 6:9], axis=1)

    def held(s: Series) -> np.ndarray:  # the last sample at or before each state time (zero-order hold)
        out = np.full((len(t), s.v.shape[1]), np.nan)
        if len(s):
            k = np.searchsorted(s.stamp_ns, run.stamps_ns, side="right") - 1
            ok = k >= 0
            out[ok] = s.v[k[ok]]
        return out

    planes, cmd, prop = held(run.planes), held(run.planes_cmd), held(run.prop)
    for i in range(5):
        traj[f"dX{i + 1}_deg"] = planes[:, i] * RAD2DEG
        traj[f"cmd_dX{i + 1}_deg"] = cmd[:, i] * RAD2DEG
    traj["n_rps"] = prop[:, 0] / TWO_PI
    return traj


def _until_finished(run: BagRun, notes: list[str]) -> BagRun:
    """``run`` cut after the state that follows the first tick with progress >= 1 (the runner's end)."""
    if not len(run.progress):
        return run
    done = np.flatnonzero(run.progress.v[:, 0] >= 1.0)
    if not len(done):
        return run
    fin_ns = int(run.progress.stamp_ns[done[0]])
    m = int(np.searchsorted(run.stamps_ns, fin_ns, side="right")) + 1  # ticks up to fin_ns, and the next state
    if m >= len(run.t):
        return run
    notes.append(f"the mission finished at t = {fin_ns * 1e-9:.2f} s (progress 1): analysed up to the state after "
                 f"that tick, as the runner; {len(run.t) - m} later state(s) recorded, not analysed")
    return dataclasses.replace(run, t=run.t[:m], x=run.x[:m], stamps_ns=run.stamps_ns[:m],
                               state_publish_ns=run.state_publish_ns[:m])
