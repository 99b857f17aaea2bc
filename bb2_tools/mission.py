"""Closed-loop missions without ROS: ROM + Bernstein path + guidance/autopilot stack + terrain checks.

A mission is a YAML file (format below) loaded by :func:`load_mission` into a :class:`Mission`.
:func:`mission_components` builds everything a run needs -- the ROM, the simulator at its initial state,
the control stack and the hull probes for the terrain checks -- and is **the** constructor shared by the
in-process :class:`MissionRunner` and the ROS 2 nodes, so both worlds start from identical objects.

The tick (``Ts = 0.05 s``, the ROM's major step), which a ROS graph in lockstep reproduces exactly::

    state_n = VehicleState.from_vector(sim.t, sim.x)        # simulator -> odometry (native frames)
    out_n   = stack.step(state_n)                            # guidance -> L1 + autopilot -> mixer
    rec_n   = sim.step(out_n.planes_deg, out_n.rps)          # ROM ode3 step, commands held over [t_n, t_n+1)

The terrain checks (grounding, broaching) look at ``state_n`` before the ROM step; they never feed back
into the loop, so a ROS graph that omits them still produces the same trajectory.

Mission file (YAML; every key optional except ``path``; unknown keys are an error)::

    name: canyon                       # default: file stem
    description: free text
    extends: other.yaml                # start from another mission file (nested mappings merge)
    path: synthetic_canyon             # shipped path name, a path file (relative to this file), or an
                                       # inline path document (bb2_planner.paths format)
    stack: rate_2022                   # stack name, stack file, or inline stack mapping (``base: ...``)
    adaptation: true                   # L1 adaptation on/off (overrides the stack's own setting)
    terrain: synthetic_canyon          # none | synthetic_canyon | grid file (.npz / .csv, native frame)
    initial:                           # default: on the path start, along its tangent, at the path speed
      position_m: [x, y, z]            #   in ``frame`` (native | controller | enu | ned)
      frame: native
      offset_m: [dx, dy, dz]           #   added to the position, native frame
      heading_deg: 0.0                 #   native psi (0: bow along -x; > 0 bow to port)
      pitch_deg: 0.0                   #   native theta (> 0 bow up)
      speed_mps: 4.78                  #   forward speed (> 0 ahead)
    rps: null                          # null: the stack's feed-forward; a number (rev/s); or
                                       # path_mean_speed: the stack's rule n = v/advance with v = L/Tf
    duration_s: null                   # null: Tf * (1 + duration_margin)
    duration_margin: 0.2
    sea_state: 0
    profile: iowa                      # iowa | corrected
    hull: null                         # null: hull generated from the offsets; or a surface directory
    limits:
      min_hull_clearance_m: 0.0        # grounding: lowest hull point this close to the terrain (vertical)
      max_cg_z_m: null                 # broaching: CG above this z (null: sail top reaches the calm surface)

Clearances are **vertical** (``p_z - z_terrain(p_x, p_y)``, native frame, metres), as in
:mod:`bb2_planner.terrain`: the CG clearance is the paper's "50 m above the bottom"; the hull clearance is
the minimum over probe points (the convex-hull vertices of the hull surfaces, thinned) placed with the
vehicle's attitude, so a pitched bow or a canyon wall under the beam counts.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Callable, Mapping

import numpy as np
import yaml

from bb2_control.errors import ControlConfigError, UnknownStackError
from bb2_planner.bernstein import BernsteinPath, PathError, frame_matrix_to_native
from bb2_planner.terrain import PathBelowTerrainError, Terrain, TerrainError, TerrainOutOfBoundsError

__all__ = [
    "MissionError", "InitialState", "Limits", "Mission", "MissionComponents", "MissionStep", "MissionEvent",
    "MissionSummary", "MissionResult", "MissionRunner", "HullProbes", "MISSION_COLUMNS", "MISSIONS_DIR",
    "load_mission", "mission_from_dict", "mission_components", "stack_overrides", "initial_state", "run_mission",
    "read_mission_csv", "path_errors_closest", "terrain_elevation",
]

MISSIONS_DIR = Path(__file__).resolve().parents[1] / "missions"
RAD2DEG = 180.0 / math.pi
RPS_PATH_MEAN_SPEED = "path_mean_speed"
_TOP_KEYS = {"name", "description", "extends", "path", "stack", "adaptation", "terrain", "initial", "rps",
             "duration_s", "duration_margin", "sea_state", "profile", "hull", "limits", "format"}
_INITIAL_KEYS = {"position_m", "frame", "offset_m", "heading_deg", "pitch_deg", "speed_mps"}
_LIMIT_KEYS = {"min_hull_clearance_m", "max_cg_z_m"}
FORMAT = "bb2_tools.mission/1"


class MissionError(ValueError):
    """A mission file or setting is wrong (one clear message naming the file and the fault)."""


# ------------------------------------------------------------------------------------------ data
@dataclass(frozen=True)
class InitialState:
    """Initial conditions; None = from the path start (position, tangent heading/pitch, path speed)."""

    position_native: tuple[float, float, float] | None = None   #: m, native earth frame (z up)
    offset_native: tuple[float, float, float] = (0.0, 0.0, 0.0)  #: m, added to the position
    heading_deg: float | None = None                             #: native psi, deg
    pitch_deg: float | None = None                               #: native theta, deg (> 0 bow up)
    speed_mps: float | None = None                               #: forward speed, m/s (> 0 ahead)


@dataclass(frozen=True)
class Limits:
    """When a mission stops as failed."""

    min_hull_clearance_m: float = 0.0     #: grounding below this hull clearance (vertical), m
    max_cg_z_m: float | None = None       #: broaching above this CG z (native, z up), m; None = sail top at 0


@dataclass(frozen=True)
class Mission:
    """A validated mission.  ``path`` is the loaded Bernstein path (its own frame), ``terrain`` the loaded
    grid (or None); ``*_source`` say where they came from."""

    name: str
    path: BernsteinPath
    path_source: str
    stack: str | Mapping[str, Any] = "rate_2022"
    adaptation: bool = True
    terrain: Terrain | None = field(default=None, repr=False, compare=False)
    terrain_source: str | None = None
    initial: InitialState = InitialState()
    rps: float | str | None = None
    duration_s: float | None = None
    duration_margin: float = 0.2
    sea_state: float = 0
    profile: str = "iowa"
    hull: str | None = None
    limits: Limits = Limits()
    description: str = ""
    source_file: Path | None = None

    @property
    def duration(self) -> float:
        """Simulated time limit, s: ``duration_s`` or Tf * (1 + duration_margin)."""
        if self.duration_s is not None:
            return float(self.duration_s)
        return float(self.path.span * (1.0 + self.duration_margin))

    def with_adaptation(self, on: bool) -> "Mission":
        """Same mission with the L1 adaptation switched on or off."""
        return replace(self, adaptation=bool(on), name=self.name if on else _no_adapt_name(self.name))


def _no_adapt_name(name: str) -> str:
    return name if name.endswith("_no_adaptation") else f"{name}_no_adaptation"


# ------------------------------------------------------------------------------------------ loading
def _check_finite(doc: Any, where: str) -> None:
    """Reject NaN/inf anywhere in a parsed document, naming the key."""
    if isinstance(doc, bool):
        return
    if isinstance(doc, float) and not math.isfinite(doc):
        raise MissionError(f"{where} must be finite, got {doc!r}")
    if isinstance(doc, Mapping):
        for k, v in doc.items():
            _check_finite(v, f"{where}.{k}" if where else str(k))
    elif isinstance(doc, (list, tuple)):
        for i, v in enumerate(doc):
            _check_finite(v, f"{where}[{i}]")


def _number(v: Any, what: str, *, positive: bool = False, nonneg: bool = False) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise MissionError(f"{what} must be a number, got {v!r}")
    x = float(v)
    if not math.isfinite(x):
        raise MissionError(f"{what} must be finite, got {v!r}")
    if positive and x <= 0:
        raise MissionError(f"{what} must be > 0, got {v!r}")
    if nonneg and x < 0:
        raise MissionError(f"{what} must be >= 0, got {v!r}")
    return x


def _vec3(v: Any, what: str) -> tuple[float, float, float]:
    if not isinstance(v, (list, tuple)) or len(v) != 3:
        raise MissionError(f"{what} must be a list of 3 numbers [x, y, z], got {v!r}")
    return tuple(_number(c, f"{what}[{i}]") for i, c in enumerate(v))  # type: ignore[return-value]


def _read_yaml(file: Path) -> dict[str, Any]:
    try:
        doc = yaml.safe_load(file.read_text())
    except OSError as e:
        raise MissionError(f"{file}: cannot read mission file ({e.strerror})") from None
    except yaml.YAMLError as e:
        raise MissionError(f"{file}: not valid YAML ({e})") from None
    if not isinstance(doc, dict):
        raise MissionError(f"{file}: expected a mapping of mission settings, got {type(doc).__name__}")
    return doc


def _merge(base: Mapping[str, Any], over: Mapping[str, Any]) -> dict[str, Any]:
    out = dict(base)
    for k, v in over.items():
        out[k] = _merge(out[k], v) if isinstance(v, Mapping) and isinstance(out.get(k), Mapping) else v
    return out


def _resolve_file(value: str, base_dir: Path | None) -> Path | None:
    """A relative file is looked up beside the mission file first, then in the working directory."""
    p = Path(value).expanduser()
    if not p.is_absolute() and base_dir is not None and (base_dir / p).exists():
        return base_dir / p
    return p if p.exists() else None


def _load_path_spec(spec: Any, base_dir: Path | None) -> tuple[BernsteinPath, str]:
    from bb2_planner.paths import load_path, path_from_dict

    if isinstance(spec, Mapping):
        return path_from_dict(dict(spec), where="inline path"), "inline"
    if not isinstance(spec, str) or not spec:
        raise MissionError(f"path must be a shipped path name, a path file or an inline path, got {spec!r}")
    f = _resolve_file(spec, base_dir) if Path(spec).suffix in (".json", ".yaml", ".yml") else None
    return load_path(f if f is not None else spec), spec


def _load_terrain(spec: Any, base_dir: Path | None) -> tuple[Terrain | None, str | None]:
    from bb2_planner.terrain import synthetic_canyon

    if spec is None or (isinstance(spec, str) and spec.lower() == "none"):
        return None, None
    if not isinstance(spec, str):
        raise MissionError(f"terrain must be 'none', 'synthetic_canyon' or a .npz/.csv grid file, got {spec!r}")
    if spec == "synthetic_canyon":
        return synthetic_canyon().terrain, spec
    suffix = Path(spec).suffix.lower()
    if suffix not in (".npz", ".csv"):
        raise MissionError(f"terrain {spec!r}: expected 'none', 'synthetic_canyon' or a .npz/.csv grid file")
    f = _resolve_file(spec, base_dir)
    if f is None:
        raise MissionError(f"terrain file {spec!r} not found")
    return (Terrain.load_npz(f) if suffix == ".npz" else Terrain.load_csv(f)), spec


def mission_from_dict(doc: Mapping[str, Any], *, base_dir: Path | None = None, name: str = "mission",
                      source_file: Path | None = None) -> Mission:
    """Validate a parsed mission document (see the module docstring) and load its path and terrain.

    Raises :class:`MissionError` with one message for any fault.
    """
    doc = dict(doc)
    where = str(source_file) if source_file else "mission"
    try:
        _check_finite(doc, "")
        fmt = doc.pop("format", FORMAT)
        if fmt != FORMAT:
            raise MissionError(f"format is {fmt!r}, expected {FORMAT!r}")
        unknown = sorted(set(doc) - _TOP_KEYS)
        if unknown:
            raise MissionError(f"unknown key(s) {unknown}; allowed: {sorted(_TOP_KEYS - {'format'})}")
        if "path" not in doc or doc["path"] is None:
            raise MissionError("missing 'path' (a shipped path name, a path file or an inline path)")
        try:
            path, path_source = _load_path_spec(doc["path"], base_dir)
        except PathError as e:
            raise MissionError(f"path: {e}") from None

        stack = doc.get("stack", "rate_2022")
        if isinstance(stack, str) and Path(stack).suffix.lower() in (".yaml", ".yml", ".json"):
            f = _resolve_file(stack, base_dir)
            if f is None:
                raise MissionError(f"stack file {stack!r} not found")
            stack = str(f)
        if not isinstance(stack, (str, Mapping)):
            raise MissionError(f"stack must be a stack name, a stack file or a mapping, got {stack!r}")
        adaptation = doc.get("adaptation", True)
        if not isinstance(adaptation, bool):
            raise MissionError(f"adaptation must be true or false, got {adaptation!r}")
        _, stack_cfg = _resolve_stack(stack, adaptation, None)

        terrain, terrain_source = _load_terrain(doc.get("terrain"), base_dir)

        ini = doc.get("initial") or {}
        if not isinstance(ini, Mapping):
            raise MissionError(f"initial must be a mapping, got {ini!r}")
        bad = sorted(set(ini) - _INITIAL_KEYS)
        if bad:
            raise MissionError(f"unknown key(s) in initial: {bad}; allowed: {sorted(_INITIAL_KEYS)}")
        pos = ini.get("position_m")
        if pos is not None:
            fr = ini.get("frame", "native")
            try:
                M = np.asarray(frame_matrix_to_native(fr), float)
            except (PathError, KeyError, ValueError):
                raise MissionError(f"initial.frame {fr!r} is not one of native, controller, enu, ned") from None
            pos = tuple(float(v) for v in M @ np.array(_vec3(pos, "initial.position_m")))
        initial = InitialState(
            position_native=pos,
            offset_native=_vec3(ini.get("offset_m", [0.0, 0.0, 0.0]), "initial.offset_m"),
            heading_deg=None if ini.get("heading_deg") is None else _number(ini["heading_deg"], "initial.heading_deg"),
            pitch_deg=None if ini.get("pitch_deg") is None else _number(ini["pitch_deg"], "initial.pitch_deg"),
            speed_mps=None if ini.get("speed_mps") is None else _number(ini["speed_mps"], "initial.speed_mps",
                                                                        positive=True))
        if initial.pitch_deg is not None and abs(initial.pitch_deg) >= 90:
            raise MissionError(f"initial.pitch_deg must be within (-90, 90), got {initial.pitch_deg}")

        rps = doc.get("rps")
        if rps is not None and rps != RPS_PATH_MEAN_SPEED:
            if isinstance(rps, str):
                raise MissionError(f"rps must be null, a number or {RPS_PATH_MEAN_SPEED!r}, got {rps!r}")
            rps = _number(rps, "rps", positive=True)
        duration = doc.get("duration_s")
        if duration is not None:
            duration = _number(duration, "duration_s")
            if duration <= 0:
                raise MissionError(f"duration_s must be > 0 s, got {duration}")
        margin = _number(doc.get("duration_margin", 0.2), "duration_margin", nonneg=True)

        sea_state = _number(doc.get("sea_state", 0), "sea_state")
        from bb2_sim.parameters import load_parameters
        from bb2_sim.profiles import get_profile
        from bb2_sim.waves import wave_for_sea_state

        wave_for_sea_state(sea_state, load_parameters())
        profile = doc.get("profile", "iowa")
        get_profile(profile)
        hull = doc.get("hull")
        if hull is not None:
            f = _resolve_file(str(hull), base_dir)
            if f is None or not f.is_dir():
                raise MissionError(f"hull {hull!r} is not a directory of surface files")
            hull = str(f)

        lim = doc.get("limits") or {}
        if not isinstance(lim, Mapping):
            raise MissionError(f"limits must be a mapping, got {lim!r}")
        bad = sorted(set(lim) - _LIMIT_KEYS)
        if bad:
            raise MissionError(f"unknown key(s) in limits: {bad}; allowed: {sorted(_LIMIT_KEYS)}")
        limits = Limits(
            min_hull_clearance_m=_number(lim.get("min_hull_clearance_m", 0.0), "limits.min_hull_clearance_m"),
            max_cg_z_m=None if lim.get("max_cg_z_m") is None else _number(lim["max_cg_z_m"], "limits.max_cg_z_m"))

        if terrain is not None:
            try:
                terrain.check_path(path, 0.0)
            except PathBelowTerrainError as e:
                raise MissionError(f"path below the terrain: {e}") from None
            except TerrainOutOfBoundsError as e:
                raise MissionError(f"path leaves the terrain grid: {e}") from None
        m = Mission(name=str(doc.get("name", name)), path=path, path_source=path_source, stack=stack,
                    adaptation=adaptation, terrain=terrain, terrain_source=terrain_source, initial=initial,
                    rps=rps, duration_s=duration, duration_margin=margin, sea_state=sea_state,
                    profile=str(profile), hull=hull, limits=limits, description=str(doc.get("description", "")),
                    source_file=source_file)
        x0 = initial_state(m)   # validates the initial state against the path (e.g. zero path speed)
        if terrain is not None:
            try:
                c0 = float(terrain.clearance(x0[0:3]))
            except TerrainOutOfBoundsError as e:
                raise MissionError(f"initial position is off the terrain grid: {e}") from None
            if c0 < 0:
                raise MissionError(f"initial position is {-c0:.2f} m below the terrain (native x = {x0[0]:.1f}, "
                                   f"y = {x0[1]:.1f}, z = {x0[2]:.1f} m)")
        return m
    except MissionError as e:
        raise MissionError(f"{where}: {e}") from None
    except (UnknownStackError, ControlConfigError, TerrainError, PathError, ValueError) as e:
        raise MissionError(f"{where}: {type(e).__name__}: {e}") from None


def load_mission(file: str | Path) -> Mission:
    """Load and validate a mission file; a bare name (``canyon``) is looked up in ``missions/``."""
    f = Path(file)
    if not f.exists() and f.suffix == "" and (MISSIONS_DIR / f"{f}.yaml").exists():
        f = MISSIONS_DIR / f"{f}.yaml"
    doc = _read_yaml(f)
    seen = {f.resolve()}
    while "extends" in doc:
        base = doc.pop("extends")
        bf = _resolve_file(str(base), f.parent) if isinstance(base, str) else None
        if bf is None:
            raise MissionError(f"{f}: extends: mission file {base!r} not found")
        if bf.resolve() in seen:
            raise MissionError(f"{f}: extends: cycle through {bf}")
        seen.add(bf.resolve())
        doc = _merge(_read_yaml(bf), doc)
    return mission_from_dict(doc, base_dir=f.parent, name=f.stem, source_file=f)


# ------------------------------------------------------------------------------------------ building
def _resolve_stack(stack: str | Mapping[str, Any], adaptation: bool, speed_v_ref: float | None
                   ) -> tuple[str, dict[str, Any]]:
    from bb2_control.stacks import resolve_config

    over: dict[str, Any] = {"adaptation": bool(adaptation)}
    if speed_v_ref is not None:
        over["speed"] = {"v_ref_mps": float(speed_v_ref)}
    return resolve_config(stack, over)


def stack_overrides(m: Mission) -> dict[str, Any]:
    """Overrides the mission applies to its stack: ``adaptation`` and, when ``rps`` is set, the speed.

    ``rps`` becomes the stack's feed-forward speed reference (v_ref = rps * advance) so that the stack's
    own output carries the propeller command, in-process and in ROS alike.  Build the stack with
    ``build_stack(m.stack, m.path, stack_overrides(m))``.
    """
    over: dict[str, Any] = {"adaptation": bool(m.adaptation)}
    if m.rps is not None:
        _, cfg = _resolve_stack(m.stack, m.adaptation, None)
        advance = float(cfg["speed"].get("advance_m_per_rev", 4.0))
        v_ref = m.path.arc_length() / m.path.span if m.rps == RPS_PATH_MEAN_SPEED else float(m.rps) * advance
        over["speed"] = {"v_ref_mps": float(v_ref)}
    return over


def initial_state(m: Mission) -> np.ndarray:
    """x0 = [x y z phi theta psi u v w p q r] (native) from the mission's initial settings and the path."""
    path = m.path.to_frame("native") if m.path.frame != "native" else m.path
    ini = m.initial
    p0 = np.asarray(ini.position_native if ini.position_native is not None else path(path.t0), float)
    p0 = p0 + np.asarray(ini.offset_native, float)
    dp = np.asarray(path.velocity(path.t0), float)
    speed_path = float(np.linalg.norm(dp))
    if speed_path <= 0 and (ini.heading_deg is None or ini.speed_mps is None):
        raise MissionError("the path has zero speed at its start: give initial.heading_deg and speed_mps")
    t = dp / speed_path if speed_path > 0 else np.array([-1.0, 0.0, 0.0])
    # bow direction in native earth = R(phi, theta, psi) (-1, 0, 0) = (-cos th cos psi, -cos th sin psi, sin th)
    psi = math.radians(ini.heading_deg) if ini.heading_deg is not None else math.atan2(-t[1], -t[0])
    theta = math.radians(ini.pitch_deg) if ini.pitch_deg is not None else math.asin(float(np.clip(t[2], -1, 1)))
    speed = ini.speed_mps if ini.speed_mps is not None else speed_path
    x0 = np.zeros(12)
    x0[0:3] = p0
    x0[4], x0[5] = theta, psi
    x0[6] = -speed
    return x0


def terrain_elevation(terrain: Terrain, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Bilinear elevation of ``terrain`` at native (x, y), NaN off the grid.

    The same interpolant as :meth:`Terrain.elevation` (linear on the regular grid), without its
    per-call overhead and without raising off the grid: the per-tick clearance check uses it.
    """
    gx, gy, gz = terrain.x, terrain.y, terrain.z
    x, y = np.asarray(x, float), np.asarray(y, float)
    inside = (x >= gx[0]) & (x <= gx[-1]) & (y >= gy[0]) & (y <= gy[-1])
    i = np.clip(np.searchsorted(gx, x, side="right") - 1, 0, gx.size - 2)
    j = np.clip(np.searchsorted(gy, y, side="right") - 1, 0, gy.size - 2)
    fx = (x - gx[i]) / (gx[i + 1] - gx[i])
    fy = (y - gy[j]) / (gy[j + 1] - gy[j])
    z = (gz[i, j] * (1 - fx) * (1 - fy) + gz[i + 1, j] * fx * (1 - fy) + gz[i, j + 1] * (1 - fx) * fy
         + gz[i + 1, j + 1] * fx * fy)
    return np.where(inside, z, np.nan)


class HullProbes:
    """Probe points of the hull (native body frame) for vertical clearance and broaching checks.

    The vertices of the convex hull of all surfaces (hull, sail, planes undeflected), thinned to one per
    ``cell_m`` cube; the sail top is the highest vertex.
    """

    def __init__(self, surfaces: Any, cell_m: float = 2.0) -> None:
        from scipy.spatial import ConvexHull

        V = np.concatenate([np.asarray(surfaces.fixed_vertices).reshape(-1, 3)]
                           + [np.asarray(v).reshape(-1, 3) for v in surfaces.plane_vertices])
        P = V[ConvexHull(V).vertices]
        _, keep = np.unique(np.floor(P / cell_m), axis=0, return_index=True)
        self.points_body = P[np.sort(keep)]                 #: (n, 3) m, native body
        self.sail_top_m = float(V[:, 2].max())              #: highest point above the CG, m
        self.keel_m = float(-V[:, 2].min())                 #: lowest point below the CG, m

    def world(self, x12: np.ndarray) -> np.ndarray:
        """Probe positions (n, 3) in the native earth frame for state x12."""
        from bb2_sim.frames import rotation_native

        R = rotation_native(x12[3], x12[4], x12[5])
        return x12[0:3] + self.points_body @ R.T


@dataclass
class MissionComponents:
    """Everything a run is built from (shared by :class:`MissionRunner` and the ROS nodes).

    ``model``/``simulator`` (at ``x0``, t = 0) for the simulator node; ``stack`` (fresh, built by
    ``build_stack(m.stack, m.path, stack_overrides(m))``; ``stack.name``, ``stack.config``) for the control nodes -- its pieces (``stack.guidance``, ``stack.inner``,
    ``stack.mixer``, ``stack.speed``) can run in separate processes; ``path`` in the stack's frame.
    """

    mission: Mission
    model: Any
    simulator: Any
    stack: Any
    x0: np.ndarray
    probes: HullProbes
    max_cg_z_m: float


def mission_components(m: Mission, model: Any = None) -> MissionComponents:
    """Build the ROM (unless given), the simulator at x0, the stack and the hull probes for mission ``m``."""
    from bb2_control.stacks import build_stack
    from bb2_sim.integrator import Simulator
    from bb2_sim.model import BB2Model

    if model is None:
        model = BB2Model(m.hull, profile=m.profile, sea_state=m.sea_state)
    stack = build_stack(m.stack, m.path, stack_overrides(m))
    x0 = initial_state(m)
    probes = HullProbes(model.surfaces)
    max_z = m.limits.max_cg_z_m if m.limits.max_cg_z_m is not None else -probes.sail_top_m
    return MissionComponents(m, model, Simulator(model, x0), stack, x0, probes, float(max_z))


# ------------------------------------------------------------------------------------------ running
MISSION_COLUMNS = [
    "t_s", "x_m", "y_m", "z_m", "phi_deg", "theta_deg", "psi_deg", "u_m_s", "v_m_s", "w_m_s",
    "p_deg_s", "q_deg_s", "r_deg_s", "U_m_s", "flight_path_angle_deg",
    "q_c_rad_s", "r_c_rad_s", "q_up_ref_rad_s", "r_left_ref_rad_s", "z_ref_m", "psi_ref_deg",
    "u_ad_1", "u_ad_2", "dV_deg", "dH_deg",
    "cmd_d1_deg", "cmd_d2_deg", "cmd_d3_deg", "cmd_d4_deg", "cmd_d5_deg",
    "d1_deg", "d2_deg", "d3_deg", "d4_deg", "d5_deg", "rps_cmd", "n_rps",
    "virtual_time_s", "virtual_time_rate", "xd_m", "yd_m", "zd_m", "e_horizontal_m", "e_vertical_m",
    "terrain_z_m", "clearance_m", "hull_clearance_m",
]
"""CSV columns, one row per Ts = 0.05 s tick: the state at t_n (native frames; angles in deg, rates in
deg/s), the stack's output computed from it (rates rad/s; q_c about w2 is bow-down positive; u_ad_1/2 are
the L1 outputs of the q/r or depth/heading channels), the plane commands and the actuator angles the ROM
applies over [t_n, t_n+1), the virtual time, the desired position p_d (native), the stack's path errors
(horizontal > 0: vehicle left of the path; vertical > 0: above), the terrain under the CG and the CG and
hull clearances (NaN without terrain or off the grid)."""


@dataclass(frozen=True)
class MissionEvent:
    """Why a mission failed: ``grounded`` / ``broached`` / ``diverged`` / ``control_error``."""

    kind: str
    t: float                       #: s
    p_native: np.ndarray           #: CG position (x, y, z) native, m
    detail: str

    def __str__(self) -> str:
        x, y, z = (float(v) for v in self.p_native)
        return f"{self.kind} at t = {self.t:.2f} s, CG at x = {x:.1f}, y = {y:.1f}, z = {z:.1f} m (native): {self.detail}"


@dataclass
class MissionStep:
    """One tick: the state at t_n, the stack output from it, the ROM's step record, the clearances."""

    state: Any                    #: VehicleState at t_n
    output: Any                   #: ControlOutput
    record: Any                   #: StepRecord (None if the tick stopped before the ROM step)
    terrain_z_m: float
    clearance_m: float
    hull_clearance_m: float
    row: list[float]
    event: MissionEvent | None = None


@dataclass(frozen=True)
class MissionSummary:
    """Figures of a run.  Path errors are the stack's own (its p_T components); ``*_closest`` are
    measured from the closest point of the path, the same for every stack."""

    mission: str
    stack: str
    adaptation: bool
    mission_time_s: float
    completed: bool
    end_reason: str                 #: finished | duration | grounded | broached | diverged | control_error
    rms_vertical_m: float
    max_vertical_m: float
    rms_horizontal_m: float
    max_horizontal_m: float
    rms_vertical_closest_m: float
    max_vertical_closest_m: float
    rms_horizontal_closest_m: float
    max_horizontal_closest_m: float
    min_clearance_m: float          #: CG vertical clearance (NaN without terrain)
    min_clearance_t_s: float
    min_hull_clearance_m: float
    virtual_time_end_s: float
    wall_time_s: float
    event: MissionEvent | None = None

    @property
    def failed(self) -> bool:
        return self.event is not None

    def lines(self) -> list[str]:
        """Human-readable report."""
        out = [f"mission {self.mission}: stack {self.stack}, adaptation {'on' if self.adaptation else 'off'}",
               f"  mission time {self.mission_time_s:.2f} s ({self.end_reason}; virtual time "
               f"{self.virtual_time_end_s:.1f} s){'' if self.completed else ' -- NOT completed'}",
               f"  vertical path error    RMS {self.rms_vertical_m:7.3f} m   max {self.max_vertical_m:7.3f} m"
               f"   (closest point: RMS {self.rms_vertical_closest_m:.3f}, max {self.max_vertical_closest_m:.3f})",
               f"  horizontal path error  RMS {self.rms_horizontal_m:7.3f} m   max {self.max_horizontal_m:7.3f} m"
               f"   (closest point: RMS {self.rms_horizontal_closest_m:.3f}, max {self.max_horizontal_closest_m:.3f})"]
        if math.isfinite(self.min_clearance_m):
            out.append(f"  minimum ground clearance {self.min_clearance_m:.2f} m (CG, at t = {self.min_clearance_t_s:.1f} s);"
                       f" lowest hull point {self.min_hull_clearance_m:.2f} m")
        else:
            out.append("  minimum ground clearance: n/a (no terrain)")
        rt = self.mission_time_s / self.wall_time_s if self.wall_time_s > 0 else float("inf")
        out.append(f"  wall time {self.wall_time_s:.2f} s ({rt:.0f}x real time)")
        if self.event is not None:
            out.append(f"  FAILED: {self.event}")
        return out


@dataclass
class MissionResult:
    mission: Mission
    traj: dict[str, np.ndarray]     #: MISSION_COLUMNS -> arrays (one entry per tick)
    summary: MissionSummary
    path_native: BernsteinPath

    @property
    def failed(self) -> bool:
        return self.summary.failed


class MissionRunner:
    """Flies a mission tick by tick (see the module docstring for the tick).

    ``step()`` runs one tick; ``run()`` runs to the end (stack finished, duration, or a failure) and
    returns a :class:`MissionResult`.
    """

    def __init__(self, mission: Mission, model: Any = None) -> None:
        self.mission = mission
        self.c = mission_components(mission, model)
        self.sim, self.stack = self.c.simulator, self.c.stack
        self.terrain = mission.terrain
        self.n_steps = int(math.floor(mission.duration / self.sim.h + 1e-9))
        self.done = False
        self.event: MissionEvent | None = None
        self.end_reason = ""
        self._last_out: Any = None

    # -- terrain
    def _clearances(self, x: np.ndarray) -> tuple[float, float, float]:
        if self.terrain is None:
            return math.nan, math.nan, math.nan
        pts = np.vstack([x[0:3], self.c.probes.world(x)])
        zt = terrain_elevation(self.terrain, pts[:, 0], pts[:, 1])
        cl = pts[:, 2] - zt
        hull = float(np.nanmin(cl[1:])) if np.isfinite(cl[1:]).any() else math.nan
        return float(zt[0]), float(cl[0]), hull

    def step(self) -> MissionStep:
        """One tick at t_n: stack output from the state, terrain checks, then the ROM step to t_n+1."""
        from bb2_control.errors import NonFiniteInputError, PathFollowingError
        from bb2_sim.integrator import NonFiniteStateError
        from bb2_sim.state import VehicleState

        if self.done:
            raise RuntimeError("mission already ended")
        sim = self.sim
        x = sim.x.copy()
        state = VehicleState.from_vector(sim.t, x)
        tz, cl, hull = self._clearances(x)
        try:
            out = self.stack.step(state)
        except (PathFollowingError, NonFiniteInputError) as e:
            self._end("control_error", MissionEvent("control_error", sim.t, x[0:3].copy(), str(e)))
            row = self._row(state, x, self._last_out, None, tz, cl, hull) if self._last_out else []
            return MissionStep(state, None, None, tz, cl, hull, row, self.event)
        self._last_out = out
        event = None
        lim = self.mission.limits
        if math.isfinite(hull) and hull < lim.min_hull_clearance_m:
            event = MissionEvent("grounded", sim.t, x[0:3].copy(),
                                 f"lowest hull point {hull:.2f} m above the terrain (limit "
                                 f"{lim.min_hull_clearance_m} m); CG clearance {cl:.2f} m")
        elif x[2] > self.c.max_cg_z_m:
            event = MissionEvent("broached", sim.t, x[0:3].copy(),
                                 f"CG z = {x[2]:.2f} m above the limit {self.c.max_cg_z_m:.2f} m"
                                 + (" (sail top at the calm surface)" if lim.max_cg_z_m is None else ""))
        rec = None
        if event is None:
            try:
                rec = sim.step(out.planes_deg, out.rps)
            except NonFiniteStateError as e:
                event = MissionEvent("diverged", sim.t, x[0:3].copy(), str(e))
        row = self._row(state, x, out, rec, tz, cl, hull)
        if event is not None:
            self._end(event.kind, event)
        elif out.finished:
            self._end("finished", None)
        elif sim.n >= self.n_steps:
            self._end("duration", None)
        return MissionStep(state, out, rec, tz, cl, hull, row, event)

    def _end(self, reason: str, event: MissionEvent | None) -> None:
        self.done, self.end_reason, self.event = True, reason, event

    def _row(self, state: Any, x: np.ndarray, out: Any, rec: Any, tz: float, cl: float, hull: float) -> list[float]:
        from bb2_sim.frames import rotation_native

        v_e = rotation_native(x[3], x[4], x[5]) @ x[6:9]
        fpa = math.degrees(math.atan2(v_e[2], math.hypot(v_e[0], v_e[1])))
        u = list(out.u_ad.values()) if out.u_ad else []
        u = (u + [math.nan, math.nan])[:2]
        act_planes = rec.act.planes_deg if rec is not None else [math.nan] * 5
        n = rec.act.rps if rec is not None else math.nan
        return [state.t, x[0], x[1], x[2], x[3] * RAD2DEG, x[4] * RAD2DEG, x[5] * RAD2DEG, x[6], x[7], x[8],
                x[9] * RAD2DEG, x[10] * RAD2DEG, x[11] * RAD2DEG, math.sqrt(x[6] ** 2 + x[7] ** 2 + x[8] ** 2), fpa,
                out.q_c, out.r_c, out.q_up_ref, out.r_left_ref, out.z_ref, out.psi_ref * RAD2DEG,
                u[0], u[1], out.dV_deg, out.dH_deg, *out.planes_deg, *act_planes, out.rps, n,
                out.gamma, out.gamma_dot, *out.p_d_native, out.e_horizontal_m, out.e_vertical_m, tz, cl, hull]

    def run(self, progress: Callable[[float], None] | None = None,
            on_row: Callable[[list[float]], None] | None = None) -> MissionResult:
        """Fly to the end; ``on_row`` gets every CSV row as it is made, ``progress`` the time every 10 s."""
        rows: list[list[float]] = []
        t0 = time.perf_counter()
        while not self.done:
            st = self.step()
            if st.row:
                rows.append(st.row)
                if on_row:
                    on_row(st.row)
            if progress and self.sim.n % 200 == 0:
                progress(self.sim.t)
        wall = time.perf_counter() - t0
        arr = np.array(rows, dtype=float) if rows else np.zeros((0, len(MISSION_COLUMNS)))
        traj = {c: arr[:, i] for i, c in enumerate(MISSION_COLUMNS)}
        path_native = self.mission.path.to_frame("native") if self.mission.path.frame != "native" \
            else self.mission.path
        return MissionResult(self.mission, traj, summarize(self, traj, path_native, wall), path_native)


def _rms_max(e: np.ndarray) -> tuple[float, float]:
    e = e[np.isfinite(e)]
    if e.size == 0:
        return math.nan, math.nan
    return float(np.sqrt(np.mean(e ** 2))), float(np.max(np.abs(e)))


def path_errors_closest(path_native: BernsteinPath, p_native: np.ndarray, samples: int = 20001
                        ) -> tuple[np.ndarray, np.ndarray]:
    """(horizontal, vertical) errors of points from the closest point of the path (dense samples, KD-tree).

    Components in the path's horizontal-normal frame there: horizontal > 0 left of the path, vertical > 0
    above it (the same frame as the rate stack's p_T).
    """
    from scipy.spatial import cKDTree

    p_native = np.asarray(p_native, float).reshape(-1, 3)
    if len(p_native) == 0:
        return np.zeros(0), np.zeros(0)
    t, pts = path_native.sample(samples)
    _, k = cKDTree(pts).query(p_native)
    d = np.asarray(path_native.velocity(t[k]), float).reshape(-1, 3)
    t1 = d / np.linalg.norm(d, axis=1, keepdims=True)
    h = np.c_[-d[:, 1], d[:, 0], np.zeros(len(d))]
    t2 = h / np.maximum(np.linalg.norm(h, axis=1, keepdims=True), 1e-12)
    t3 = np.cross(t1, t2)
    e = p_native - pts[k]
    return np.einsum("ij,ij->i", e, t2), np.einsum("ij,ij->i", e, t3)


def summarize(runner: MissionRunner, traj: Mapping[str, np.ndarray], path_native: BernsteinPath,
              wall_time_s: float) -> MissionSummary:
    m = runner.mission
    rv, mv = _rms_max(np.asarray(traj["e_vertical_m"]))
    rh, mh = _rms_max(np.asarray(traj["e_horizontal_m"]))
    P = np.c_[traj["x_m"], traj["y_m"], traj["z_m"]]
    eh_c, ev_c = path_errors_closest(path_native, P)
    rvc, mvc = _rms_max(ev_c)
    rhc, mhc = _rms_max(eh_c)
    cl = np.asarray(traj["clearance_m"])
    if np.isfinite(cl).any():
        k = int(np.nanargmin(cl))
        min_cl, t_cl = float(cl[k]), float(traj["t_s"][k])
        min_hull = float(np.nanmin(traj["hull_clearance_m"]))
    else:
        min_cl = t_cl = min_hull = math.nan
    t_end = float(runner.sim.t)
    g = np.asarray(traj["virtual_time_s"])
    return MissionSummary(
        mission=m.name, stack=runner.stack.name, adaptation=m.adaptation, mission_time_s=t_end,
        completed=runner.end_reason == "finished", end_reason=runner.end_reason,
        rms_vertical_m=rv, max_vertical_m=mv, rms_horizontal_m=rh, max_horizontal_m=mh,
        rms_vertical_closest_m=rvc, max_vertical_closest_m=mvc, rms_horizontal_closest_m=rhc,
        max_horizontal_closest_m=mhc, min_clearance_m=min_cl, min_clearance_t_s=t_cl,
        min_hull_clearance_m=min_hull, virtual_time_end_s=float(g[-1]) if g.size else math.nan,
        wall_time_s=wall_time_s, event=runner.event)


def run_mission(m: Mission | str | Path, *, model: Any = None, progress: Callable[[float], None] | None = None,
                on_row: Callable[[list[float]], None] | None = None) -> MissionResult:
    """Load (if needed) and fly a mission."""
    if not isinstance(m, Mission):
        m = load_mission(m)
    return MissionRunner(m, model).run(progress=progress, on_row=on_row)


def read_mission_csv(file: str | Path) -> dict[str, np.ndarray]:
    """A mission CSV back into column arrays."""
    import csv

    with open(file, newline="") as fh:
        r = csv.reader(fh)
        head = next(r)
        data = np.array([[float(v) for v in row] for row in r], dtype=float).reshape(-1, len(head))
    return {c: data[:, i] for i, c in enumerate(head)}
