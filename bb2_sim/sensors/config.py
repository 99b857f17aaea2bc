"""The sensor-suite file: presets, validation and conversion to SI (no ROS).

A suite file (YAML, ``format: bb2_sensor_suite/1``) has one block per sensor -- ``imu``, ``pressure``, ``dvl``,
``altimeter``, ``gps`` -- with the keys of the presets ``bb2_sim/data/sensors_tactical.yaml`` and
``sensors_mems.yaml`` (units in the key names, datasheet units at this edge).  A file may start from a preset
with ``base: tactical`` (or ``mems``) and give only what differs (nested mappings merge); a block set to
``null`` (or ``enabled: false``) removes that sensor.  ``faults:`` is a list of faults (:class:`FaultSpec`).

Every key is checked: an unknown key, a missing one, a non-number, NaN/inf, a negative noise or a rate <= 0 is a
:class:`SensorConfigError` with one line naming the file and the key.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping

import numpy as np
import yaml

from bb2_sim.names import unknown_keys_hint
from bb2_sim.yaml_files import load as load_yaml

__all__ = ["SensorConfigError", "FORMAT", "PRESETS", "DATA_DIR", "SENSOR_NAMES", "Mounting", "GyroConfig",
           "AccelConfig", "AhrsConfig", "ImuConfig", "PressureConfig", "DvlConfig", "AltimeterConfig",
           "GpsConfig", "FaultSpec", "SuiteConfig", "load_suite_config", "suite_config_from_mapping",
           "faults_from_list", "SensorSpec", "sensors_from_mapping", "navigation_from_value", "NAVIGATION_MODES"]

FORMAT = "bb2_sensor_suite/1"
DATA_DIR = Path(__file__).resolve().parents[1] / "data"
PRESETS = {"tactical": DATA_DIR / "sensors_tactical.yaml", "mems": DATA_DIR / "sensors_mems.yaml"}
SENSOR_NAMES = ("imu", "pressure", "dvl", "altimeter", "gps")

DEG = math.pi / 180.0
G0 = 9.80665          #: standard gravity (for ug), m/s^2
UG = 1e-6 * G0        #: one micro-g, m/s^2
PPM = 1e-6


class SensorConfigError(ValueError):
    """A sensor-suite file or value is wrong (one line naming the file and the key)."""


# ------------------------------------------------------------------------------------------ helpers
def _num(v: Any, what: str, *, positive: bool = False, nonneg: bool = False, le: float | None = None) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise SensorConfigError(f"{what} must be a number, got {v!r}")
    x = float(v)
    if not math.isfinite(x):
        raise SensorConfigError(f"{what} must be finite, got {v!r}")
    if positive and x <= 0:
        raise SensorConfigError(f"{what} must be > 0, got {v!r}")
    if nonneg and x < 0:
        raise SensorConfigError(f"{what} must be >= 0, got {v!r}")
    if le is not None and x > le:
        raise SensorConfigError(f"{what} must be <= {le:g}, got {v!r}")
    return x


def _vec(v: Any, n: int, what: str) -> np.ndarray:
    if not isinstance(v, (list, tuple)) or len(v) != n:
        raise SensorConfigError(f"{what} must be a list of {n} numbers, got {v!r}")
    return np.array([_num(c, f"{what}[{i}]") for i, c in enumerate(v)])


def _block(doc: Any, what: str, keys: set[str], optional: set[str] = frozenset()) -> Mapping[str, Any]:
    if not isinstance(doc, Mapping):
        raise SensorConfigError(f"{what} must be a mapping, got {doc!r}")
    unknown = sorted(set(doc) - keys - optional)
    if unknown:
        raise SensorConfigError(f"unknown key(s) in {what}: {unknown}{unknown_keys_hint(unknown, keys | optional)}; "
                                f"allowed: {sorted(keys | optional)}")
    missing = sorted(keys - set(doc))
    if missing:
        raise SensorConfigError(f"missing key(s) in {what}: {missing}")
    return doc


def rotation_rpy(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """R = Rz(yaw) Ry(pitch) Rx(roll): components in the rotated frame -> the parent frame (REP-103 rpy)."""
    cr, sr, cp, sp, cy, sy = (math.cos(roll), math.sin(roll), math.cos(pitch), math.sin(pitch),
                              math.cos(yaw), math.sin(yaw))
    return np.array([[cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
                     [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
                     [-sp, cp * sr, cp * cr]])


# ------------------------------------------------------------------------------------------ data
@dataclass(frozen=True)
class Mounting:
    """Where a sensor sits: ``position_flu`` (m) in base_link (FLU at the CG) and ``R_flu_sensor`` (sensor-frame
    components -> base_link components), from ``rpy_deg`` (REP-103 fixed-axis roll, pitch, yaw)."""

    position_flu: np.ndarray
    rpy_rad: np.ndarray

    @property
    def R_flu_sensor(self) -> np.ndarray:
        return rotation_rpy(*self.rpy_rad)

    @classmethod
    def from_mapping(cls, doc: Any, what: str) -> "Mounting":
        d = _block(doc, what, {"position_m", "rpy_deg"})
        return cls(_vec(d["position_m"], 3, f"{what}.position_m"), _vec(d["rpy_deg"], 3, f"{what}.rpy_deg") * DEG)


@dataclass(frozen=True)
class GyroConfig:
    """SI: white-noise density (rad/s/sqrt(Hz)), Gauss-Markov bias instability (rad/s, its correlation time s),
    bias random walk (rad/s/sqrt(s)), turn-on bias sigma (rad/s), scale factor and misalignment sigmas (1)."""

    noise_density: float
    bias_instability: float
    bias_instability_tau_s: float
    bias_random_walk: float
    turn_on_bias: float
    scale_factor: float
    misalignment: float


@dataclass(frozen=True)
class AccelConfig:
    """SI: white-noise density (m/s^2/sqrt(Hz)), bias instability (m/s^2) and tau (s), bias random walk
    (m/s^2/sqrt(s)), turn-on bias sigma (m/s^2), scale factor and misalignment sigmas (1)."""

    noise_density: float
    bias_instability: float
    bias_instability_tau_s: float
    bias_random_walk: float
    turn_on_bias: float
    scale_factor: float
    misalignment: float


@dataclass(frozen=True)
class AhrsConfig:
    """SI (rad, rad/s, rad/sqrt(s)): attitude noise, constant heading drift-rate sigma, heading random walk."""

    roll_pitch_noise: float
    heading_noise: float
    heading_drift: float
    heading_random_walk: float


@dataclass(frozen=True)
class ImuConfig:
    rate_hz: float
    frame_id: str
    mounting: Mounting
    gyro: GyroConfig
    accel: AccelConfig
    ahrs: AhrsConfig
    source: str = ""


@dataclass(frozen=True)
class PressureConfig:
    rate_hz: float
    frame_id: str
    mounting: Mounting
    noise_pa: float
    resolution_pa: float
    offset_pa: float
    atmospheric_pressure_pa: float
    source: str = ""


@dataclass(frozen=True)
class DvlConfig:
    rate_hz: float
    latency_s: float
    frame_id: str
    mounting: Mounting
    beam_angle_rad: float
    beam_azimuths_rad: np.ndarray
    min_range_m: float
    max_range_m: float
    max_beam_incidence_rad: float
    beam_noise_mps: float
    beam_noise_fraction: float
    scale_factor: float
    water_track_noise_mps: float
    source: str = ""

    def beams_dvl(self) -> np.ndarray:
        """Unit beam directions (4, 3) in the DVL frame (pointing down, away from the transducer)."""
        s, c = math.sin(self.beam_angle_rad), math.cos(self.beam_angle_rad)
        a = np.asarray(self.beam_azimuths_rad)
        return np.column_stack([s * np.cos(a), s * np.sin(a), -c * np.ones_like(a)])


@dataclass(frozen=True)
class AltimeterConfig:
    rate_hz: float
    frame_id: str
    mounting: Mounting
    min_range_m: float
    max_range_m: float
    noise_m: float
    noise_fraction: float
    field_of_view_rad: float
    dropout_probability: float
    source: str = ""


@dataclass(frozen=True)
class GpsConfig:
    rate_hz: float
    frame_id: str
    mounting: Mounting
    horizontal_noise_m: float
    vertical_noise_m: float
    time_to_first_fix_s: float
    min_antenna_height_m: float
    origin_lat_deg: float
    origin_lon_deg: float
    origin_alt_m: float
    source: str = ""


FAULT_KINDS = ("dropout", "stuck", "bias_step")


@dataclass(frozen=True)
class FaultSpec:
    """A fault of one sensor over ``[start_s, end_s)`` (sim time; ``end_s`` inf = to the end).

    ``dropout``: no message; ``stuck``: the last value before the window repeated (new stamps); ``bias_step``:
    ``bias`` added to ``field`` (imu: ``gyro`` rad/s or ``accel`` m/s^2, 3 values in imu_link; pressure: Pa;
    dvl: 3 values m/s in dvl_link; altimeter: m; gps: 3 values m, ENU)."""

    sensor: str
    kind: str
    start_s: float
    end_s: float = math.inf
    bias: tuple[float, ...] = ()
    field: str = ""

    def active(self, t: float) -> bool:
        return self.start_s <= t < self.end_s


_BIAS_FIELDS = {"imu": {"gyro": 3, "accel": 3}, "pressure": {"pressure": 1}, "dvl": {"velocity": 3},
                "altimeter": {"range": 1}, "gps": {"position": 3}}


def faults_from_list(doc: Any, where: str = "faults") -> tuple[FaultSpec, ...]:
    """Validate a ``faults:`` list (see :class:`FaultSpec`)."""
    if doc is None:
        return ()
    if not isinstance(doc, (list, tuple)):
        raise SensorConfigError(f"{where} must be a list of faults, got {doc!r}")
    out = []
    for i, f in enumerate(doc):
        w = f"{where}[{i}]"
        d = _block(f, w, {"sensor", "kind", "start_s"}, {"end_s", "duration_s", "bias", "field"})
        sensor, kind = d["sensor"], d["kind"]
        if sensor not in SENSOR_NAMES:
            raise SensorConfigError(f"{w}.sensor must be one of {list(SENSOR_NAMES)}, got {sensor!r}")
        if kind not in FAULT_KINDS:
            raise SensorConfigError(f"{w}.kind must be one of {list(FAULT_KINDS)}, got {kind!r}")
        start = _num(d["start_s"], f"{w}.start_s", nonneg=True)
        if "end_s" in d and "duration_s" in d:
            raise SensorConfigError(f"{w}: give end_s or duration_s, not both")
        end = math.inf
        if d.get("end_s") is not None:
            end = _num(d["end_s"], f"{w}.end_s")
        elif d.get("duration_s") is not None:
            end = start + _num(d["duration_s"], f"{w}.duration_s", positive=True)
        if end <= start:
            raise SensorConfigError(f"{w}: end_s must be after start_s, got [{start:g}, {end:g})")
        bias: tuple[float, ...] = ()
        fld = ""
        if kind == "bias_step":
            fields = _BIAS_FIELDS[sensor]
            fld = d.get("field", next(iter(fields)))
            if fld not in fields:
                raise SensorConfigError(f"{w}.field of a {sensor} bias_step must be one of {list(fields)}, "
                                        f"got {fld!r}")
            if "bias" not in d:
                raise SensorConfigError(f"{w}: a bias_step needs bias")
            n = fields[fld]
            b = d["bias"]
            bias = (_num(b, f"{w}.bias"),) if n == 1 and not isinstance(b, (list, tuple)) \
                else tuple(_vec(b, n, f"{w}.bias"))
        elif "bias" in d or "field" in d:
            raise SensorConfigError(f"{w}: bias/field belong to a bias_step, not a {kind}")
        out.append(FaultSpec(sensor, kind, start, end, bias, fld))
    return tuple(out)


@dataclass(frozen=True)
class SuiteConfig:
    """A validated suite: one config per present sensor (None = absent), the faults, where it came from."""

    name: str
    imu: ImuConfig | None = None
    pressure: PressureConfig | None = None
    dvl: DvlConfig | None = None
    altimeter: AltimeterConfig | None = None
    gps: GpsConfig | None = None
    faults: tuple[FaultSpec, ...] = ()
    source: str = ""
    description: str = ""
    document: Mapping[str, Any] = field(default_factory=dict, repr=False, compare=False)  #: the merged YAML

    def sensors(self) -> dict[str, Any]:
        """Present sensors by name, in :data:`SENSOR_NAMES` order."""
        return {n: getattr(self, n) for n in SENSOR_NAMES if getattr(self, n) is not None}


# ------------------------------------------------------------------------------------------ per sensor
_COMMON = {"rate_hz", "frame_id", "mounting"}


def _frame(v: Any, what: str) -> str:
    if not isinstance(v, str) or not v or "/" in v or " " in v:
        raise SensorConfigError(f"{what} must be a frame name (no '/' or spaces), got {v!r}")
    return v


def _imu(d: Mapping[str, Any], w: str) -> ImuConfig:
    d = _block(d, w, _COMMON | {"gyro", "accel", "ahrs"}, {"enabled"})
    g = _block(d["gyro"], f"{w}.gyro", {"angle_random_walk_deg_sqrt_h", "bias_instability_deg_h",
                                         "bias_instability_tau_s", "rate_random_walk_deg_h_sqrt_h",
                                         "turn_on_bias_deg_h", "scale_factor_ppm", "misalignment_mrad"})
    a = _block(d["accel"], f"{w}.accel", {"velocity_random_walk_m_s_sqrt_h", "bias_instability_ug",
                                           "bias_instability_tau_s", "bias_random_walk_m_s2_sqrt_s",
                                           "turn_on_bias_ug", "scale_factor_ppm", "misalignment_mrad"})
    h = _block(d["ahrs"], f"{w}.ahrs", {"roll_pitch_noise_deg", "heading_noise_deg", "heading_drift_deg_h",
                                         "heading_random_walk_deg_sqrt_h"})

    def nn(doc, k, where):
        return _num(doc[k], f"{where}.{k}", nonneg=True)

    gw, aw = f"{w}.gyro", f"{w}.accel"
    gyro = GyroConfig(
        noise_density=nn(g, "angle_random_walk_deg_sqrt_h", gw) * DEG / 60.0,
        bias_instability=nn(g, "bias_instability_deg_h", gw) * DEG / 3600.0,
        bias_instability_tau_s=_num(g["bias_instability_tau_s"], f"{gw}.bias_instability_tau_s", positive=True),
        bias_random_walk=nn(g, "rate_random_walk_deg_h_sqrt_h", gw) * DEG / 3600.0 / 60.0,
        turn_on_bias=nn(g, "turn_on_bias_deg_h", gw) * DEG / 3600.0,
        scale_factor=nn(g, "scale_factor_ppm", gw) * PPM,
        misalignment=nn(g, "misalignment_mrad", gw) * 1e-3)
    accel = AccelConfig(
        noise_density=nn(a, "velocity_random_walk_m_s_sqrt_h", aw) / 60.0,
        bias_instability=nn(a, "bias_instability_ug", aw) * UG,
        bias_instability_tau_s=_num(a["bias_instability_tau_s"], f"{aw}.bias_instability_tau_s", positive=True),
        bias_random_walk=nn(a, "bias_random_walk_m_s2_sqrt_s", aw),
        turn_on_bias=nn(a, "turn_on_bias_ug", aw) * UG,
        scale_factor=nn(a, "scale_factor_ppm", aw) * PPM,
        misalignment=nn(a, "misalignment_mrad", aw) * 1e-3)
    hw = f"{w}.ahrs"
    ahrs = AhrsConfig(roll_pitch_noise=nn(h, "roll_pitch_noise_deg", hw) * DEG,
                      heading_noise=nn(h, "heading_noise_deg", hw) * DEG,
                      heading_drift=nn(h, "heading_drift_deg_h", hw) * DEG / 3600.0,
                      heading_random_walk=nn(h, "heading_random_walk_deg_sqrt_h", hw) * DEG / 60.0)
    return ImuConfig(_num(d["rate_hz"], f"{w}.rate_hz", positive=True), _frame(d["frame_id"], f"{w}.frame_id"),
                     Mounting.from_mapping(d["mounting"], f"{w}.mounting"), gyro, accel, ahrs)


def _pressure(d: Mapping[str, Any], w: str) -> PressureConfig:
    d = _block(d, w, _COMMON | {"noise_pa", "resolution_pa", "offset_pa", "atmospheric_pressure_pa"}, {"enabled"})
    return PressureConfig(
        _num(d["rate_hz"], f"{w}.rate_hz", positive=True), _frame(d["frame_id"], f"{w}.frame_id"),
        Mounting.from_mapping(d["mounting"], f"{w}.mounting"), _num(d["noise_pa"], f"{w}.noise_pa", nonneg=True),
        _num(d["resolution_pa"], f"{w}.resolution_pa", nonneg=True),
        _num(d["offset_pa"], f"{w}.offset_pa", nonneg=True),
        _num(d["atmospheric_pressure_pa"], f"{w}.atmospheric_pressure_pa", positive=True))


def _dvl(d: Mapping[str, Any], w: str) -> DvlConfig:
    d = _block(d, w, _COMMON | {"latency_s", "beam_angle_deg", "beam_azimuths_deg", "min_range_m", "max_range_m",
                                "max_beam_incidence_deg", "beam_noise_mps", "beam_noise_fraction",
                                "scale_factor_ppm", "water_track_noise_mps"}, {"enabled"})
    az = d["beam_azimuths_deg"]
    if not isinstance(az, (list, tuple)) or len(az) < 3:
        raise SensorConfigError(f"{w}.beam_azimuths_deg must list at least 3 beams, got {az!r}")
    angle = _num(d["beam_angle_deg"], f"{w}.beam_angle_deg", positive=True, le=60.0)
    lo, hi = _num(d["min_range_m"], f"{w}.min_range_m", nonneg=True), _num(d["max_range_m"], f"{w}.max_range_m",
                                                                             positive=True)
    if hi <= lo:
        raise SensorConfigError(f"{w}: max_range_m must exceed min_range_m, got {lo:g} .. {hi:g}")
    return DvlConfig(
        _num(d["rate_hz"], f"{w}.rate_hz", positive=True), _num(d["latency_s"], f"{w}.latency_s", nonneg=True),
        _frame(d["frame_id"], f"{w}.frame_id"), Mounting.from_mapping(d["mounting"], f"{w}.mounting"),
        angle * DEG, _vec(az, len(az), f"{w}.beam_azimuths_deg") * DEG, lo, hi,
        _num(d["max_beam_incidence_deg"], f"{w}.max_beam_incidence_deg", positive=True, le=90.0) * DEG,
        _num(d["beam_noise_mps"], f"{w}.beam_noise_mps", nonneg=True),
        _num(d["beam_noise_fraction"], f"{w}.beam_noise_fraction", nonneg=True),
        _num(d["scale_factor_ppm"], f"{w}.scale_factor_ppm", nonneg=True) * PPM,
        _num(d["water_track_noise_mps"], f"{w}.water_track_noise_mps", nonneg=True))


def _altimeter(d: Mapping[str, Any], w: str) -> AltimeterConfig:
    d = _block(d, w, _COMMON | {"min_range_m", "max_range_m", "noise_m", "noise_fraction", "field_of_view_deg",
                                "dropout_probability"}, {"enabled"})
    lo, hi = _num(d["min_range_m"], f"{w}.min_range_m", nonneg=True), _num(d["max_range_m"], f"{w}.max_range_m",
                                                                             positive=True)
    if hi <= lo:
        raise SensorConfigError(f"{w}: max_range_m must exceed min_range_m, got {lo:g} .. {hi:g}")
    return AltimeterConfig(
        _num(d["rate_hz"], f"{w}.rate_hz", positive=True), _frame(d["frame_id"], f"{w}.frame_id"),
        Mounting.from_mapping(d["mounting"], f"{w}.mounting"), lo, hi,
        _num(d["noise_m"], f"{w}.noise_m", nonneg=True), _num(d["noise_fraction"], f"{w}.noise_fraction", nonneg=True),
        _num(d["field_of_view_deg"], f"{w}.field_of_view_deg", positive=True, le=180.0) * DEG,
        _num(d["dropout_probability"], f"{w}.dropout_probability", nonneg=True, le=1.0))


def _gps(d: Mapping[str, Any], w: str) -> GpsConfig:
    d = _block(d, w, _COMMON | {"horizontal_noise_m", "vertical_noise_m", "time_to_first_fix_s",
                                "min_antenna_height_m", "origin"}, {"enabled"})
    o = _block(d["origin"], f"{w}.origin", {"latitude_deg", "longitude_deg", "altitude_m"})
    lat = _num(o["latitude_deg"], f"{w}.origin.latitude_deg")
    if abs(lat) >= 89.0:
        raise SensorConfigError(f"{w}.origin.latitude_deg must be within (-89, 89), got {lat!r}")
    return GpsConfig(
        _num(d["rate_hz"], f"{w}.rate_hz", positive=True), _frame(d["frame_id"], f"{w}.frame_id"),
        Mounting.from_mapping(d["mounting"], f"{w}.mounting"),
        _num(d["horizontal_noise_m"], f"{w}.horizontal_noise_m", nonneg=True),
        _num(d["vertical_noise_m"], f"{w}.vertical_noise_m", nonneg=True),
        _num(d["time_to_first_fix_s"], f"{w}.time_to_first_fix_s", nonneg=True),
        _num(d["min_antenna_height_m"], f"{w}.min_antenna_height_m"),
        lat, _num(o["longitude_deg"], f"{w}.origin.longitude_deg", le=180.0), _num(o["altitude_m"],
                                                                                    f"{w}.origin.altitude_m"))


_BUILD = {"imu": _imu, "pressure": _pressure, "dvl": _dvl, "altimeter": _altimeter, "gps": _gps}


# ------------------------------------------------------------------------------------------ loading
def _merge(base: Mapping[str, Any], over: Mapping[str, Any]) -> dict[str, Any]:
    out = dict(base)
    for k, v in over.items():
        out[k] = _merge(out[k], v) if isinstance(v, Mapping) and isinstance(out.get(k), Mapping) else v
    return out


def _read(file: Path) -> dict[str, Any]:
    try:
        doc = load_yaml(file.read_text(encoding="utf-8"))
    except OSError as e:
        raise SensorConfigError(f"{file}: cannot read the sensor suite ({e.strerror})") from None
    except UnicodeDecodeError as e:
        raise SensorConfigError(f"{file}: not UTF-8 text (byte {e.start})") from None
    except yaml.YAMLError as e:
        raise SensorConfigError(f"{file}: not valid YAML ({e})") from None
    if not isinstance(doc, dict):
        raise SensorConfigError(f"{file}: expected a mapping (a sensor suite), got {type(doc).__name__}")
    return doc


def _resolve_document(doc: Mapping[str, Any], base_dir: Path | None, depth: int = 0) -> dict[str, Any]:
    doc = dict(doc)
    base = doc.pop("base", None)
    if base is None:
        return doc
    if depth > 8:
        raise SensorConfigError("base: chain deeper than 8 files (a loop?)")
    return _merge(_resolve_document(_read(_resolve(base, base_dir)), base_dir, depth + 1), doc)


def _resolve(spec: str, base_dir: Path | None) -> Path:
    if not isinstance(spec, str) or not spec:
        raise SensorConfigError(f"a sensor suite is {' | '.join(PRESETS)} | FILE.yaml, got {spec!r}")
    if spec in PRESETS:
        return PRESETS[spec]
    p = Path(spec).expanduser()
    if not p.is_absolute() and base_dir is not None and (base_dir / p).exists():
        return base_dir / p
    if not p.exists():
        raise SensorConfigError(f"sensor suite {spec!r} is neither a preset ({', '.join(PRESETS)}) nor a file")
    return p


def suite_config_from_mapping(doc: Mapping[str, Any], *, where: str = "sensor suite",
                              base_dir: Path | None = None, name: str = "suite") -> SuiteConfig:
    """Validate a suite document (``base:`` resolved first) into a :class:`SuiteConfig`."""
    try:
        doc = _resolve_document(doc, base_dir)
        fmt = doc.get("format", FORMAT)
        if fmt != FORMAT:
            raise SensorConfigError(f"format is {fmt!r}, expected {FORMAT!r}")
        allowed = set(SENSOR_NAMES) | {"format", "name", "description", "faults"}
        unknown = sorted(set(doc) - allowed)
        if unknown:
            raise SensorConfigError(f"unknown key(s) {unknown}{unknown_keys_hint(unknown, allowed)}; "
                                    f"allowed: {sorted(allowed)}")
        kw: dict[str, Any] = {}
        for s in SENSOR_NAMES:
            block = doc.get(s)
            if block is None:
                continue
            if not isinstance(block, Mapping):
                raise SensorConfigError(f"{s} must be a mapping (or null: no {s}), got {block!r}")
            enabled = block.get("enabled", True)
            if not isinstance(enabled, bool):
                raise SensorConfigError(f"{s}.enabled must be true or false, got {enabled!r}")
            if enabled:
                kw[s] = _BUILD[s](block, s)
        faults = faults_from_list(doc.get("faults"))
        for f in faults:
            if f.sensor not in kw:
                raise SensorConfigError(f"a fault names the {f.sensor}, which this suite does not have")
        return SuiteConfig(name=str(doc.get("name", name)), faults=faults, source=where,
                           description=str(doc.get("description", "")).strip(), document=doc, **kw)
    except SensorConfigError as e:
        raise SensorConfigError(f"{where}: {e}") from None


def load_suite_config(spec: "str | Path | Mapping[str, Any]", *, base_dir: Path | None = None) -> SuiteConfig:
    """A preset name (``tactical``, ``mems``), a suite file, or an inline mapping -> :class:`SuiteConfig`."""
    if isinstance(spec, Mapping):
        return suite_config_from_mapping(spec, where="inline sensor suite", base_dir=base_dir)
    p = _resolve(str(spec), base_dir)
    return suite_config_from_mapping(_read(p), where=str(p), base_dir=p.parent, name=p.stem)


# ------------------------------------------------------------------------------------------ mission block
NAVIGATION_MODES = ("truth", "sensors")


@dataclass(frozen=True)
class SensorSpec:
    """The ``sensors:`` block of a mission: the suite, its seed and the mission's faults (added to the suite's)."""

    suite: SuiteConfig
    seed: int = 0
    faults: tuple[FaultSpec, ...] = ()
    suite_source: str = ""

    def all_faults(self) -> tuple[FaultSpec, ...]:
        return self.suite.faults + self.faults


def sensors_from_mapping(doc: Any, *, base_dir: Path | None = None, where: str = "sensors") -> SensorSpec | None:
    """``sensors: tactical | mems | FILE | none`` or ``sensors: {suite: ..., seed: 0, faults: [...]}``
    (``suite`` may also be an inline suite mapping).  None / ``none``: no sensor suite."""
    if doc is None or (isinstance(doc, str) and doc.lower() == "none"):
        return None
    if isinstance(doc, str):
        doc = {"suite": doc}
    if not isinstance(doc, Mapping):
        raise SensorConfigError(f"{where} must be tactical | mems | FILE | none, or a mapping with suite, seed, "
                                f"faults; got {doc!r}")
    bad = sorted(set(doc) - {"suite", "seed", "faults"})
    if bad:
        hint = unknown_keys_hint(bad, ("faults", "seed", "suite"))
        raise SensorConfigError(f"unknown key(s) in {where}: {bad}{hint}; allowed: ['faults', 'seed', 'suite']")
    spec = doc.get("suite", "tactical")
    suite = load_suite_config(spec, base_dir=base_dir)
    seed = doc.get("seed", 0)
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise SensorConfigError(f"{where}.seed must be an integer >= 0, got {seed!r}")
    faults = faults_from_list(doc.get("faults"), f"{where}.faults")
    present = suite.sensors()
    for f in faults:
        if f.sensor not in present:
            raise SensorConfigError(f"{where}.faults names the {f.sensor}, which the suite {suite.name!r} does not "
                                    f"have")
    return SensorSpec(suite, int(seed), faults, spec if isinstance(spec, str) else "inline")


def navigation_from_value(v: Any, sensors: SensorSpec | None, where: str = "navigation") -> str:
    if v is None:
        return "truth"
    if v not in NAVIGATION_MODES:
        raise SensorConfigError(f"{where} must be one of {list(NAVIGATION_MODES)}, got {v!r}")
    if v == "sensors" and sensors is None:
        raise SensorConfigError(f"{where}: sensors needs a sensors: block (the suite to navigate on)")
    return str(v)
