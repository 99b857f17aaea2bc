"""A recorded BB2 run read from a bag into typed series: :class:`BagRun` (of :class:`Series`), :func:`read_bag`.

``BAG`` is a rosbag2 bag directory (metadata.yaml + .mcap, ours or any rosbag2 MCAP with the contract's
topics) or a bare ``.mcap``.  A bag whose recorder was killed (no summary) is read up to its last complete
chunk, and the run's warnings say so.

What is read (contract topics of :mod:`bb2_msgs_py.contract`, decoded with the standard deserialisers --
``rclpy.serialization`` with the installed message classes, else ``mcap_ros2`` from the bag's own schemas --
and converted with the contract's conversions, :mod:`bb2_msgs_py.conversions`):

* the trajectory from ``/bb2/state_native`` (exact float64 ROM state) or, when absent, ``/bb2/odom``
  converted back to native (psi unwrapped);
* the path from ``/bb2/path/bernstein`` (exact control points) or, when absent, the ``/bb2/path`` samples;
* ``/bb2/guidance/path_error`` (the stack's own path errors p_T), ``rate_cmd``, ``vh_cmd``, plane and
  propeller commands and states, ``/bb2/altitude``, ``/bb2/mission/progress``, ``/bb2/status``.

Messages are keyed by their header stamp (integer nanoseconds; ``/bb2/mission/progress``, a bare
``Float64``, by its log time); a stamp seen twice is kept once (the first received).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, NamedTuple, Sequence

import numpy as np

from bb2_tools.bagfile import BagError, BagReader, Gap, bag_gaps, gaps_by_topic

__all__ = ["AnalysisError", "Series", "StatusEntry", "BagRun", "read_bag", "USED_TOPICS"]

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
T_NAV = "/bb2/nav/state_native"
USED_TOPICS = (T_STATE, T_ODOM, T_BERNSTEIN, T_PATH, T_PATH_ERROR, T_RATE, T_VH, T_PLANES_CMD, T_PLANES,
               T_PROP_CMD, T_PROP, T_ALT, T_PROGRESS, T_STATUS, T_NAV)


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


class StatusEntry(NamedTuple):
    """One ``diagnostic_msgs/DiagnosticStatus`` of a ``/bb2/status`` message."""

    t_s: float                             #: s, the message's header stamp
    name: str                              #: e.g. "bb2/simulator"
    values: dict[str, str]                 #: its key -> value pairs


@dataclass
class BagRun:
    """What a bag holds, decoded: the native trajectory, the path, commands and bookkeeping."""

    source: Path                           #: the bag directory or .mcap given
    label: str                             #: the run's name in printouts (default: the bag's name)
    topics: dict[str, str]                 #: topic -> type name, every topic of the bag
    counts: dict[str, int]                 #: topic -> number of readable messages
    truncated: bool                        #: no summary (recorder killed): read up to the last complete chunk
    problem: str                           #: what ended a truncated file ("" if none)
    custom_data: dict[str, str]            #: metadata.yaml custom_data (mission_file, maneuver, ...)
    state_source: str                      #: "state_native" | "odometry"
    t: np.ndarray                          #: s, state times (sorted, unique)
    x: np.ndarray                          #: (n, 12) native state [x y z phi theta psi u v w p q r]
    state_publish_ns: np.ndarray           #: DDS source timestamps of the states (wall clock, ns)
    path: Any = None                       #: BernsteinPath in the native frame (exact), or None
    path_samples: np.ndarray | None = None  #: (m, 3) native samples of the path
    path_source: str = ""                  #: topic the path comes from ("" if none)
    path_error: Series = field(default_factory=lambda: Series.empty(3))    #: m, path frame (along, left, up)
    rate_cmd: Series = field(default_factory=lambda: Series.empty(2))      #: rad/s native (q_c, r_c)
    vh_cmd: Series = field(default_factory=lambda: Series.empty(2))        #: rad (delta_V, delta_H)
    planes_cmd: Series = field(default_factory=lambda: Series.empty(5))    #: rad
    planes: Series = field(default_factory=lambda: Series.empty(5))        #: rad (actual)
    prop_cmd: Series = field(default_factory=lambda: Series.empty(1))      #: rad/s
    prop: Series = field(default_factory=lambda: Series.empty(1))          #: rad/s (actual)
    altitude: Series = field(default_factory=lambda: Series.empty(1))      #: m (NaN: no bottom in range)
    progress: Series = field(default_factory=lambda: Series.empty(1))      #: 1
    #: the navigation estimate the controllers flew on (navigation: sensors), native x12; empty on the truth
    nav_state: Series = field(default_factory=lambda: Series.empty(12))
    status: list[StatusEntry] = field(default_factory=list)  #: every status, in bag order
    warnings: list[str] = field(default_factory=list)
    #: messages lost before they reached the recorder (:func:`bb2_tools.bagfile.bag_gaps`); None: the bag
    #: cannot tell (no publication sequence numbers: another recorder's bag)
    gaps: list[Gap] | None = None

    stamps_ns: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))  #: ns of the states

    def status_value(self, key: str, name_prefix: str = "") -> str | None:
        """The last value of a ``/bb2/status`` key (from statuses whose name starts with the prefix)."""
        for st in reversed(self.status):
            if st.name.startswith(name_prefix) and key in st.values:
                return st.values[key]
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


def read_bag(path: str | Path, label: str | None = None, vehicle: str | None = None) -> BagRun:
    """Decode the contract topics of a bag (see the module docstring); :class:`AnalysisError` if unusable.
    ``vehicle``: one boat of a fleet's bag (:class:`BagReader`); a fleet's bag of one boat is read as that boat."""
    from bb2_msgs_py import conversions as cv

    p = Path(path)
    if not p.exists():
        raise AnalysisError(f"no bag at {p} (expected a bag directory or a .mcap file)")
    try:
        reader = BagReader(p, vehicle)
        if vehicle is None and T_STATE not in reader.topics and T_ODOM not in reader.topics:
            if len(reader.vehicles) == 1:
                reader = BagReader(p, reader.vehicles[0])
            elif reader.vehicles:
                raise AnalysisError(f"{p}: a fleet's bag ({', '.join(reader.vehicles)}): read one vehicle at a time")
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
    status: list[StatusEntry] = []
    base_link = reader.vehicle_base_link()  # boat1/base_link in a fleet boat's bag
    for m in reader.raw_messages(wanted):
        try:
            msg = decode(m.type, m.data)
            if m.topic == T_STATE:
                s = cv.state_native_from_message(msg)
                ns = cv.seconds_to_ns(s.t)
                rows[T_STATE].append((ns, [s.t, *s.as_vector()]))
                state_pub.setdefault(ns, m.publish_time_ns)
            elif m.topic == T_NAV:
                s = cv.state_native_from_message(msg)
                rows[T_NAV].append((cv.seconds_to_ns(s.t), list(s.as_vector())))
            elif m.topic == T_ODOM:
                s = cv.odometry_to_state(msg, child_frame_id=base_link)
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
                rows[m.topic].append((_stamp_ns(msg), cv.rate_command_from_message(msg, frame_id=base_link)))
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
                    status.append(StatusEntry(_stamp_ns(msg) * 1e-9, str(st.name),
                                              {kv.key: kv.value for kv in st.values}))
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
        source=p, label=label or reader.vehicle or (p.name if p.is_dir() else p.stem), topics=topics,
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
        progress=_series(rows[T_PROGRESS], 1), status=status, warnings=warnings,
        nav_state=_series(rows[T_NAV], 12))
    if reader.metadata is None and p.is_dir():
        run.warnings.append("no metadata.yaml beside the .mcap (bag not finished; `bagfile.recover` repairs it)")
    try:
        run.gaps = bag_gaps(reader)
    except BagError as exc:
        run.warnings.append(f"cannot tell whether the recording has gaps: {exc}")
    run.warnings.extend(gap_warnings(run.gaps, state_topic=src, used=wanted))
    if run.gaps is None:
        run.warnings.extend(state_hole_warnings(run.t, src))
    return run


def gap_warnings(gaps: Sequence[Gap] | None, *, state_topic: str, used: Sequence[str]) -> list[str]:
    """One warning per topic with recording gaps: every gap (where, in log time, and how long; how many
    messages), and whether the figures are affected (the state topic: they are computed over the ticks that
    remain; another topic they use: its statistics are over the samples that remain; else not affected)."""
    out = []
    for topic_name, gs in gaps_by_topic(gaps or ()).items():
        if topic_name == state_topic:
            affect = "the figures are affected: computed over the ticks that remain"
        elif topic_name in used:
            affect = f"figures from {topic_name} are affected: computed over the samples that remain"
        else:
            affect = "not used by the figures: they are not affected"
        where = "; ".join(_where(g) for g in gs)
        out.append(f"recording gap(s) on {topic_name}: {len(gs)} gap(s), {sum(g.missing for g in gs)} message(s) "
                   f"lost before reaching the recorder ({affect}): {where}")
    return out


def _where(g: Gap) -> str:
    """Where a gap is, in log time, for a warning."""
    if g.unrecorded:
        return (f"{g.missing} published and never recorded, " +
                ("none recorded at all" if g.after_log_s is None else f"after t = {g.after_log_s:.3f} s") +
                f" (its publishers counted {g.before_sequence}; the bag ends at t = {g.before_log_s:.3f} s)")
    if g.head:
        return f"the first {g.missing}, before t = {g.before_log_s:.3f} s"
    if f"{g.after_log_s:.3f}" == f"{g.before_log_s:.3f}":  # a stalled recorder logged both at its resume time
        return (f"{g.missing} at t = {g.after_log_s:.3f} s of log time (the recorder's clock stood still meanwhile; "
                f"published over {g.duration_s:.3f} s of wall time)")
    return (f"{g.missing} between t = {g.after_log_s:.3f} s and {g.before_log_s:.3f} s (published over "
            f"{g.duration_s:.3f} s of wall time)")


def state_hole_warnings(t: np.ndarray, state_topic: str) -> list[str]:
    """Holes in the state's time grid (steps more than 1.5 times the median apart), for bags that cannot tell
    their gaps from sequence numbers."""
    if len(t) < 3:
        return []
    dt = np.diff(t)
    h = float(np.median(dt))
    holes = np.flatnonzero(dt > 1.5 * h)
    if not len(holes):
        return []
    where = "; ".join(f"t = {t[k]:.3f} .. {t[k + 1]:.3f} s" for k in holes[:20]) + (
        f"; and {len(holes) - 20} more" if len(holes) > 20 else "")
    return [f"{state_topic} has {len(holes)} hole(s) in its {h:g} s time grid (the figures are computed over the "
            f"ticks that remain): {where}"]
