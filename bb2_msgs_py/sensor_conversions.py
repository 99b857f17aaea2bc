"""Sensor-model samples (:mod:`bb2_sim.sensors`) <-> standard messages of ``/bb2/sensors/*`` (contract rows).

The builders import the message packages inside the functions (this module imports without rclpy).

=========================  ===========================================  ==========================================
sample                     message                                      notes
=========================  ===========================================  ==========================================
``ImuSample``              ``sensor_msgs/Imu`` (imu_link)               orientation of imu_link in ENU (REP-145),
                                                                        covariances row-major 3x3
``PressureSample``         ``sensor_msgs/FluidPressure``                absolute Pa, variance Pa^2
``DvlSample`` locked       ``geometry_msgs/TwistWithCovarianceStamped`` on ``/bb2/sensors/dvl``; angular block of
                                                                        the covariance -1 (not measured)
``DvlSample`` unlocked     the same type                                on ``/bb2/sensors/dvl/water_track``
DVL beams                  ``sensor_msgs/Range`` per beam               frame :func:`dvl_beam_frame` (x along the
                                                                        beam), +inf no echo
``AltimeterSample``        ``sensor_msgs/Range`` (ULTRASOUND)           REP-117 +inf / -inf
``GpsSample``              ``sensor_msgs/NavSatFix``                    STATUS_FIX / STATUS_NO_FIX, service GPS,
                                                                        covariance DIAGONAL_KNOWN (UNKNOWN: none)
=========================  ===========================================  ==========================================
"""
from __future__ import annotations

import json
import math
from typing import Any

import numpy as np

from .contract import FRAME_BASE_LINK
from .conversions import _header

__all__ = ["DVL_TOPIC", "DVL_WATER_TOPIC", "DVL_RANGES_TOPIC", "SENSOR_TOPICS", "MOUNTINGS_FORMAT",
           "dvl_beam_frame", "imu_sample_message", "pressure_sample_message", "dvl_sample_message",
           "dvl_range_messages", "altimeter_sample_message", "gps_sample_message", "sample_messages",
           "mountings_description", "mountings_json", "imu_sample_from_message", "dvl_from_message",
           "gps_from_message", "NAVIGATION_SENSOR_TOPICS", "sample_from_message", "sample_order"]

from bb2_sim.sensors.samples import sample_order  # noqa: E402  (sort the samples read back from the topics)

DVL_TOPIC = "/bb2/sensors/dvl"
DVL_WATER_TOPIC = "/bb2/sensors/dvl/water_track"
DVL_RANGES_TOPIC = "/bb2/sensors/dvl/ranges"
SENSOR_TOPICS = ("/bb2/sensors/imu", "/bb2/sensors/pressure", DVL_TOPIC, DVL_WATER_TOPIC, DVL_RANGES_TOPIC,
                 "/bb2/sensors/altimeter", "/bb2/sensors/gps", "/bb2/sensors/mountings")
#: the topics whose messages the navigation filter (bb2_control.navigation) takes, in its sensors' order
NAVIGATION_SENSOR_TOPICS = ("/bb2/sensors/imu", "/bb2/sensors/pressure", DVL_TOPIC, DVL_WATER_TOPIC,
                            "/bb2/sensors/gps")
MOUNTINGS_FORMAT = "bb2_sensor_mountings/1"
DVL_BEAM_FOV_RAD = 0.035   # ~2 deg: the beam width of the Range messages of the DVL beams (nominal)


def dvl_beam_frame(dvl_frame: str, i: int) -> str:
    """The frame of DVL beam ``i`` (x along the beam), child of the DVL's frame."""
    return f"{dvl_frame.removesuffix('_link')}_beam_{i}"


def _cov9(c) -> np.ndarray:
    return np.ascontiguousarray(np.asarray(c, dtype=float).reshape(9))


def imu_sample_message(s):
    from geometry_msgs.msg import Quaternion, Vector3
    from sensor_msgs.msg import Imu

    q, w, f = s.orientation_xyzw.tolist(), s.angular_velocity.tolist(), s.specific_force.tolist()
    return Imu(header=_header(s.t, s.frame_id), orientation=Quaternion(x=q[0], y=q[1], z=q[2], w=q[3]),
               orientation_covariance=_cov9(s.orientation_covariance),
               angular_velocity=Vector3(x=w[0], y=w[1], z=w[2]),
               angular_velocity_covariance=_cov9(s.angular_velocity_covariance),
               linear_acceleration=Vector3(x=f[0], y=f[1], z=f[2]),
               linear_acceleration_covariance=_cov9(s.specific_force_covariance))


def imu_sample_from_message(msg) -> dict[str, Any]:
    o, w, f = msg.orientation, msg.angular_velocity, msg.linear_acceleration
    return {"t": msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9, "frame_id": msg.header.frame_id,
            "q_xyzw": np.array([o.x, o.y, o.z, o.w]), "w": np.array([w.x, w.y, w.z]),
            "f": np.array([f.x, f.y, f.z]),
            "cov_q": np.array(msg.orientation_covariance).reshape(3, 3),
            "cov_w": np.array(msg.angular_velocity_covariance).reshape(3, 3),
            "cov_f": np.array(msg.linear_acceleration_covariance).reshape(3, 3)}


def pressure_sample_message(s):
    from sensor_msgs.msg import FluidPressure

    return FluidPressure(header=_header(s.t, s.frame_id), fluid_pressure=float(s.pressure_pa),
                         variance=float(s.variance_pa2))


def dvl_sample_message(s):
    """``TwistWithCovarianceStamped`` of a DVL ping (bottom or water track: the caller picks the topic)."""
    from geometry_msgs.msg import Twist, TwistWithCovariance, TwistWithCovarianceStamped, Vector3

    cov = np.zeros((6, 6))
    cov[0:3, 0:3] = s.covariance
    cov[3, 3] = cov[4, 4] = cov[5, 5] = -1.0      # angular velocity not measured
    v = s.velocity.tolist()
    return TwistWithCovarianceStamped(
        header=_header(s.t, s.frame_id),
        twist=TwistWithCovariance(twist=Twist(linear=Vector3(x=v[0], y=v[1], z=v[2]), angular=Vector3()),
                                  covariance=np.ascontiguousarray(cov.reshape(36))))


def dvl_from_message(msg) -> dict[str, Any]:
    v = msg.twist.twist.linear
    return {"t": msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9, "frame_id": msg.header.frame_id,
            "v": np.array([v.x, v.y, v.z]), "cov": np.array(msg.twist.covariance).reshape(6, 6)[0:3, 0:3]}


def _range(t: float, frame_id: str, r: float, variance: float, fov: float, lo: float, hi: float):
    from sensor_msgs.msg import Range

    return Range(header=_header(t, frame_id), radiation_type=Range.ULTRASOUND, field_of_view=float(fov),
                 min_range=float(lo), max_range=float(hi), range=float(r), variance=float(variance))


def dvl_range_messages(s, min_range_m: float, max_range_m: float, noise_m: float = 0.0):
    """One ``Range`` per beam (frame :func:`dvl_beam_frame`), +inf without an echo."""
    return [_range(s.t, dvl_beam_frame(s.frame_id, i), float(r) if ok else math.inf, noise_m ** 2,
                   DVL_BEAM_FOV_RAD, min_range_m, max_range_m)
            for i, (r, ok) in enumerate(zip(s.beam_ranges_m, s.beam_valid))]


def altimeter_sample_message(s):
    return _range(s.t, s.frame_id, s.range_m, s.variance_m2, s.field_of_view_rad, s.min_range_m, s.max_range_m)


def gps_sample_message(s):
    from sensor_msgs.msg import NavSatFix, NavSatStatus

    st = NavSatStatus(status=NavSatStatus.STATUS_FIX if s.fix else NavSatStatus.STATUS_NO_FIX,
                      service=NavSatStatus.SERVICE_GPS)
    if s.fix:
        cov, kind = _cov9(s.covariance_enu), NavSatFix.COVARIANCE_TYPE_DIAGONAL_KNOWN
    else:
        cov, kind = np.zeros(9), NavSatFix.COVARIANCE_TYPE_UNKNOWN
    return NavSatFix(header=_header(s.t, s.frame_id), status=st, latitude=float(s.latitude_deg),
                     longitude=float(s.longitude_deg), altitude=float(s.altitude_m), position_covariance=cov,
                     position_covariance_type=kind)


def gps_from_message(msg) -> dict[str, Any]:
    return {"t": msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9, "fix": msg.status.status >= 0,
            "lat": msg.latitude, "lon": msg.longitude, "alt": msg.altitude,
            "cov": np.array(msg.position_covariance).reshape(3, 3)}


def sample_messages(s, suite_config=None, *, frame_prefix: str = "") -> list[tuple[str, Any]]:
    """(topic, message) pairs of one sample (a DVL ping gives its velocity and one range per beam); the frame ids
    carry the vehicle's ``frame_prefix`` (:func:`bb2_msgs_py.contract.frame_prefix`: ``boat1/imu_link``)."""
    out = _sample_messages(s, suite_config)
    if frame_prefix:
        for _topic, msg in out:
            msg.header.frame_id = frame_prefix + msg.header.frame_id
    return out


def _sample_messages(s, suite_config) -> list[tuple[str, Any]]:
    kind = s.sensor
    if kind == "imu":
        return [("/bb2/sensors/imu", imu_sample_message(s))]
    if kind == "pressure":
        return [("/bb2/sensors/pressure", pressure_sample_message(s))]
    if kind == "altimeter":
        return [("/bb2/sensors/altimeter", altimeter_sample_message(s))]
    if kind == "gps":
        return [("/bb2/sensors/gps", gps_sample_message(s))]
    if kind == "dvl":
        out = [(DVL_TOPIC if s.bottom_lock else DVL_WATER_TOPIC, dvl_sample_message(s))]
        d = suite_config.dvl if suite_config is not None else None
        lo, hi = (d.min_range_m, d.max_range_m) if d is not None else (0.0, math.inf)
        return out + [(DVL_RANGES_TOPIC, m) for m in dvl_range_messages(s, lo, hi)]
    raise ValueError(f"no message for a sample of {kind!r}")


def _quat_of_rpy(r: float, p: float, y: float) -> list[float]:
    cr, sr, cp, sp, cy, sy = (math.cos(r / 2), math.sin(r / 2), math.cos(p / 2), math.sin(p / 2),
                              math.cos(y / 2), math.sin(y / 2))
    return [sr * cp * cy - cr * sp * sy, cr * sp * cy + sr * cp * sy, cr * cp * sy - sr * sp * cy,
            cr * cp * cy + sr * sp * sy]


def mountings_description(suite_config, seed: int = 0, parent: str = FRAME_BASE_LINK, *,
                          frame_prefix: str = "") -> dict[str, Any]:
    """The static transforms ``parent -> sensor frame`` (and ``dvl frame -> each beam``) and the rates, as the
    JSON latched on ``/bb2/sensors/mountings`` (format ``bb2_sensor_mountings/1``); every frame id carries the
    vehicle's ``frame_prefix`` (``boat1/base_link -> boat1/imu_link``)."""
    tfs, rates = [], {}
    parent = frame_prefix + parent
    for name, c in suite_config.sensors().items():
        m = c.mounting
        child = frame_prefix + c.frame_id
        tfs.append({"parent": parent, "child": child, "translation_m": [float(v) for v in m.position_flu],
                    "rotation_xyzw": _quat_of_rpy(*[float(a) for a in m.rpy_rad])})
        rates[name] = float(c.rate_hz)
        if name == "dvl":
            for i, b in enumerate(c.beams_dvl()):
                # beam frame: x along the beam (Range convention); yaw = azimuth, pitch down to the beam
                yaw = math.atan2(b[1], b[0])
                pitch = math.atan2(-b[2], math.hypot(b[0], b[1]))
                tfs.append({"parent": child, "child": dvl_beam_frame(child, i),
                            "translation_m": [0.0, 0.0, 0.0], "rotation_xyzw": _quat_of_rpy(0.0, pitch, yaw)})
    return {"format": MOUNTINGS_FORMAT, "suite": suite_config.name, "seed": int(seed), "source": suite_config.source,
            "transforms": tfs, "rates_hz": rates}


def mountings_json(suite_config, seed: int = 0, *, frame_prefix: str = "") -> str:
    return json.dumps(mountings_description(suite_config, seed, frame_prefix=frame_prefix), allow_nan=False)


# ---------------------------------------------------------------------------------------- messages -> samples
def _cov(values, n: int, where: str) -> np.ndarray:
    from .conversions import ConversionError

    c = np.array(values, dtype=float)
    if c.size != n * n:
        raise ConversionError(f"{where}: a covariance of {n * n} numbers expected, got {c.size}")
    return c.reshape(n, n)


def sample_from_message(topic: str, msg, suite_config=None, *, frame_prefix: str = ""):
    """The sensor sample (:mod:`bb2_sim.sensors.samples`) a ``/bb2/sensors/*`` message carries: the inverse of
    :func:`sample_messages`, for an autopilot that reads the sensor topics (the navigation filter takes these).

    ``t`` is the header stamp (to the nanosecond); ``t_available`` adds the latency of the suite's sensor where the
    sample has one (the DVL; none without ``suite_config``).  A DVL message gives no beam ranges (those come on
    ``/bb2/sensors/dvl/ranges``).  A GPS fix is turned back to ``map`` (ENU) about the suite's origin, so a GPS
    message needs ``suite_config``.  Raises ``ConversionError`` for a topic that carries no sample of these kinds or
    a frame other than the suite's (with the vehicle's ``frame_prefix``, which the sample's frame drops)."""
    from bb2_sim.sensors.geodesy import geodetic_to_enu
    from bb2_sim.sensors.samples import DvlSample, GpsSample, ImuSample, PressureSample

    from .conversions import ConversionError, stamp_to_seconds

    kinds = {"/bb2/sensors/imu": "imu", "/bb2/sensors/pressure": "pressure", DVL_TOPIC: "dvl", DVL_WATER_TOPIC: "dvl",
             "/bb2/sensors/gps": "gps"}
    kind = kinds.get(topic)
    if kind is None:
        raise ConversionError(f"no sensor sample is carried on {topic!r} (the sample topics: {sorted(kinds)})")
    t = stamp_to_seconds(msg.header.stamp)
    frame = msg.header.frame_id
    if frame_prefix and not frame.startswith(frame_prefix):
        raise ConversionError(f"{topic}: frame_id {frame!r} is not of this vehicle (frames {frame_prefix}*)")
    frame = frame.removeprefix(frame_prefix)
    cfg = suite_config.sensors().get(kind) if suite_config is not None else None
    if suite_config is not None:
        if cfg is None:
            raise ConversionError(f"{topic}: the suite {suite_config.name!r} has no {kind}")
        if frame != cfg.frame_id:
            raise ConversionError(f"{topic}: frame_id {msg.header.frame_id!r}, the suite's {kind} is mounted as "
                                  f"{frame_prefix + cfg.frame_id!r}")
    if kind == "imu":
        o, w, f = msg.orientation, msg.angular_velocity, msg.linear_acceleration
        return ImuSample("imu", t, t, frame, np.array([w.x, w.y, w.z]), np.array([f.x, f.y, f.z]),
                         np.array([o.x, o.y, o.z, o.w]), _cov(msg.orientation_covariance, 3, topic),
                         _cov(msg.angular_velocity_covariance, 3, topic),
                         _cov(msg.linear_acceleration_covariance, 3, topic))
    if kind == "pressure":
        return PressureSample("pressure", t, t, frame, float(msg.fluid_pressure), float(msg.variance))
    if kind == "dvl":
        v = msg.twist.twist.linear
        latency = float(cfg.latency_s) if cfg is not None else 0.0
        return DvlSample("dvl", t, t + latency, frame, topic == DVL_TOPIC, np.array([v.x, v.y, v.z]),
                         _cov(msg.twist.covariance, 6, topic)[0:3, 0:3], np.zeros(0), np.zeros(0, bool))
    if suite_config is None:
        raise ConversionError(f"{topic}: a GPS fix needs the suite (its map origin) to give a position in map")
    from sensor_msgs.msg import NavSatStatus

    origin = (float(cfg.origin_lat_deg), float(cfg.origin_lon_deg), float(cfg.origin_alt_m))
    fix = msg.status.status >= NavSatStatus.STATUS_FIX
    lat, lon, alt = float(msg.latitude), float(msg.longitude), float(msg.altitude)
    p = geodetic_to_enu(lat, lon, alt, *origin) if fix else np.full(3, math.nan)
    cov = _cov(msg.position_covariance, 3, topic) if fix else np.full((3, 3), math.nan)
    return GpsSample("gps", t, t, frame, bool(fix), lat, lon, alt, np.asarray(p, float).reshape(3), cov, origin)
