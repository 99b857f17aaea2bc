"""Standard maneuvers of the BB2 ROM: settings (data), the maneuver logic, and the runner.

A maneuver is a set of defaults in ``data/maneuvers.yaml`` plus the channel logic below: the vertical
channel is flown by the authors' depth/pitch PID, a zig-zag, or imposed; the horizontal channel by the
heading PD, a zig-zag, a constant rudder, or imposed. Commands go through the X-plane mixer
(:func:`bb2_sim.xplane.plane_angles_deg`, dV = dv > 0 bow up, dH = dh > 0 bow to port) and then the ROM's
actuators. The run is logged every ``log_every`` steps with the columns of the reference CSVs.
"""
from __future__ import annotations

import csv
import math
from dataclasses import dataclass, field, fields, replace
from functools import lru_cache
from pathlib import Path
from typing import Any, Callable, Iterable, Mapping

import numpy as np

from .autopilot_v12 import V12Autopilot, autopilot_v12_gains
from .integrator import NonFiniteStateError, Simulator, StepRecord, check_substeps
from .model import BB2Model
from .names import did_you_mean
from .xplane import plane_angles_deg
from .yaml_files import load as load_yaml

DATA = Path(__file__).resolve().parent / "data" / "maneuvers.yaml"
RAD2DEG = 180.0 / math.pi

CSV_COLUMNS = [
    "t_s", "x_m", "y_m", "z_m", "phi_deg", "theta_deg", "psi_deg", "u_m_s", "v_m_s", "w_m_s",
    "p_deg_s", "q_deg_s", "r_deg_s", "U_m_s",
    "dX1_deg", "dX2_deg", "dX3_deg", "dX4_deg", "dX5_deg",
    "cmd_dX1_deg", "cmd_dX2_deg", "cmd_dX3_deg", "cmd_dX4_deg", "cmd_dX5_deg",
    "n_rps", "J", "KT", "KQ", "thrust_N", "thrust_deduction", "thrust_net_N", "torque_Nm", "dmass_kg",
]
"""Columns of the authors' reference runs (native frames, see REFERENCE.md): the maneuver CSV starts with them."""
SEA_COLUMNS = ["eta_cg_m"]
"""Columns after the reference ones: the free-surface elevation (m, z up) above the CG's horizontal position."""
OUTPUT_COLUMNS = CSV_COLUMNS + SEA_COLUMNS
"""Columns of the maneuver CSV (``bb2-sim maneuver --out``) and of :attr:`ManeuverResult.traj`."""


TRAJECTORY_ROW_BYTES = 1500
"""Memory of one logged row (every 0.1 s) while a maneuver runs: a list of ~34 Python floats and its numpy copy;
:func:`validate` refuses a duration whose trajectory would not fit in memory."""


class ManeuverError(ValueError):
    """Bad maneuver name or settings."""


@lru_cache(maxsize=1)
def _catalogue() -> dict:
    return load_yaml(DATA.read_text())["maneuvers"]


def maneuver_names() -> list[str]:
    return list(_catalogue())


@dataclass(frozen=True)
class ManeuverSettings:
    """Everything that defines a maneuver run (user units: depth m positive down, speed m/s ahead, deg, s)."""

    name: str
    depth: float
    speed_mps: float
    duration: float
    vertical: str
    horizontal: str
    depth_ref: float | None = None
    heading_ref_deg: float = 0.0
    rps: float | None = None
    sea_state: float = 0
    rudder_deg: float = 0.0
    amplitude_deg: float = 0.0
    check_deg: float = 0.0
    sail_planes: str = "zero"
    planes_deg: tuple[float, ...] = (0.0, 0.0, 0.0, 0.0, 0.0)
    profile: str = "iowa"
    propeller: str = "constant"   # constant (the authors' rps, default) | speed-pi (the root model's speed PI)
    doc: str = ""
    environment: Any = None       # a bb2_sim.environment.Environment (irregular sea, current); None: sea_state
    substeps: int = 1             # ROM ode3 steps per 0.05 s step (1: the authors'; bb2_sim.integrator)

    @property
    def zigzag(self) -> bool:
        """A zig-zag on either channel (its amplitude and check angle are read)."""
        return "zigzag" in (self.vertical, self.horizontal)

    @property
    def imposed(self) -> bool:
        """Every plane imposed (both channels ``imposed``: ``planes_deg`` is read)."""
        return self.vertical == "imposed" and self.horizontal == "imposed"

    @property
    def rps_command(self) -> float:
        """Propeller command: the given rps, else the authors' rule n = U/4."""
        if self.rps is not None:
            return float(self.rps)
        return self.speed_mps * float(autopilot_v12_gains()["rps_per_speed"])

    def expected_speed_mps(self) -> float:
        """The speed the run is expected to hold, m/s: its start, or the steady cruise of its constant propeller
        command when faster (:func:`step_stability.cruise_speed`; the speed PI holds the start)."""
        from .step_stability import cruise_speed

        return self.speed_mps if self.propeller != "constant" else max(self.speed_mps, cruise_speed(self.rps_command))

    @property
    def z_ref(self) -> float:
        return -(self.depth if self.depth_ref is None else self.depth_ref)

    def initial_state(self) -> np.ndarray:
        """[x y z phi theta psi u v w p q r] native: at the given depth, moving ahead at the given speed."""
        x0 = np.zeros(12)
        x0[2] = -self.depth
        x0[6] = -self.speed_mps
        return x0


def maneuver_settings(name: str, **overrides) -> ManeuverSettings:
    """Defaults of maneuver ``name`` with user overrides (None values are ignored); validated.

    ``sea`` and ``current``: a mission's ``sea:`` and ``current:`` blocks (mappings,
    :mod:`bb2_sim.environment`), for settings written as a document (a campaign's maneuver options): the
    maneuver then flies in that sea and current, as ``bb2-sim maneuver`` with the same sea and current options
    (:func:`with_sea`)."""
    cat = _catalogue()
    if name not in cat:
        raise ManeuverError(f"unknown maneuver {name!r}{did_you_mean(name, cat)} (choose from {', '.join(cat)})")
    d = dict(cat[name])
    d.update({k: v for k, v in overrides.items() if v is not None})
    sea_doc, current_doc = d.pop("sea", None), d.pop("current", None)
    known = {f.name for f in fields(ManeuverSettings)}
    bad = set(d) - known
    if bad:
        settable = sorted(known - {"name", "doc", "environment"} | {"sea", "current"})
        hints = [repr(b) + did_you_mean(b, settable) for b in sorted(bad)]
        raise ManeuverError(f"unknown maneuver setting(s): {', '.join(hints)}; known: {', '.join(settable)}")
    if "planes_deg" in d:
        d["planes_deg"] = tuple(float(v) for v in d["planes_deg"])
    from .environment import Environment

    if d.get("environment") is not None and not isinstance(d["environment"], Environment):
        raise ManeuverError(f"environment must be a bb2_sim.environment.Environment, got {d['environment']!r}: "
                            "in a document, give the sea and the current as sea: and current: blocks")
    s = ManeuverSettings(name=name, **d)
    if sea_doc is not None or current_doc is not None:
        if s.environment is not None:
            raise ManeuverError("give either an environment or sea: / current: blocks, not both")
        s = with_sea(s, sea_doc, current_doc, overrides.get("sea_state"))
    validate(s)
    return s


def with_sea(s: ManeuverSettings, sea: Mapping[str, Any] | None = None, current: Mapping[str, Any] | None = None,
             sea_state: float | None = None) -> ManeuverSettings:
    """``s`` flying in the sea and current of a mission's ``sea:`` / ``current:`` blocks (None: not given; both
    None: ``s`` as it is, in its sea state of the authors' table), as ``bb2-sim maneuver`` does with its sea and
    current options.  ``sea_state``: the one the user gave with the settings (None: the maneuver's default, which a
    sea block does not take): it goes into the sea block (a spectrum's Hs and Tp from the sea-state table), which
    may then name no other.  A current alone flies in the maneuver's sea state.  :class:`ManeuverError` for a bad
    block, naming its key."""
    if sea is None and current is None:
        return s
    from .environment import Environment, current_from_mapping, sea_from_mapping
    from .sea import SeaInputError

    block: Any = {"sea_state": s.sea_state}
    if sea is not None:
        block = sea
        if sea_state is not None and isinstance(sea, Mapping):
            if sea.get("sea_state", sea_state) != sea_state:
                raise ManeuverError(f"sea_state {sea_state:g} and sea.sea_state {sea['sea_state']!r}: give one")
            block = {**sea, "sea_state": sea_state}
    try:
        env = Environment(sea_from_mapping(block), current_from_mapping(current))
    except SeaInputError as e:
        raise ManeuverError(str(e)) from None
    return replace(s, environment=env, sea_state=env.sea.sea_state if env.sea.authors_table else 0)


def inapplicable_settings(s: ManeuverSettings, given: Iterable[str]) -> list[str]:
    """The settings among ``given`` (the ones a user set) that maneuver ``s`` does not read with its channels, in
    the order given: a rudder for a zig-zag, an amplitude for a turning circle, imposed planes for anything but
    ``open-loop``, a heading reference without the heading autopilot, a depth reference without the depth PID.
    They would be ignored without a word; the CLIs refuse them."""
    reads = {"rudder_deg": s.horizontal == "rudder", "amplitude_deg": s.zigzag, "check_deg": s.zigzag,
             "planes_deg": s.imposed,
             "sail_planes": s.vertical == "zigzag", "heading_ref_deg": s.horizontal == "pd",
             "depth_ref": s.vertical == "pid" or (s.vertical == "zigzag" and s.sail_planes == "pid")}
    return [k for k in given if not reads.get(k, True)]


def channels(s: ManeuverSettings) -> str:
    """``vertical pid, horizontal rudder``: how maneuver ``s`` flies, for messages."""
    return f"vertical {s.vertical}, horizontal {s.horizontal}"


def _largest(planes_deg) -> float:
    return float(np.max(np.abs(planes_deg)))


def saturation_warning(s: ManeuverSettings, plane_limit_deg: float) -> str:
    """Before a run: '' or one line saying that the maneuver's own plane command (its rudder, its zigzag amplitude,
    its imposed planes) deflects a plane beyond ``plane_limit_deg``, where the actuators stop it, as the authors'
    model does: the run is then that of the limit, not of the command asked for.  (The autopilot's own share of
    the planes, e.g. the depth PID's in a turning circle, comes on top and is not foreseen here.)"""
    asked: list[tuple[str, float]] = []  # (the setting as given, the largest plane deflection it asks for)
    if s.horizontal == "rudder":
        asked.append((f"its rudder of {s.rudder_deg:g} deg", _largest(plane_angles_deg(0.0, s.rudder_deg))))
    if s.zigzag:
        dv, dh = (s.amplitude_deg, 0.0) if s.vertical == "zigzag" else (0.0, s.amplitude_deg)
        asked.append((f"its zigzag amplitude of {s.amplitude_deg:g} deg", _largest(plane_angles_deg(dv, dh))))
    if s.imposed:
        asked.append((f"its imposed planes {','.join(f'{d:g}' for d in s.planes_deg)} deg",
                      _largest(s.planes_deg)))
    over = [(what, deg) for what, deg in asked if deg > plane_limit_deg + 1e-9]
    if not over:
        return ""
    what, deg = over[0]
    return (f"maneuver {s.name}: the planes are asked for up to {deg:g} deg ({what}), beyond their limit of "
            f"{plane_limit_deg:g} deg, where they stop: the run is that of the limit, not of the command")


def validate(s: ManeuverSettings) -> None:
    """Raise :class:`ManeuverError` with one clear message for any bad setting."""
    numeric = {"depth": s.depth, "speed_mps": s.speed_mps, "duration": s.duration,
               "heading_ref_deg": s.heading_ref_deg, "sea_state": s.sea_state, "rudder_deg": s.rudder_deg,
               "amplitude_deg": s.amplitude_deg, "check_deg": s.check_deg}
    if s.depth_ref is not None:
        numeric["depth_ref"] = s.depth_ref
    if s.rps is not None:
        numeric["rps"] = s.rps
    for k, v in numeric.items():
        if not isinstance(v, (int, float)) or not math.isfinite(v):
            raise ManeuverError(f"{k} must be a finite number, got {v!r}")
    if len(s.planes_deg) != 5:
        raise ManeuverError(f"--planes-deg needs exactly 5 angles d1,d2,d3,d4,d5 (got {len(s.planes_deg)})")
    try:
        check_substeps(s.substeps)
    except ValueError as e:
        raise ManeuverError(str(e)) from None
    if not all(math.isfinite(v) for v in s.planes_deg):
        raise ManeuverError(f"plane angles must be finite, got {list(s.planes_deg)}")
    if s.duration <= 0:
        raise ManeuverError(f"duration must be positive, got {s.duration}")
    if s.depth < 0:
        raise ManeuverError(f"initial depth {s.depth:g} m is above the calm surface (depth is positive down)")
    try:
        from .outputs import check_fits_in_memory

        check_fits_in_memory(s.duration / (2 * 0.05) * TRAJECTORY_ROW_BYTES, f"a {s.duration:g} s trajectory")
    except MemoryError as e:
        raise ManeuverError(f"duration {s.duration:g} s: {e}; fly a shorter maneuver") from None
    if s.rps is not None and s.rps < 0:
        raise ManeuverError(f"rps must be >= 0, got {s.rps}")
    if s.vertical not in ("pid", "zigzag", "imposed") or s.horizontal not in ("pd", "zigzag", "rudder", "imposed"):
        raise ManeuverError(f"unknown channel logic vertical={s.vertical!r} horizontal={s.horizontal!r}")
    if s.propeller not in ("constant", "speed-pi"):
        raise ManeuverError(f"propeller must be 'constant' or 'speed-pi', got {s.propeller!r}")
    if s.sail_planes not in ("zero", "pid"):
        raise ManeuverError(f"sail planes must be 'pid' or 'zero', got {s.sail_planes!r}")
    if s.zigzag and (s.amplitude_deg <= 0 or s.check_deg <= 0):
        raise ManeuverError("zig-zags need --amplitude-deg > 0 and --check-deg > 0")
    if s.environment is not None and s.sea_state not in (0, None) and not s.environment.sea.authors_table:
        raise ManeuverError("give either a sea state (the authors' table) or a spectrum sea, not both")


class ZigZag:
    """Zig-zag command +-A switched at the first major step where the monitored angle reaches +-C."""

    def __init__(self, amplitude_deg: float, check_deg: float):
        self.A, self.C = float(amplitude_deg), float(check_deg)
        self.sign = 1.0
        self.reversals: list[float] = []

    def step(self, t: float, angle_deg: float) -> float:
        if self.sign > 0 and angle_deg >= self.C:
            self.sign = -1.0
            self.reversals.append(t)
        elif self.sign < 0 and angle_deg <= -self.C:
            self.sign = 1.0
            self.reversals.append(t)
        return self.sign * self.A


class ManeuverCommander:
    """Per major step: state -> five plane commands (deg, authors' plane signs) and the rps command."""

    def __init__(self, s: ManeuverSettings):
        self.s = s
        self.autopilot = V12Autopilot(z_ref=s.z_ref, psi_ref=math.radians(s.heading_ref_deg))
        self.zigzag = ZigZag(s.amplitude_deg, s.check_deg) if s.zigzag else None
        self.speed_pi = None
        if s.propeller == "speed-pi":
            from .profiles import get_profile
            from .speed_control import SpeedPI
            self.speed_pi = SpeedPI(-s.speed_mps, get_profile(s.profile).speed_pi_feedforward)

    def step(self, t: float, x: np.ndarray) -> tuple[np.ndarray, float]:
        s = self.s
        rps = self.speed_pi.step(x[6]) if self.speed_pi else s.rps_command
        if s.imposed:
            return np.array(s.planes_deg, dtype=float), rps
        dv_pid, dh_pd = self.autopilot.step(x[2], x[4], x[5])
        dv, dh = dv_pid, dh_pd
        if s.vertical == "zigzag":
            dv = self.zigzag.step(t, x[4] * RAD2DEG)
        if s.horizontal == "zigzag":
            dh = self.zigzag.step(t, x[5] * RAD2DEG)
        elif s.horizontal == "rudder":
            dh = -s.rudder_deg
        planes = plane_angles_deg(dv, dh)
        if s.vertical == "zigzag":
            planes[4] = dv_pid if s.sail_planes == "pid" else 0.0
        return planes, rps


def model_sea(model: BB2Model):
    """The model's sea as a :class:`bb2_sim.sea.sea.Sea` (``elevation(x, y, t)`` on arrays of native earth
    points), or None when it is calm."""
    if model.sea is not None:
        return model.sea
    if model.wave.calm:
        return None
    from .sea.sea import AuthorsTableSea
    return AuthorsTableSea(model.wave, model.params.g)


def surface_elevation(model: BB2Model, x_earth: float, y_earth: float, t: float) -> float:
    """Free-surface elevation (m, z up) of the model's sea at the earth point (x, y) at time t."""
    sea = model_sea(model)
    return 0.0 if sea is None else float(sea.elevation(x_earth, y_earth, t))


def record_row(rec: StepRecord, model: BB2Model) -> list[float]:
    """One CSV row (OUTPUT_COLUMNS) from a major-step record."""
    x = rec.x
    P = model.params
    prop = rec.ev.prop
    n = rec.act.rps
    thrust_ow = prop.KT * P.rho * n * n * P.prop_D ** 4
    return [rec.t, x[0], x[1], x[2], x[3] * RAD2DEG, x[4] * RAD2DEG, x[5] * RAD2DEG, x[6], x[7], x[8],
            x[9] * RAD2DEG, x[10] * RAD2DEG, x[11] * RAD2DEG, math.sqrt(x[6] ** 2 + x[7] ** 2 + x[8] ** 2),
            *rec.act.planes_deg, *rec.commands_planes_deg, n, prop.J, prop.KT, prop.KQ, thrust_ow, prop.t,
            (1.0 - prop.t) * thrust_ow, prop.torque, rec.act.dmass_kg,
            surface_elevation(model, x[0], x[1], rec.t)]


@dataclass
class ManeuverResult:
    settings: ManeuverSettings
    traj: dict[str, np.ndarray]
    error: NonFiniteStateError | None = None
    reversals: list[float] = field(default_factory=list)
    wall_time_s: float = 0.0

    @property
    def completed(self) -> bool:
        return self.error is None

    def divergence_hint(self, substeps_option: str) -> str:
        """'' or what to change after a divergence: more ROM sub-steps for a boat fast enough for the step to be
        unstable (:func:`step_stability.substeps_hint`, naming ``substeps_option``), or a profile that starts from
        rest for a run that started at rest (:func:`profiles.at_rest_hint`)."""
        if self.error is None:
            return ""
        from .profiles import at_rest_hint
        from .step_stability import substeps_hint

        s = self.settings
        return (substeps_hint(self.traj["t_s"], self.traj["U_m_s"], s.substeps, substeps_option, s.expected_speed_mps())
                or at_rest_hint(s.profile, s.speed_mps, getattr(self.error, "t", math.inf)))


class CsvWriter:
    """Writes CSV rows as they come (flushed), so a diverged or interrupted run keeps what it had."""

    def __init__(self, path: str | Path, columns: list[str] = OUTPUT_COLUMNS):
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._fh = open(self.path, "w", newline="")
        self._w = csv.writer(self._fh)
        self._w.writerow(columns)

    def write(self, row: Iterable[float]) -> None:
        try:
            self._w.writerow([f"{v:.12g}" for v in row])
            self._fh.flush()
        except OSError as e:  # a full device: the error names the file (exit 2, one line)
            raise OSError(e.errno, e.strerror, str(self.path)) from None

    def close(self) -> None:
        try:
            self._fh.close()
        except OSError as e:
            raise OSError(e.errno, e.strerror, str(self.path)) from None


def check_initial_depth(s: ManeuverSettings, model: BB2Model) -> None:
    """Refuse a start with the sail top above the calm surface (CG depth < the sail's height above the CG, the
    broaching definition of a mission): the ROM would fly in the air."""
    top = model.surfaces.sail_top_m()
    if s.depth < top:
        raise ManeuverError(f"initial depth {s.depth:g} m puts the sail top {top - s.depth:.2f} m above the calm "
                            f"surface (the sail top is {top:.2f} m above the CG): give --depth >= {top:.2f}")


def build_model(s: ManeuverSettings, hull_mesh: str | None = None, trim_to_buoyancy: bool | None = None) -> BB2Model:
    """The ROM of maneuver ``s``: the authors' sea-state table, or the settings' environment (sea, current)."""
    if s.environment is None:
        return BB2Model(hull_mesh, profile=s.profile, sea_state=s.sea_state, trim_to_buoyancy=trim_to_buoyancy)
    from .parameters import load_parameters
    return BB2Model(hull_mesh, profile=s.profile, trim_to_buoyancy=trim_to_buoyancy,
                    **s.environment.model_kwargs(load_parameters()))


def run_maneuver(s: ManeuverSettings, model: BB2Model | None = None, *, hull_mesh: str | None = None,
                 log_every: int = 2, on_row: Callable[[list[float]], None] | None = None,
                 progress: Callable[[float], None] | None = None) -> ManeuverResult:
    """Fly maneuver ``s``; log every ``log_every`` steps (0.1 s). Stops at the first non-finite state."""
    import time

    model = model or build_model(s, hull_mesh)
    sim = Simulator(model, s.initial_state(), substeps=s.substeps)
    cmd = ManeuverCommander(s)
    n_steps = int(round(s.duration / sim.h))
    rows: list[list[float]] = []
    err = None
    t0 = time.perf_counter()
    for k in range(n_steps + 1):
        x = sim.x
        planes, rps = cmd.step(sim.t, x)
        try:
            rec = sim.step(planes, rps)
        except NonFiniteStateError as e:
            err = e
            break
        if k % log_every == 0:
            row = record_row(rec, model)
            rows.append(row)
            if on_row:
                on_row(row)
        if progress and k % 200 == 0:
            progress(rec.t)
    arr = np.array(rows) if rows else np.zeros((0, len(OUTPUT_COLUMNS)))
    traj = {c: arr[:, i] for i, c in enumerate(OUTPUT_COLUMNS)}
    reversals = cmd.zigzag.reversals if cmd.zigzag else []
    return ManeuverResult(s, traj, err, list(reversals), time.perf_counter() - t0)
