"""The mission file: schema, validation and loading into a :class:`Mission` (no ROS).

Mission file (YAML; every key optional except ``path``; unknown keys are an error)::

    name: canyon                       # default: file stem; one file name (it names the run's files)
    description: free text
    extends: other.yaml                # start from another mission file (nested mappings merge): beside
                                       # this file, else the working directory, else a shipped name (canyon)
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
    sea_state: 0                       # the authors' regular head-sea table (0..7), as before; or:
    sea:                               # an irregular / directional sea (bb2_sim.environment; missions/README.md)
      spectrum: jonswap                #   jonswap | pm | ittc | regular
      hs: 3.25                         #   significant wave height, m  (or sea_state: 5 for the table's Hs, Tp)
      tp: 9.7                          #   peak period, s
      gamma: 3.3                       #   JONSWAP peak enhancement
      amplitude_m: null                #   regular: amplitude (default hs/2), m
      period_s: null                   #   regular: period (default tp), s
      heading_deg: 0.0                 #   direction the waves travel towards, native earth frame (0 = +x)
      spreading_s: null                #   cos-2s spreading exponent (short-crested); null = long-crested
      components: 64                   #   number of components, or a CSV component list (file)
      seed: 0                          #   random phases
    current:                           # a current (bb2_sim.environment)
      speed_mps: 0.5                   #   m/s
      heading_deg: 90.0                #   direction the water moves towards, native earth frame (0 = +x)
      profile: null                    #   {depths_m: [...], factors: [...]} or {water_depth_m: d, alpha: 1/7}
    sensors: tactical                  # sensor suite (bb2_sim.sensors): tactical | mems | FILE | none (default:
                                       # none, no /bb2/sensors/* topics); or {suite: ..., seed: 0, faults: [...]}
                                       # with faults [{sensor: dvl, kind: dropout|stuck|bias_step, start_s: 100,
                                       # end_s: 130, bias: ..., field: ...}] (bb2_sim.sensors.config.FaultSpec)
    navigation: truth                  # what the stack flies on: truth (the paper) | sensors (our filter)
    profile: iowa                      # iowa | corrected
    substeps: 1                        # ROM ode3 steps per 0.05 s step (1: the authors', numerically unstable
                                       # from ~11.6 m/s; 2 to ~15, 3 to ~18, 4 to ~20.5: bb2_sim.step_stability)
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

import functools
import json
import math
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Mapping

import numpy as np
import yaml

from bb2_control.errors import ControlConfigError, UnknownStackError
from bb2_planner.bernstein import BernsteinPath, PathError, frame_matrix_to_native
from bb2_planner.terrain import PathBelowTerrainError, Terrain, TerrainError, TerrainOutOfBoundsError
from bb2_sim.environment import Environment, current_from_mapping, sea_from_mapping
from bb2_sim.sea import SeaInputError
from bb2_sim.sensors.config import SensorConfigError, SensorSpec, navigation_from_value, sensors_from_mapping
from bb2_sim.names import did_you_mean, unknown_keys_hint
from bb2_sim.outputs import plain_name
from bb2_sim.yaml_files import load as load_yaml

__all__ = ["MissionError", "InitialState", "Limits", "Mission", "MISSIONS_DIR", "RPS_PATH_MEAN_SPEED", "FORMAT",
           "load_mission", "mission_file", "read_mission_document", "mission_from_dict", "initial_state"]

MISSIONS_DIR = Path(__file__).resolve().parents[1] / "missions"
RPS_PATH_MEAN_SPEED = "path_mean_speed"
RPS_PATH_MEAN_SPEED = "path_mean_speed"
_TOP_KEYS = {"name", "description", "extends", "path", "stack", "adaptation", "terrain", "initial", "rps",
             "duration_s", "duration_margin", "sea_state", "sea", "current", "profile", "hull", "limits",
             "format", "sensors", "navigation", "substeps"}
_INITIAL_KEYS = {"position_m", "frame", "offset_m", "heading_deg", "pitch_deg", "speed_mps"}
_LIMIT_KEYS = {"min_hull_clearance_m", "max_cg_z_m"}
FORMAT = "bb2_mission/1"


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
    environment: Environment = Environment()   #: the sea and current (its sea is the table's sea_state if none)
    sensors: SensorSpec | None = field(default=None, compare=False)  #: sensor suite, seed, faults (None: none)
    navigation: str = "truth"                  #: what the stack flies on: truth (the paper) | sensors
    substeps: int = 1                          #: ROM ode3 steps per major step (1: the authors' fixed step)

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
        doc = load_yaml(file.read_text(encoding="utf-8"))
    except FileNotFoundError as e:
        raise MissionError(f"{file}: cannot read mission file ({e.strerror}){shipped_name_hint(file)}") from None
    except OSError as e:
        raise MissionError(f"{file}: cannot read mission file ({e.strerror})") from None
    except UnicodeDecodeError as e:
        raise MissionError(f"{file}: not UTF-8 text (byte {e.start})") from None
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


@functools.lru_cache(maxsize=4)
def _synthetic_canyon_terrain(parameters_json: str) -> Terrain:
    """The synthetic canyon's terrain for its parameter document, generated once per process (~0.12 s each time
    otherwise: a fifth of a short mission's cost in a campaign worker); its arrays are read-only, shared by the
    missions that use it."""
    from bb2_planner.terrain import synthetic_canyon

    t = synthetic_canyon(json.loads(parameters_json)).terrain
    for a in (t.x, t.y, t.z):
        a.setflags(write=False)
    return t


def _load_terrain(spec: Any, base_dir: Path | None) -> tuple[Terrain | None, str | None]:
    from bb2_planner.terrain import load_canyon_parameters

    if spec is None or (isinstance(spec, str) and spec.lower() == "none"):
        return None, None
    if not isinstance(spec, str):
        raise MissionError(f"terrain must be 'none', 'synthetic_canyon' or a .npz/.csv grid file, got {spec!r}")
    if spec == "synthetic_canyon":
        return _synthetic_canyon_terrain(json.dumps(load_canyon_parameters(), sort_keys=True)), spec
    suffix = Path(spec).suffix.lower()
    if suffix not in (".npz", ".csv"):
        raise MissionError(f"terrain {spec!r}: expected 'none', 'synthetic_canyon' or a .npz/.csv grid file")
    f = _resolve_file(spec, base_dir)
    if f is None:
        raise MissionError(f"terrain file {spec!r} not found")
    return (Terrain.load_npz(f) if suffix == ".npz" else Terrain.load_csv(f)), spec


def _resolve_stack(stack: str | Mapping[str, Any], adaptation: bool, speed_v_ref: float | None
                   ) -> tuple[str, dict[str, Any]]:
    from bb2_control.stacks import resolve_config

    over: dict[str, Any] = {"adaptation": bool(adaptation)}
    if speed_v_ref is not None:
        over["speed"] = {"v_ref_mps": float(speed_v_ref)}
    return resolve_config(stack, over)


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
            raise MissionError(f"unknown key(s) {unknown}{unknown_keys_hint(unknown, _TOP_KEYS)}; "
                               f"allowed: {sorted(_TOP_KEYS - {'format'})}")
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
            raise MissionError(f"unknown key(s) in initial: {bad}{unknown_keys_hint(bad, _INITIAL_KEYS)}; "
                               f"allowed: {sorted(_INITIAL_KEYS)}")
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
        sea_doc = doc.get("sea")
        if sea_doc is not None and "sea_state" in doc:
            raise MissionError("give either sea_state (the authors' table) or a sea: block, not both "
                               "(sea: {sea_state: S} is the same table)")
        sea = sea_from_mapping(sea_doc if sea_doc is not None else {"sea_state": sea_state}, base_dir=base_dir)
        environment = Environment(sea, current_from_mapping(doc.get("current")))
        try:
            sensors = sensors_from_mapping(doc.get("sensors"), base_dir=base_dir)
            navigation = navigation_from_value(doc.get("navigation"), sensors)
        except SensorConfigError as e:
            raise MissionError(str(e)) from None
        if sea.authors_table:
            sea_state = sea.sea_state
        profile = doc.get("profile", "iowa")
        get_profile(profile)
        from bb2_sim.integrator import check_substeps

        try:
            substeps = check_substeps(doc.get("substeps", 1))
        except ValueError as e:
            raise MissionError(f"{e} (ROM ode3 steps per 0.05 s step)") from None
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
            raise MissionError(f"unknown key(s) in limits: {bad}{unknown_keys_hint(bad, _LIMIT_KEYS)}; "
                               f"allowed: {sorted(_LIMIT_KEYS)}")
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
        try:
            run_name = plain_name(doc.get("name", name), "name")
        except ValueError as exc:
            raise MissionError(str(exc)) from None
        m = Mission(name=run_name, path=path, path_source=path_source, stack=stack,
                    adaptation=adaptation, terrain=terrain, terrain_source=terrain_source, initial=initial,
                    rps=rps, duration_s=duration, duration_margin=margin, sea_state=sea_state,
                    profile=str(profile), hull=hull, limits=limits, description=str(doc.get("description", "")),
                    source_file=source_file, environment=environment, sensors=sensors, navigation=navigation,
                    substeps=substeps)
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
    except (MissionError, SeaInputError) as e:
        raise MissionError(f"{where}: {e}") from None
    except (UnknownStackError, ControlConfigError, TerrainError, PathError, ValueError) as e:
        raise MissionError(f"{where}: {type(e).__name__}: {e}") from None


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


def shipped_missions() -> list[str]:
    """The names of the shipped missions (``missions/*.yaml`` without .yaml: canyon, circle ...)."""
    return sorted(f.stem for f in MISSIONS_DIR.glob("*.yaml"))


def is_bare_name(value: str | Path) -> bool:
    """Whether ``value`` could be a shipped name: no folder, no suffix (``canyon``, not ``./canyon``, ``c.yaml``)."""
    f = Path(value)
    return not f.suffix and len(f.parts) == 1


def shipped_name_hint(value: str | Path, names: list[str] | None = None, what: str = "missions") -> str:
    """For a file that does not exist and could be a shipped name (:func:`is_bare_name`): ``" (did you mean
    'canyon'?); shipped missions: canyon, circle, ..."``, else ``""``."""
    if not is_bare_name(value):
        return ""
    names = shipped_missions() if names is None else names
    return f"{did_you_mean(str(value), names)}; shipped {what}: {', '.join(names)}"


def mission_file(file: str | Path) -> Path:
    """The mission file ``file`` names: itself, or for a bare name not found here (``canyon``) ``missions/``'s."""
    f = Path(file)
    if not f.exists() and f.suffix == "" and (MISSIONS_DIR / f"{f}.yaml").exists():
        return MISSIONS_DIR / f"{f}.yaml"
    return f


def read_mission_document(file: str | Path) -> dict[str, Any]:
    """The document of mission file ``file`` (:func:`mission_file`) with its ``extends`` chain merged, nested
    mappings key by key.  Each ``extends`` is looked up beside the file that names it, then in the working
    directory, then, a bare name, in ``missions/`` (``extends: canyon``).  :class:`MissionError` naming the file."""
    f = mission_file(file)
    doc = _read_yaml(f)
    seen = {f.resolve()}
    holder = f                  # the file whose extends is being resolved (relative to its own folder)
    while "extends" in doc:
        base = doc.pop("extends")
        bf = _resolve_file(str(base), holder.parent) if isinstance(base, str) else None
        if bf is None and isinstance(base, str) and mission_file(base).exists():   # a shipped name
            bf = mission_file(base)
        if bf is None:
            raise MissionError(f"{holder}: extends: mission file {base!r} not found"
                               + (shipped_name_hint(base) if isinstance(base, str) else ""))
        if bf.resolve() in seen:
            raise MissionError(f"{f}: extends: cycle through {bf}")
        seen.add(bf.resolve())
        doc = _merge(_read_yaml(bf), doc)          # the base's own extends comes with it
        holder = bf
    return doc


def load_mission(file: str | Path) -> Mission:
    """Load and validate a mission file; a bare name (``canyon``) is looked up in ``missions/``."""
    f = mission_file(file)
    doc = read_mission_document(f)
    return mission_from_dict(doc, base_dir=f.parent, name=f.stem, source_file=f)

