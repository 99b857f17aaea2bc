"""bb2-analyze: the figures and numbers of a recorded BB2 run (one bag, or two bags compared).

Usage::

    bb2-analyze BAG [BAG2] [--out DIR] [--mission FILE.yaml] [--maneuver NAME] [--label A --label B]

``BAG`` is a rosbag2 bag directory (metadata.yaml + .mcap, ours or any rosbag2 MCAP with the contract's
topics) or a bare ``.mcap``.  A bag whose recorder was killed (no summary) is read up to its last complete
chunk and the report says so.  Output (``--out``, default ``<BAG>/analysis/``): PNG figures
(:mod:`bb2_tools.analysis_plots`), ``report.html`` (one self-contained file, :mod:`bb2_tools.report`) and
``figures.json``; the figures are also printed.  With two bags the plots overlay both runs and every
figure is printed as ``A``, ``B`` and ``B - A``.

What is read (contract topics of :mod:`bb2_msgs_py.contract`, decoded with the contract's conversions):

* the trajectory from ``/bb2/state_native`` (exact float64 ROM state) or, when absent, ``/bb2/odom``
  converted back to native (psi unwrapped);
* the path from ``/bb2/path/bernstein`` (exact control points) or, when absent, the ``/bb2/path`` samples
  (or the mission's path);
* ``/bb2/guidance/path_error`` (the stack's own path errors p_T), ``rate_cmd``, ``vh_cmd``, plane and
  propeller commands and states, ``/bb2/altitude``, ``/bb2/mission/progress``, ``/bb2/status``.

Definitions (those of :mod:`bb2_mission`, so analysis and runner agree by construction):

* a *tick* is a recorded state that the ROM stepped from: every state but the last one (the runner
  logs the rows t_0 .. t_{N-1} and ends with the simulator at t_N, which the simulator node also
  publishes);  messages are matched to ticks by their header stamp (integer nanoseconds);
* ``rms/max_vertical_m``, ``rms/max_horizontal_m``: the stack's own errors (``path_error`` y = left,
  z = up) over the ticks, RMS and max |e| (:func:`bb2_mission.MissionSummary`);
* ``*_closest_m``: from the closest path point, :func:`bb2_mission.path_errors_closest`;
* ground clearance: ``z - z_terrain(x, y)`` of the CG (vertical, native) and of the lowest hull probe when
  the mission's terrain is known (``--mission``, or the bag's ``custom_data`` ``mission_file``, or the
  simulator's ``/bb2/status`` ``mission_file``); else the altimeter's minimum (``/bb2/altitude``);
* the end: a bag whose ``/bb2/mission/progress`` reaches 1 (the path follower's virtual time at the path's
  end: the runner's ``finished``) is analysed up to that tick and the state after it, as the runner ends
  there; what the graph recorded after (the launcher stops on the progress it sees) is left out, with a note;
* mission time: the time of the last analysed state; real-time factor: sim time over the wall time of the
  states' DDS source timestamps (else the simulator's status value);
* maneuver figures (``--maneuver NAME`` or ``custom_data`` ``maneuver``): :func:`bb2_sim.metrics.figures_for`
  on the maneuver CSV columns rebuilt from the bag.

Figures are SI (m, s, rad); names ending in ``_rad``/``_rad_s`` are printed in degrees.
Exit codes: 0 done; 2 bad input (no bag, not a bag, no usable topics, bad mission file).
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import math
import sys
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, Callable, Mapping, Sequence

import numpy as np

from bb2_tools.bagfile import BagError, BagReader

__all__ = ["AnalysisError", "Series", "BagRun", "Analysis", "read_bag", "analyze", "compare",
           "format_figure", "figure_lines", "comparison_lines", "write_outputs", "main"]

RAD2DEG = 180.0 / math.pi
TWO_PI = 2.0 * math.pi
_EPOCH_2001_NS = 978_307_200 * 1_000_000_000  # a publish time after this is a wall-clock time

T_STATE = "/bb2/state_native"
T_ODOM = "/bb2/odom"
T_BERNSTEIN = "/bb2/path/bernstein"
T_PATH = "/bb2/path"
T_PATH_ERROR = "/bb2/guidance/path_error"
T_RATE = "/bb2/guidance/rate_cmd"
T_VH = "/bb2/autopilot/vh_cmd"
T_PLANES_CMD = "/bb2/planes/cmd"
T_PLANES = "/bb2/planes/state"
T_PROP_CMD = "/bb2/propeller/cmd"
T_PROP = "/bb2/propeller/state"
T_ALT = "/bb2/altitude"
T_PROGRESS = "/bb2/mission/progress"
T_STATUS = "/bb2/status"
USED_TOPICS = (T_STATE, T_ODOM, T_BERNSTEIN, T_PATH, T_PATH_ERROR, T_RATE, T_VH, T_PLANES_CMD, T_PLANES,
               T_PROP_CMD, T_PROP, T_ALT, T_PROGRESS, T_STATUS)


class AnalysisError(ValueError):
    """Input that cannot be analysed (no bag, not a bag, no usable topics, bad options)."""


# ------------------------------------------------------------------------------------------ data
@dataclass
class Series:
    """Samples of one topic: ``t`` (s, header stamps, sorted, one per stamp) and ``v`` (n x k)."""

    t: np.ndarray
    v: np.ndarray
    stamp_ns: np.ndarray

    @classmethod
    def empty(cls, k: int) -> "Series":
        return cls(np.zeros(0), np.zeros((0, k)), np.zeros(0, dtype=np.int64))

    def __len__(self) -> int:
        return len(self.t)

    def col(self, j: int) -> np.ndarray:
        return self.v[:, j]

    def at_stamps(self, stamps_ns: np.ndarray) -> np.ndarray:
        """Rows with exactly these stamps (NaN rows where a stamp has no sample)."""
        out = np.full((len(stamps_ns), self.v.shape[1]), np.nan)
        if len(self):
            k = np.searchsorted(self.stamp_ns, stamps_ns)
            k = np.clip(k, 0, len(self) - 1)
            hit = self.stamp_ns[k] == stamps_ns
            out[hit] = self.v[k[hit]]
        return out


@dataclass
class BagRun:
    """What a bag holds, decoded: the native trajectory, the path, commands and bookkeeping."""

    source: Path
    label: str
    topics: dict[str, str]
    counts: dict[str, int]
    truncated: bool
    problem: str
    custom_data: dict[str, str]
    state_source: str                      #: "state_native" | "odometry"
    t: np.ndarray                          #: s, state times (sorted, unique)
    x: np.ndarray                          #: (n, 12) native state [x y z phi theta psi u v w p q r]
    state_publish_ns: np.ndarray           #: DDS source timestamps of the states (wall clock, ns)
    path: Any = None                       #: BernsteinPath in the native frame (exact), or None
    path_samples: np.ndarray | None = None  #: (m, 3) native samples of the path
    path_source: str = ""
    path_error: Series = field(default_factory=lambda: Series.empty(3))    #: m, path frame (along, left, up)
    rate_cmd: Series = field(default_factory=lambda: Series.empty(2))      #: rad/s native (q_c, r_c)
    vh_cmd: Series = field(default_factory=lambda: Series.empty(2))        #: rad (delta_V, delta_H)
    planes_cmd: Series = field(default_factory=lambda: Series.empty(5))    #: rad
    planes: Series = field(default_factory=lambda: Series.empty(5))        #: rad (actual)
    prop_cmd: Series = field(default_factory=lambda: Series.empty(1))      #: rad/s
    prop: Series = field(default_factory=lambda: Series.empty(1))          #: rad/s (actual)
    altitude: Series = field(default_factory=lambda: Series.empty(1))      #: m (NaN: no bottom in range)
    progress: Series = field(default_factory=lambda: Series.empty(1))      #: 1
    status: list[tuple[float, str, dict[str, str]]] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)

    stamps_ns: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))  #: ns of the states

    def status_value(self, key: str, name_prefix: str = "") -> str | None:
        """The last value of a ``/bb2/status`` key (from statuses whose name starts with the prefix)."""
        for _, name, values in reversed(self.status):
            if name.startswith(name_prefix) and key in values:
                return values[key]
        return None


# ------------------------------------------------------------------------------------------ reading
def _decoders(reader: BagReader) -> Callable[[str, bytes], Any]:
    """Decode by type: the installed rclpy message class (C, fast), else mcap_ros2's dynamic decoder."""
    cache: dict[str, Callable[[bytes], Any]] = {}

    def dynamic(type_name: str) -> Callable[[bytes], Any]:
        from mcap_ros2.decoder import DecoderFactory

        schema = next((s for s in reader._schemas.values() if s.name == type_name), None)
        if schema is None:
            raise AnalysisError(f"{reader.mcap_path}: no schema for type {type_name}")
        return DecoderFactory().decoder_for("cdr", schema)

    def decode(type_name: str, data: bytes) -> Any:
        dec = cache.get(type_name)
        if dec is None:
            try:
                from rclpy.serialization import deserialize_message

                from bb2_msgs_py.contract import message_class

                cls = message_class(type_name)
                dec = cache[type_name] = lambda b, c=cls: deserialize_message(b, c)
            except Exception:  # not installed here: decode from the bag's own schema
                dec = cache[type_name] = dynamic(type_name)
        return dec(data)

    return decode


def _stamp_ns(msg: Any) -> int:
    st = msg.header.stamp
    return int(st.sec) * 1_000_000_000 + int(st.nanosec)


def _series(rows: list[tuple[int, Sequence[float]]], k: int) -> Series:
    """Sort by stamp; a stamp seen twice (a lockstep re-send answered from a cache) is kept once (first)."""
    if not rows:
        return Series.empty(k)
    rows = sorted(rows, key=lambda r: r[0])  # stable: the first received wins among equal stamps
    ns = np.array([r[0] for r in rows], dtype=np.int64)
    keep = np.r_[True, np.diff(ns) != 0]
    v = np.array([list(r[1]) for r in rows], dtype=float).reshape(len(rows), k)[keep]
    return Series(ns[keep] * 1e-9, v, ns[keep])


def read_bag(path: str | Path, label: str | None = None) -> BagRun:
    """Decode the contract topics of a bag (see the module docstring); :class:`AnalysisError` if unusable."""
    from bb2_msgs_py import conversions as cv

    p = Path(path)
    if not p.exists():
        raise AnalysisError(f"no bag at {p} (expected a bag directory or a .mcap file)")
    try:
        reader = BagReader(p)
    except BagError as exc:
        raise AnalysisError(f"{p}: not a readable bag: {exc}") from None
    topics = reader.topics
    if not topics:
        why = f" ({reader.problem})" if reader.problem else ""
        raise AnalysisError(f"{p}: not a bag or an empty one: no topics found{why}")
    if T_STATE not in topics and T_ODOM not in topics:
        raise AnalysisError(f"{p}: no usable topics: neither {T_STATE} nor {T_ODOM} is in the bag "
                            f"(it has {sorted(topics)})")
    decode = _decoders(reader)
    use_native = T_STATE in topics and reader.message_counts.get(T_STATE, 0) > 0
    wanted = [t for t in USED_TOPICS if t in topics and not (use_native and t == T_ODOM)]
    rows: dict[str, list] = {t: [] for t in USED_TOPICS}
    warnings: list[str] = []
    bad: dict[str, str] = {}
    state_pub: dict[int, int] = {}
    bernstein = None
    path_samples = None
    status: list[tuple[float, str, dict[str, str]]] = []
    for m in reader.raw_messages(wanted):
        try:
            msg = decode(m.type, m.data)
            if m.topic == T_STATE:
                s = cv.state_native_from_message(msg)
                ns = cv.seconds_to_ns(s.t)
                rows[T_STATE].append((ns, [s.t, *s.as_vector()]))
                state_pub.setdefault(ns, m.publish_time_ns)
            elif m.topic == T_ODOM:
                s = cv.odometry_to_state(msg)
                ns = _stamp_ns(msg)
                rows[T_ODOM].append((ns, [s.t, *s.as_vector()]))
                state_pub.setdefault(ns, m.publish_time_ns)
            elif m.topic == T_BERNSTEIN:
                bernstein = cv.bernstein_from_message(msg, name="bag")
            elif m.topic == T_PATH:
                path_samples = cv.path_from_message(msg)
            elif m.topic == T_PATH_ERROR:
                rows[m.topic].append((_stamp_ns(msg), cv.path_error_from_message(msg)))
            elif m.topic == T_RATE:
                rows[m.topic].append((_stamp_ns(msg), cv.rate_command_from_message(msg)))
            elif m.topic == T_VH:
                rows[m.topic].append((_stamp_ns(msg), cv.vh_from_message(msg)))
            elif m.topic in (T_PLANES_CMD, T_PLANES):
                rows[m.topic].append((_stamp_ns(msg), cv.planes_from_message(msg)))
            elif m.topic in (T_PROP_CMD, T_PROP):
                rows[m.topic].append((_stamp_ns(msg), [cv.propeller_from_message(msg)]))
            elif m.topic == T_ALT:
                a = cv.altitude_from_message(msg)
                rows[m.topic].append((_stamp_ns(msg), [a if math.isfinite(a) else math.nan]))
            elif m.topic == T_PROGRESS:
                rows[m.topic].append((m.log_time_ns, [float(msg.data)]))
            elif m.topic == T_STATUS:
                for st in msg.status:
                    status.append((_stamp_ns(msg) * 1e-9, str(st.name), {kv.key: kv.value for kv in st.values}))
        except (ValueError, AttributeError, TypeError, IndexError) as exc:
            if m.topic not in bad:
                bad[m.topic] = f"{type(exc).__name__}: {exc}"
    for topic_name, why in bad.items():
        warnings.append(f"{topic_name}: some messages could not be decoded and were skipped (first: {why})")
    if reader.truncated:
        warnings.insert(0, f"the bag is truncated (recorder killed?): read up to the last complete chunk, "
                           f"{reader.message_count} messages ({reader.problem or 'no summary'})")
    src = T_STATE if use_native else T_ODOM
    states = _series(rows[src], 13)  # [t (exact float, as published), x12]
    if len(states) < 2:
        raise AnalysisError(f"{p}: no usable topics: {src} has {len(states)} readable state(s), need >= 2")
    x = states.v[:, 1:].copy()
    if not use_native:
        x[:, 5] = np.unwrap(x[:, 5])
        warnings.append(f"no {T_STATE} in the bag: trajectory from odometry {T_ODOM} (quaternion round trip, "
                        "psi unwrapped)")
    path = None
    path_source = ""
    if bernstein is not None:
        path = bernstein.to_frame("native") if bernstein.frame != "native" else bernstein
        path_source = T_BERNSTEIN
        if path_samples is None:
            path_samples = path.sample(2001)[1]
    elif path_samples is not None:
        path_source = T_PATH
    md = reader.metadata or {}
    run = BagRun(
        source=p, label=label or (p.name if p.is_dir() else p.stem), topics=topics,
        counts=reader.message_counts, truncated=reader.truncated, problem=reader.problem,
        custom_data={str(k): str(v) for k, v in (md.get("custom_data") or {}).items()},
        state_source="state_native" if use_native else "odometry", t=states.v[:, 0].copy(), x=x,
        state_publish_ns=np.array([state_pub[int(n)] for n in states.stamp_ns], dtype=np.int64),
        stamps_ns=states.stamp_ns.copy(),
        path=path, path_samples=path_samples, path_source=path_source,
        path_error=_series(rows[T_PATH_ERROR], 3), rate_cmd=_series(rows[T_RATE], 2),
        vh_cmd=_series(rows[T_VH], 2), planes_cmd=_series(rows[T_PLANES_CMD], 5),
        planes=_series(rows[T_PLANES], 5), prop_cmd=_series(rows[T_PROP_CMD], 1),
        prop=_series(rows[T_PROP], 1), altitude=_series(rows[T_ALT], 1),
        progress=_series(rows[T_PROGRESS], 1), status=status, warnings=warnings)
    if reader.metadata is None and p.is_dir():
        run.warnings.append("no metadata.yaml beside the .mcap (bag not finished; `bagfile.recover` repairs it)")
    return run


# ------------------------------------------------------------------------------------------ analysis
@dataclass
class Analysis:
    """The figures of one run and the arrays behind them (native frames, SI)."""

    run: BagRun
    figures: dict[str, float]               #: name -> value (SI; see the module docstring)
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
    maneuver_figures: Any = None
    maneuver_traj: dict[str, np.ndarray] | None = None
    warnings: list[str] = field(default_factory=list)
    rtf_source: str = "unknown"             #: where the real-time factor comes from

    @property
    def label(self) -> str:
        return self.run.label


def _rms_max(e: np.ndarray) -> tuple[float, float]:
    """RMS and max |e| over the finite samples (as the mission runner's summary)."""
    e = np.asarray(e, float)
    e = e[np.isfinite(e)]
    if e.size == 0:
        return math.nan, math.nan
    return float(np.sqrt(np.mean(e ** 2))), float(np.max(np.abs(e)))


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


def _hull_probes(mission: Any, warnings: list[str]) -> Any:
    try:
        from bb2_sim.model import BB2Model
        from bb2_mission import HullProbes

        return HullProbes(BB2Model(mission.hull, profile=mission.profile, sea_state=mission.sea_state).surfaces)
    except Exception as exc:  # the CG clearance is still computed
        warnings.append(f"hull probes unavailable ({type(exc).__name__}: {exc}): CG clearance only")
        return None


def _signal_stats(prefix: str, t: np.ndarray, v: np.ndarray, out: dict[str, float], *, unit: str,
                  limit: float | None = None, rate_limit: float | None = None) -> None:
    """mean, max |v|, RMS and max rate, and the fraction of samples at the position / rate limit."""
    ok = np.isfinite(v)
    t, v = t[ok], v[ok]
    if v.size == 0:
        return
    out[f"{prefix}_mean_{unit}"] = float(np.mean(v))
    out[f"{prefix}_max_abs_{unit}"] = float(np.max(np.abs(v)))
    if v.size > 1:
        rate = np.diff(v) / np.diff(t)
        out[f"{prefix}_rms_rate_{unit}_s"] = float(np.sqrt(np.mean(rate ** 2)))
        out[f"{prefix}_max_abs_rate_{unit}_s"] = float(np.max(np.abs(rate)))
        if rate_limit is not None:
            out[f"{prefix}_rate_limited_fraction"] = float(np.mean(np.abs(rate) >= rate_limit * (1 - 1e-6)))
    if limit is not None:
        out[f"{prefix}_saturated_fraction"] = float(np.mean(np.abs(v) >= limit * (1 - 1e-6)))


def _planes_stats(prefix: str, s: Series, out: dict[str, float], limit_rad: float,
                  rate_limit_rad_s: float | None) -> None:
    if not len(s):
        return
    v = s.v
    out[f"{prefix}_max_abs_rad"] = float(np.nanmax(np.abs(v)))
    for i in range(5):
        out[f"{prefix}_d{i + 1}_max_abs_rad"] = float(np.nanmax(np.abs(v[:, i])))
    out[f"{prefix}_any_saturated_fraction"] = float(np.mean(np.any(np.abs(v) >= limit_rad * (1 - 1e-6), axis=1)))
    if len(s) > 1:
        rate = np.diff(v, axis=0) / np.diff(s.t)[:, None]
        out[f"{prefix}_max_abs_rate_rad_s"] = float(np.nanmax(np.abs(rate)))
        if rate_limit_rad_s is not None:
            out[f"{prefix}_any_rate_limited_fraction"] = float(
                np.mean(np.any(np.abs(rate) >= rate_limit_rad_s * (1 - 1e-6), axis=1)))


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


def analyze(run: BagRun, *, mission: Any = None, maneuver: str | None = None,
            maneuver_settings: Mapping[str, Any] | None = None) -> Analysis:
    """Compute the figures of a decoded bag (see the module docstring for every definition)."""
    from bb2_sim.parameters import load_parameters
    from bb2_mission import path_errors_closest

    warnings = list(run.warnings)
    recorded_time_s = float(run.t[-1] - run.t[0])
    run = _until_finished(run, warnings)
    figs: dict[str, float] = {}
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
        if not (mp.span == path.span and np.array_equal(np.asarray(mp.control_points), np.asarray(path.control_points))):
            warnings.append(f"the bag's path differs from the path of mission {mission.name!r}: "
                            "analysing against the bag's")

    figs["mission_time_s"] = float(run.t[-1])
    figs["recorded_time_s"] = recorded_time_s
    figs["ticks"] = float(tick.sum())  # states stepped from

    # path errors: the stack's own (p_T of /bb2/guidance/path_error) and from the closest path point
    e = run.path_error.at_stamps(ticks_ns)
    e_h, e_v = e[:, 1], e[:, 2]
    if len(run.path_error):
        missing = int(np.isnan(e_v).sum())
        if missing:
            warnings.append(f"{T_PATH_ERROR}: {missing} of {len(ticks_ns)} ticks have no path error "
                            "(statistics over the recorded ones)")
        figs["rms_vertical_m"], figs["max_vertical_m"] = _rms_max(e_v)
        figs["rms_horizontal_m"], figs["max_horizontal_m"] = _rms_max(e_h)
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
    if np.isfinite(ev_c).any():
        figs["rms_vertical_closest_m"], figs["max_vertical_closest_m"] = _rms_max(ev_c)
        figs["rms_horizontal_closest_m"], figs["max_horizontal_closest_m"] = _rms_max(eh_c)
    if len(run.progress):
        figs["final_progress"] = float(run.progress.v[-1, 0])

    # ground clearance
    zt = cl = hull = np.full(n, np.nan)
    terrain = getattr(mission, "terrain", None)
    if terrain is not None:
        probes = _hull_probes(mission, warnings)
        vals = np.array([_clearances(terrain, probes, xi) for xi in run.x])
        zt, cl, hull = vals[:, 0], vals[:, 1], vals[:, 2]
        clt, hullt = cl[tick], hull[tick]
        if np.isfinite(clt).any():
            k = int(np.nanargmin(clt))
            figs["min_clearance_m"] = float(clt[k])
            figs["min_clearance_t_s"] = float(run.t[tick][k])
        if np.isfinite(hullt).any():
            figs["min_hull_clearance_m"] = float(np.nanmin(hullt))
    elif len(run.altitude):
        a = run.altitude.v[:, 0]
        if np.isfinite(a).any():
            k = int(np.nanargmin(a))
            figs["min_altitude_m"] = float(a[k])
            figs["min_altitude_t_s"] = float(run.altitude.t[k])
        warnings.append("terrain unknown (give --mission): ground clearance from the altimeter (/bb2/altitude)")

    # trajectory
    x = run.x
    figs["mean_speed_m_s"] = float(np.mean(np.linalg.norm(x[:, 6:9], axis=1)))
    figs["max_depth_m"] = float(np.max(-x[:, 2]))
    figs["min_depth_m"] = float(np.min(-x[:, 2]))

    # commands and planes
    act = load_parameters().act
    lim = math.radians(float(act["plane_limit_deg"]))
    rate_lim = math.radians(float(act["plane_rate_deg_s"]))
    if len(run.rate_cmd):
        _signal_stats("q_c", run.rate_cmd.t, run.rate_cmd.col(0), figs, unit="rad_s")
        _signal_stats("r_c", run.rate_cmd.t, run.rate_cmd.col(1), figs, unit="rad_s")
    if len(run.vh_cmd):
        _signal_stats("dV", run.vh_cmd.t, run.vh_cmd.col(0), figs, unit="rad")
        _signal_stats("dH", run.vh_cmd.t, run.vh_cmd.col(1), figs, unit="rad")
    _planes_stats("planes_cmd", run.planes_cmd, figs, lim, None)
    _planes_stats("planes", run.planes, figs, lim, rate_lim)
    if len(run.prop_cmd):  # shaft speed in rev/s, the ROM's unit
        _signal_stats("propeller_cmd", run.prop_cmd.t, run.prop_cmd.col(0) / TWO_PI, figs, unit="rps",
                      limit=float(act["rps_limits"][1]))
    if len(run.prop):
        _signal_stats("propeller", run.prop.t, run.prop.col(0) / TWO_PI, figs, unit="rps",
                      limit=float(act["rps_limits"][1]))

    rtf, rtf_source = _real_time_factor(run)
    figs["real_time_factor"] = rtf
    if not math.isfinite(rtf):
        warnings.append("real-time factor unknown (no wall-clock publish times, no simulator status)")

    # maneuver
    maneuver = maneuver or run.custom_data.get("maneuver") or None
    man_figs = man_traj = None
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
            for k, v in man_figs.to_dict().items():
                if isinstance(v, tuple):
                    for i, vi in enumerate(v):
                        if isinstance(vi, (int, float)) and not isinstance(vi, bool):
                            figs[f"maneuver.{k}[{i}]"] = float(vi)
                elif isinstance(v, (int, float)) and not isinstance(v, bool):
                    figs[f"maneuver.{k}"] = float(v)

    a = Analysis(run=run, figures=figs, tick=tick, e_vertical=e_v, e_horizontal=e_h,
                 e_vertical_closest=np.asarray(ev_c, float), e_horizontal_closest=np.asarray(eh_c, float),
                 clearance=cl, hull_clearance=hull, terrain_z=zt, mission=mission, maneuver=maneuver,
                 maneuver_figures=man_figs, maneuver_traj=man_traj, warnings=warnings, rtf_source=rtf_source)
    return a


# ------------------------------------------------------------------------------------------ printing
_UNIT_SUFFIXES = (("_rps_s", "rev/s^2", 1.0), ("_rps", "rev/s", 1.0), ("_rad_s_s", "deg/s^2", RAD2DEG), ("_rad_s", "deg/s", RAD2DEG), ("_rad", "deg", RAD2DEG),
                  ("_m_s", "m/s", 1.0), ("_m", "m", 1.0), ("_s", "s", 1.0), ("_fraction", "%", 100.0))


def format_figure(name: str, value: float) -> tuple[str, str, str]:
    """(label, value text, unit) in display units: radians become degrees, fractions percent."""
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


def figure_lines(a: Analysis) -> list[str]:
    out = [f"{a.label}: {a.run.source}"]
    for w in a.warnings:
        out.append(f"  warning: {w}")
    for k, v in a.figures.items():
        label, text, unit = format_figure(k, v)
        out.append(f"  {label:<44s} {text:>12s} {unit}")
    return out


def compare(a: Analysis, b: Analysis) -> list[tuple[str, float, float, float]]:
    """(figure, value A, value B, B - A) for every figure of either run (NaN where one lacks it)."""
    names = list(a.figures) + [k for k in b.figures if k not in a.figures]
    out = []
    for k in names:
        va, vb = a.figures.get(k, math.nan), b.figures.get(k, math.nan)
        out.append((k, va, vb, vb - va if math.isfinite(va) and math.isfinite(vb) else math.nan))
    return out


def comparison_lines(a: Analysis, b: Analysis) -> list[str]:
    out = [f"comparison  A = {a.label}  B = {b.label}",
           f"  {'figure':<44s} {'A':>12s} {'B':>12s} {'B - A':>12s}"]
    for k, va, vb, d in compare(a, b):
        label, ta, unit = format_figure(k, va)
        _, tb, _ = format_figure(k, vb)
        _, td, _ = format_figure(k, d)
        out.append(f"  {label:<44s} {ta:>12s} {tb:>12s} {td:>12s} {unit}")
    return out


# ------------------------------------------------------------------------------------------ outputs
def write_outputs(analyses: Sequence[Analysis], out_dir: str | Path) -> dict[str, Path]:
    """PNG figures, figures.json and report.html into ``out_dir``; returns name -> file."""
    from bb2_tools import analysis_plots, report

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    files = analysis_plots.plot_analyses(analyses, out)
    doc = {a.label: {"source": str(a.run.source), "figures": a.figures, "warnings": a.warnings}
           for a in analyses}
    if len(analyses) == 2:
        doc["comparison"] = [{"figure": k, "A": va, "B": vb, "B_minus_A": d}
                             for k, va, vb, d in compare(analyses[0], analyses[1])]
    fj = out / "figures.json"
    fj.write_text(json.dumps(doc, indent=1, default=float, allow_nan=True))
    files["figures_json"] = fj
    files["report"] = report.write_analysis_report(analyses, files, out / "report.html")
    return files


def _parse(argv: Sequence[str]) -> argparse.Namespace:
    p = argparse.ArgumentParser(prog="bb2-analyze", description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("bags", nargs="+", type=Path, metavar="BAG",
                   help="bag directory or .mcap; a second BAG is overlaid and compared")
    p.add_argument("--out", type=Path, default=None, help="output directory (default <BAG>/analysis/)")
    p.add_argument("--mission", default=None, help="mission YAML (or shipped name) for the terrain and path")
    p.add_argument("--maneuver", default=None,
                   help="maneuver name (self-propulsion, depth-heading, turning-circle, hzz, vzz, open-loop)")
    p.add_argument("--maneuver-settings", default=None, help="JSON object of maneuver settings")
    p.add_argument("--label", action="append", default=None, help="label of each bag (repeat)")
    p.add_argument("--no-report", action="store_true", help="print the figures only")
    return p.parse_args(list(argv))


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``bb2-analyze``; returns the exit code (0 ok, 2 bad input)."""
    args = _parse(sys.argv[1:] if argv is None else argv)
    try:
        if len(args.bags) > 2:
            raise AnalysisError(f"give one or two bags, got {len(args.bags)}")
        labels = list(args.label or [])
        if len(labels) > len(args.bags):
            raise AnalysisError(f"{len(labels)} --label for {len(args.bags)} bag(s)")
        ms = None
        if args.maneuver_settings:
            try:
                ms = json.loads(args.maneuver_settings)
            except json.JSONDecodeError as exc:
                raise AnalysisError(f"--maneuver-settings is not JSON: {exc}") from None
            if not isinstance(ms, dict):
                raise AnalysisError("--maneuver-settings must be a JSON object")
        runs = []
        for i, b in enumerate(args.bags):
            label = labels[i] if i < len(labels) else None
            run = read_bag(b, label)
            if len(args.bags) == 2 and label is None:
                run.label = f"{'AB'[i]}: {run.label}"
            runs.append(run)
        analyses = [analyze(r, mission=args.mission, maneuver=args.maneuver, maneuver_settings=ms) for r in runs]
        if len(analyses) == 2 and analyses[0].label == analyses[1].label:
            analyses[1].run.label += " (2)"
    except (AnalysisError, BagError) as exc:
        print(f"bb2-analyze: error: {exc}", file=sys.stderr)
        return 2
    if len(analyses) == 2:
        for a in analyses:
            print(f"{a.label}: {a.run.source}" + "".join(f"\n  warning: {w}" for w in a.warnings))
        print("\n".join(comparison_lines(*analyses)))
    else:
        print("\n".join(figure_lines(analyses[0])))
    if not args.no_report:
        first = args.bags[0]
        out = args.out or ((first if first.is_dir() else first.parent / first.stem) / "analysis")
        files = write_outputs(analyses, out)
        print(f"bb2-analyze: report {files['report']} ({len(files) - 2} figures in {out})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
