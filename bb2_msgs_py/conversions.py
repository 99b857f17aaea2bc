"""numpy <-> ROS 2 message conversions of the BB2 contract.

The numerical functions (``*_arrays``, :func:`specific_force_flu`, :func:`depth_to_pressure` ...)
are plain numpy; the message builders import the ROS message packages inside the function, so
this module imports without rclpy.

Conventions (see :mod:`bb2_msgs_py.contract` and :mod:`bb2_sim.frames`, the only frame math):

* the ROM state is native (earth z up, bow along -x at psi = 0; body x aft / y stbd / z up);
  messages are REP-103: world ENU, body FLU (``base_link``).
* plane deflections are radians in messages (ROM sign convention, unchanged), degrees only in the
  ``*_deg`` helpers at the edges.
* a time ``t`` (s) becomes a stamp of whole nanoseconds (``round(t * 1e9)``).
"""
from __future__ import annotations

import math
import struct
from functools import lru_cache
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from bb2_sim import frames
from bb2_sim.state import VehicleState

from .contract import (BERNSTEIN_POINTS_LABEL, FRAME_BASE_LINK, FRAME_MAP, FRAME_ODOM, FRAME_PATH,
                       PLANE_JOINTS, PROPELLER_JOINT, STATE_NATIVE_LABEL, VH_JOINTS, ContractError)

SENSORS_YAML = Path(__file__).resolve().parent / "data" / "sensors.yaml"


class ConversionError(ContractError):
    """A message or array that cannot be converted (wrong names, sizes, frames, non-finite)."""


@lru_cache(maxsize=1)
def sensor_model() -> dict[str, Any]:
    """The sensor model constants of ``data/sensors.yaml`` (units in the key names)."""
    from bb2_sim.yaml_files import load as load_yaml

    with open(SENSORS_YAML, encoding="utf-8") as fh:
        return load_yaml(fh)


# ----------------------------------------------------------------------------------------- time
def seconds_to_ns(t: float) -> int:
    """Seconds -> integer nanoseconds (rounded)."""
    if not math.isfinite(t):
        raise ConversionError(f"time must be finite, got {t!r}")
    return int(round(t * 1e9))


def _stamp_parts(t: float) -> tuple[int, int]:
    """(sec, nanosec) of a stamp of ``t`` seconds (t >= 0)."""
    ns = seconds_to_ns(t)
    if ns < 0:
        raise ConversionError(f"stamps must be >= 0 s, got {t!r}")
    return divmod(ns, 1_000_000_000)


def stamp(t: float):
    """``builtin_interfaces/Time`` of ``t`` seconds (t >= 0)."""
    from builtin_interfaces.msg import Time

    sec, nanosec = _stamp_parts(t)
    return Time(sec=sec, nanosec=nanosec)


def stamp_to_seconds(st) -> float:
    """Seconds of a ``builtin_interfaces/Time``."""
    return st.sec + st.nanosec * 1e-9


def stamp_to_ns(st) -> int:
    """Integer nanoseconds of a ``builtin_interfaces/Time``."""
    return st.sec * 1_000_000_000 + st.nanosec


def leading_stamp_ns(cdr: bytes) -> int:
    """Integer nanoseconds of the ``builtin_interfaces/Time`` a serialized message starts with (a ``std_msgs/Header``'s
    stamp: every stamped message; ``rosgraph_msgs/Clock``), read from the CDR bytes without deserializing them:
    after the 4-byte encapsulation header (its second byte 1: little endian, 0: big endian) come ``int32 sec`` and
    ``uint32 nanosec``."""
    if len(cdr) < 12 or cdr[1] not in (0, 1):
        raise ConversionError(f"not a CDR message starting with a stamp ({len(cdr)} bytes, encapsulation "
                              f"{bytes(cdr[:2]).hex() or 'none'})")
    sec, nanosec = struct.unpack_from("<iI" if cdr[1] else ">iI", cdr, 4)
    return sec * 1_000_000_000 + nanosec


def _header(t: float, frame_id: str):
    from std_msgs.msg import Header

    return Header(stamp=stamp(t), frame_id=frame_id)


def _fill_header(header, t: float, frame_id: str) -> None:
    """Write :func:`_header`'s stamp and frame into an existing ``std_msgs/Header``."""
    header.stamp.sec, header.stamp.nanosec = _stamp_parts(t)
    header.frame_id = frame_id


def _stamped(cls, t: float, frame_id: str):
    """A new stamped message ``cls()`` with its header written: rclpy builds every nested default of a message before
    the keyword values given, so ``cls(header=...)`` would build a header twice."""
    msg = cls()
    _fill_header(msg.header, t, frame_id)
    return msg


def clock_message(t: float):
    """``rosgraph_msgs/Clock`` at ``t`` seconds."""
    from rosgraph_msgs.msg import Clock

    return Clock(clock=stamp(t))


def _vec3(a) -> np.ndarray:
    a = np.asarray(a, dtype=float)
    if a.shape != (3,):
        raise ConversionError(f"expected a 3-vector, got shape {a.shape}")
    return a


# ----------------------------------------------------------------------------------------- odometry
def state_to_enu_arrays(state: VehicleState) -> dict[str, np.ndarray]:
    """ROM state -> REP-103 arrays: ``p_enu``, ``q_enu_flu`` (x, y, z, w), ``v_flu``, ``w_flu``."""
    phi, theta, psi = (float(x) for x in state.euler_native)
    return {
        "p_enu": frames.earth_native_to_enu(_vec3(state.p_native)),
        "q_enu_flu": np.array(frames.quaternion_enu_flu(phi, theta, psi)),
        "v_flu": frames.body_native_to_flu(_vec3(state.v_body_native)),
        "w_flu": frames.body_native_to_flu(_vec3(state.w_body_native)),
    }


def enu_arrays_to_state(t: float, p_enu, q_enu_flu, v_flu, w_flu) -> VehicleState:
    """Inverse of :func:`state_to_enu_arrays` (psi wrapped to (-pi, pi])."""
    R_enu_flu = frames.rotation_from_quaternion(np.asarray(q_enu_flu, dtype=float))
    R_native = frames.D_FLIP @ R_enu_flu @ frames.D_FLIP
    phi, theta, psi = frames.euler_from_rotation(R_native)
    return VehicleState(
        t=float(t),
        p_native=frames.earth_enu_to_native(_vec3(p_enu)),
        euler_native=np.array([phi, theta, psi]),
        v_body_native=frames.body_flu_to_native(_vec3(v_flu)),
        w_body_native=frames.body_flu_to_native(_vec3(w_flu)),
    )


@lru_cache(maxsize=16)
def _diag_cached(n: int, variance: float) -> np.ndarray:
    a = np.diag(np.full(n, float(variance))).ravel()
    a.setflags(write=False)
    return a


def _diag6(variance: float) -> np.ndarray:
    """Row-major 6x6 diagonal covariance (a fresh float64 array; the message field takes it as is)."""
    return _diag_cached(6, float(variance)).copy()


def _diag3(variance: float) -> np.ndarray:
    """Row-major 3x3 diagonal covariance (a fresh float64 array)."""
    return _diag_cached(3, float(variance)).copy()


_ENU_MEMO: list = [None, None]  # (key, arrays) of the last state converted: odometry then IMU of one state


def _enu_arrays_memo(state: VehicleState) -> dict[str, np.ndarray]:
    """:func:`state_to_enu_arrays`, remembering the last state (the simulator converts each state twice:
    odometry at t_n, IMU once the step from t_n is integrated).  Keyed on the exact values."""
    key = (float(state.t), np.asarray(state.as_vector(), dtype=float).tobytes())
    if _ENU_MEMO[0] != key:
        _ENU_MEMO[0], _ENU_MEMO[1] = key, state_to_enu_arrays(state)
    return _ENU_MEMO[1]


def state_to_odometry(state: VehicleState, *, frame_id: str = FRAME_ODOM,
                      child_frame_id: str = FRAME_BASE_LINK,
                      pose_variance: float | None = None, twist_variance: float | None = None):
    """``nav_msgs/Odometry``: pose of ``base_link`` in ENU ``frame_id``, twist in ``base_link`` (FLU).

    Covariances are diagonal with the nominal variances of ``sensors.yaml`` unless given.
    """
    from nav_msgs.msg import Odometry

    return fill_odometry(Odometry(), state, frame_id=frame_id, child_frame_id=child_frame_id,
                         pose_variance=pose_variance, twist_variance=twist_variance)


def fill_odometry(msg, state: VehicleState, *, frame_id: str = FRAME_ODOM, child_frame_id: str = FRAME_BASE_LINK,
                  pose_variance: float | None = None, twist_variance: float | None = None):
    """Write :func:`state_to_odometry`'s every field into ``msg`` (a ``nav_msgs/Odometry``) and return it: a
    publisher may keep one message and refill it each step (publishing copies it), a fifth of the cost of building
    one (rclpy builds every nested default first)."""
    model = sensor_model()["odometry"]
    a = _enu_arrays_memo(state)
    p, q, v, w = a["p_enu"].tolist(), a["q_enu_flu"].tolist(), a["v_flu"].tolist(), a["w_flu"].tolist()
    _fill_header(msg.header, state.t, frame_id)
    msg.child_frame_id = child_frame_id
    pose, twist = msg.pose.pose, msg.twist.twist
    pose.position.x, pose.position.y, pose.position.z = p
    pose.orientation.x, pose.orientation.y, pose.orientation.z, pose.orientation.w = q
    msg.pose.covariance = _diag6(model["pose_variance"] if pose_variance is None else pose_variance)
    twist.linear.x, twist.linear.y, twist.linear.z = v
    twist.angular.x, twist.angular.y, twist.angular.z = w
    msg.twist.covariance = _diag6(model["twist_variance"] if twist_variance is None else twist_variance)
    return msg


def odometry_to_state(msg, *, child_frame_id: str = FRAME_BASE_LINK) -> VehicleState:
    """Inverse of :func:`state_to_odometry` (time from the header stamp); the twist must be in ``child_frame_id``
    (the vehicle's base_link: ``boat1/base_link`` for a boat in ``/boat1``) or unnamed."""
    if msg.child_frame_id not in (child_frame_id, ""):
        raise ConversionError(f"odometry twist must be in {child_frame_id!r}, got {msg.child_frame_id!r}")
    pp, qq = msg.pose.pose.position, msg.pose.pose.orientation
    lv, av = msg.twist.twist.linear, msg.twist.twist.angular
    return enu_arrays_to_state(stamp_to_seconds(msg.header.stamp), [pp.x, pp.y, pp.z],
                               [qq.x, qq.y, qq.z, qq.w], [lv.x, lv.y, lv.z], [av.x, av.y, av.z])


# ----------------------------------------------------------------------------------------- IMU
def specific_force_flu(state: VehicleState, v_dot_body_native, g_m_s2: float) -> np.ndarray:
    """Specific force at the CG in ``base_link`` (FLU), m/s^2, as an accelerometer measures it.

    ``f = a - g``: the inertial acceleration of the CG ``a = dv/dt|_body + w x v`` (native body,
    ``v_dot_body_native`` the body-frame derivative of (u, v, w)) minus gravity.  At rest and
    level it is (0, 0, +g) in FLU (the gravity reaction).
    """
    phi, theta, psi = (float(x) for x in state.euler_native)
    a_native = _vec3(v_dot_body_native) + np.cross(_vec3(state.w_body_native), _vec3(state.v_body_native))
    g_body_native = frames.rotation_native(phi, theta, psi).T @ np.array([0.0, 0.0, -float(g_m_s2)])
    return frames.body_native_to_flu(a_native - g_body_native)


def imu_message(state: VehicleState, f_flu, *, frame_id: str = FRAME_BASE_LINK,
                orientation_known: bool = True, variances: dict[str, float] | None = None):
    """``sensor_msgs/Imu`` from the ROM state and the specific force ``f_flu`` (FLU, m/s^2).

    Orientation is that of ``base_link`` in ENU.  With ``orientation_known=False`` the message
    marks the orientation unknown as its definition says (``orientation_covariance[0] = -1``).
    """
    from sensor_msgs.msg import Imu

    return fill_imu(Imu(), state, f_flu, frame_id=frame_id, orientation_known=orientation_known,
                    variances=variances)


def fill_imu(msg, state: VehicleState, f_flu, *, frame_id: str = FRAME_BASE_LINK, orientation_known: bool = True,
             variances: dict[str, float] | None = None):
    """Write :func:`imu_message`'s every field into ``msg`` (a ``sensor_msgs/Imu``) and return it (see
    :func:`fill_odometry`)."""
    model = sensor_model()["imu"]
    if variances:
        model = {**model, **variances}
    a = _enu_arrays_memo(state)
    q, w, f = a["q_enu_flu"].tolist(), a["w_flu"].tolist(), _vec3(f_flu).tolist()
    if orientation_known:
        q_cov = _diag3(model["orientation_variance_rad2"])
    else:
        q = [0.0, 0.0, 0.0, 1.0]
        q_cov = np.array([-1.0] + [0.0] * 8)
    _fill_header(msg.header, state.t, frame_id)
    msg.orientation.x, msg.orientation.y, msg.orientation.z, msg.orientation.w = q
    msg.orientation_covariance = q_cov
    msg.angular_velocity.x, msg.angular_velocity.y, msg.angular_velocity.z = w
    msg.angular_velocity_covariance = _diag3(model["angular_velocity_variance_rad2_s2"])
    msg.linear_acceleration.x, msg.linear_acceleration.y, msg.linear_acceleration.z = f
    msg.linear_acceleration_covariance = _diag3(model["linear_acceleration_variance_m2_s4"])
    return msg


def imu_to_arrays(msg) -> dict[str, Any]:
    """``q_enu_flu`` (None when the message marks it unknown), ``w_flu``, ``f_flu``, ``t``."""
    o, w, f = msg.orientation, msg.angular_velocity, msg.linear_acceleration
    known = msg.orientation_covariance[0] != -1.0
    return {"t": stamp_to_seconds(msg.header.stamp),
            "q_enu_flu": np.array([o.x, o.y, o.z, o.w]) if known else None,
            "w_flu": np.array([w.x, w.y, w.z]), "f_flu": np.array([f.x, f.y, f.z])}


# ----------------------------------------------------------------------------------------- depth, altitude
def depth_to_pressure(depth_m: float) -> float:
    """Absolute pressure (Pa) at ``depth_m`` (positive down): ``p_atm + rho g depth``."""
    w = sensor_model()["water"]
    return w["p_atm_pa"] + w["rho_kg_m3"] * w["g_m_s2"] * float(depth_m)


def pressure_to_depth(p_pa: float) -> float:
    """Inverse of :func:`depth_to_pressure`."""
    w = sensor_model()["water"]
    return (float(p_pa) - w["p_atm_pa"]) / (w["rho_kg_m3"] * w["g_m_s2"])


def depth_message(t: float, depth_m: float, *, frame_id: str = FRAME_BASE_LINK):
    """``sensor_msgs/FluidPressure`` of the CG depth (m, positive down)."""
    from sensor_msgs.msg import FluidPressure

    if not math.isfinite(depth_m):
        raise ConversionError(f"depth must be finite, got {depth_m!r}")
    msg = _stamped(FluidPressure, t, frame_id)
    msg.fluid_pressure = depth_to_pressure(depth_m)
    msg.variance = float(sensor_model()["depth_sensor"]["variance_pa2"])
    return msg


def depth_from_message(msg) -> float:
    """Depth (m, positive down) of a ``sensor_msgs/FluidPressure``."""
    return pressure_to_depth(msg.fluid_pressure)


def altitude_message(t: float, altitude_m: float, *, frame_id: str = FRAME_BASE_LINK):
    """``sensor_msgs/Range`` (float32 fields) of the altitude above the bottom.

    An altitude beyond ``max_range`` (or non-finite, no bottom) is published as ``+inf``.
    """
    from sensor_msgs.msg import Range

    m = sensor_model()["altimeter"]
    r = float(altitude_m)
    if not math.isfinite(r) or r > m["max_range_m"]:
        r = math.inf
    msg = _stamped(Range, t, frame_id)
    msg.radiation_type, msg.field_of_view = int(m["radiation_type"]), float(m["field_of_view_rad"])
    msg.min_range, msg.max_range = float(m["min_range_m"]), float(m["max_range_m"])
    msg.range, msg.variance = r, float(m["variance_m2"])
    return msg


def altitude_from_message(msg) -> float:
    """Altitude (m) of a ``sensor_msgs/Range`` (``inf`` = no bottom in range)."""
    return float(msg.range)


# ----------------------------------------------------------------------------------------- joints
def _joint_state(t: float, names: Sequence[str], *, position=None, velocity=None,
                 frame_id: str = FRAME_BASE_LINK):
    from sensor_msgs.msg import JointState

    msg = _stamped(JointState, t, frame_id)
    msg.name = list(names)
    if position is not None:
        msg.position = [float(x) for x in position]
    if velocity is not None:
        msg.velocity = [float(x) for x in velocity]
    return msg


def _by_name(msg, names: Sequence[str], field: str) -> np.ndarray:
    values = list(getattr(msg, field))
    if len(values) != len(msg.name):
        raise ConversionError(f"JointState has {len(msg.name)} names but {len(values)} {field} values")
    index = {n: i for i, n in enumerate(msg.name)}
    missing = [n for n in names if n not in index]
    if missing:
        raise ConversionError(f"JointState lacks joints {missing} (has {list(msg.name)})")
    return np.array([values[index[n]] for n in names], dtype=float)


def planes_message(t: float, delta_rad, *, velocity_rad_s=None, frame_id: str = FRAME_BASE_LINK):
    """JointState of the five plane deflections ``delta1..delta5`` (rad), for state or command."""
    d = np.asarray(delta_rad, dtype=float)
    if d.shape != (len(PLANE_JOINTS),):
        raise ConversionError(f"expected {len(PLANE_JOINTS)} plane deflections, got shape {d.shape}")
    return _joint_state(t, PLANE_JOINTS, position=d, velocity=velocity_rad_s, frame_id=frame_id)


def planes_from_message(msg) -> np.ndarray:
    """Plane deflections (rad) in the order delta1..delta5, whatever the message's joint order."""
    return _by_name(msg, PLANE_JOINTS, "position")


def planes_message_deg(t: float, delta_deg, **kw):
    """:func:`planes_message` from degrees (edge helper)."""
    return planes_message(t, np.radians(np.asarray(delta_deg, dtype=float)), **kw)


def planes_from_message_deg(msg) -> np.ndarray:
    """:func:`planes_from_message` in degrees (edge helper)."""
    return np.degrees(planes_from_message(msg))


def propeller_message(t: float, omega_rad_s: float, *, frame_id: str = FRAME_BASE_LINK):
    """JointState of the propeller shaft speed (rad/s), for state or command."""
    return _joint_state(t, (PROPELLER_JOINT,), velocity=[omega_rad_s], frame_id=frame_id)


def propeller_from_message(msg) -> float:
    """Propeller shaft speed (rad/s)."""
    return float(_by_name(msg, (PROPELLER_JOINT,), "velocity")[0])


def vh_message(t: float, delta_v_rad: float, delta_h_rad: float, *, frame_id: str = FRAME_BASE_LINK):
    """JointState of the autopilot's virtual plane commands (delta_V, delta_H), rad."""
    return _joint_state(t, VH_JOINTS, position=[delta_v_rad, delta_h_rad], frame_id=frame_id)


def vh_from_message(msg) -> tuple[float, float]:
    """(delta_V, delta_H), rad."""
    v = _by_name(msg, VH_JOINTS, "position")
    return float(v[0]), float(v[1])


# ----------------------------------------------------------------------------------------- guidance
def rate_command_message(t: float, q_c_native: float, r_c_native: float, *, frame_id: str = FRAME_BASE_LINK):
    """``geometry_msgs/Vector3Stamped`` of the rate commands as a FLU body rate (``frame_id``: the vehicle's
    base_link).

    The native (ROM) commands q_c (bow up > 0) and r_c (bow to port > 0) map to FLU as
    ``(x, y, z) = (0, -q_c, r_c)``.
    """
    from geometry_msgs.msg import Vector3Stamped

    w = frames.body_native_to_flu(np.array([0.0, float(q_c_native), float(r_c_native)]))
    msg = _stamped(Vector3Stamped, t, frame_id)
    msg.vector.x, msg.vector.y, msg.vector.z = w[0], w[1], w[2]
    return msg


def rate_command_from_message(msg, *, frame_id: str = FRAME_BASE_LINK) -> tuple[float, float]:
    """(q_c, r_c) native from a rate command; rejects a frame other than ``frame_id`` (the vehicle's base_link)."""
    if msg.header.frame_id != frame_id:
        raise ConversionError(f"rate command must be in {frame_id!r}, got {msg.header.frame_id!r}")
    w = frames.body_flu_to_native(np.array([msg.vector.x, msg.vector.y, msg.vector.z]))
    return float(w[1]), float(w[2])


def path_error_message(t: float, e_path, *, frame_id: str = FRAME_PATH):
    """``geometry_msgs/Vector3Stamped`` of the path error (m) in the path frame ``frame_id`` (x along, y left, z up;
    the vehicle's own: ``boat1/path_frenet`` for a boat in ``/boat1``)."""
    from geometry_msgs.msg import Vector3Stamped

    e = _vec3(e_path)
    msg = _stamped(Vector3Stamped, t, frame_id)
    msg.vector.x, msg.vector.y, msg.vector.z = e[0], e[1], e[2]
    return msg


def path_error_from_message(msg) -> np.ndarray:
    """Path error (m) in the path frame."""
    return np.array([msg.vector.x, msg.vector.y, msg.vector.z])


def path_message(t: float, p_native, *, frame_id: str = FRAME_MAP):
    """``nav_msgs/Path`` of path samples ``p_native`` (N x 3, native earth) in ENU ``frame_id``.

    Each pose's orientation points its x axis along the path tangent (finite differences, no roll).
    """
    from geometry_msgs.msg import Point, Pose, PoseStamped, Quaternion
    from nav_msgs.msg import Path as PathMsg

    p = np.asarray(p_native, dtype=float)
    if p.ndim != 2 or p.shape[1] != 3 or len(p) < 2 or not np.all(np.isfinite(p)):
        raise ConversionError(f"path must be N x 3 finite samples with N >= 2, got shape {p.shape}")
    p_enu = frames.earth_native_to_enu(p)
    tangent = np.gradient(p_enu, axis=0)
    yaw = np.arctan2(tangent[:, 1], tangent[:, 0])
    pitch = -np.arctan2(tangent[:, 2], np.hypot(tangent[:, 0], tangent[:, 1]))
    header = _header(t, frame_id)
    poses = []
    for k in range(len(p_enu)):
        cy, sy, cp, sp = np.cos(yaw[k] / 2), np.sin(yaw[k] / 2), np.cos(pitch[k] / 2), np.sin(pitch[k] / 2)
        q = (-sy * sp, cy * sp, sy * cp, cy * cp)  # Rz(yaw) Ry(pitch), (x, y, z, w)
        poses.append(PoseStamped(header=header, pose=Pose(
            position=Point(x=p_enu[k, 0], y=p_enu[k, 1], z=p_enu[k, 2]),
            orientation=Quaternion(x=q[0], y=q[1], z=q[2], w=q[3]))))
    return PathMsg(header=header, poses=poses)


def path_from_message(msg) -> np.ndarray:
    """Path samples (N x 3, native earth) of a ``nav_msgs/Path`` in ENU."""
    if msg.header.frame_id != FRAME_MAP:
        raise ConversionError(f"path must be in {FRAME_MAP!r}, got {msg.header.frame_id!r}")
    p_enu = np.array([[ps.pose.position.x, ps.pose.position.y, ps.pose.position.z] for ps in msg.poses])
    return frames.earth_enu_to_native(p_enu.reshape(-1, 3))


# ----------------------------------------------------------------------------------------- exact native state
def state_native_message(state: VehicleState):
    """``std_msgs/Float64MultiArray`` of the exact ROM state: ``[t, x, y, z, phi, theta, psi, u, v, w, p, q, r]``.

    Native frames and SI units (see :class:`bb2_sim.state.VehicleState`); float64 end to end, so
    :func:`state_native_from_message` returns the very same numbers (no quaternion round trip).
    """
    from std_msgs.msg import Float64MultiArray, MultiArrayDimension, MultiArrayLayout

    if not math.isfinite(state.t):
        raise ConversionError(f"state time must be finite, got {state.t!r}")
    data = np.concatenate([[float(state.t)], state.as_vector()])
    layout = MultiArrayLayout(dim=[MultiArrayDimension(label=STATE_NATIVE_LABEL, size=13, stride=13)],
                              data_offset=0)
    return Float64MultiArray(layout=layout, data=data.tolist())


def state_native_from_message(msg) -> VehicleState:
    """Inverse of :func:`state_native_message` (exact); rejects another layout."""
    dims = list(msg.layout.dim)
    data = np.asarray(msg.data, dtype=float)
    if len(dims) != 1 or dims[0].label != STATE_NATIVE_LABEL or data.shape != (13,) or msg.layout.data_offset:
        raise ConversionError(f"not a native state: layout {[(d.label, d.size) for d in dims]}, "
                              f"{data.size} values (expected {STATE_NATIVE_LABEL!r}, 13 values)")
    return VehicleState.from_vector(float(data[0]), data[1:])


# ----------------------------------------------------------------------------------------- exact Bernstein path
def bernstein_message(path):
    """``std_msgs/Float64MultiArray`` of a :class:`bb2_planner.bernstein.BernsteinPath` (exact).

    Layout: ``dim[0]`` = (``control_points``, n+1, (n+1) d), ``dim[1]`` = (path frame, d, d),
    ``data_offset`` = 2; ``data = [t0, tf, c[0,0], c[0,1], ..., c[n,d-1]]`` (metres, seconds).
    """
    from std_msgs.msg import Float64MultiArray, MultiArrayDimension, MultiArrayLayout

    c = np.asarray(path.control_points, dtype=float)
    n1, d = c.shape
    layout = MultiArrayLayout(dim=[MultiArrayDimension(label=BERNSTEIN_POINTS_LABEL, size=n1, stride=n1 * d),
                                   MultiArrayDimension(label=str(path.frame), size=d, stride=d)],
                              data_offset=2)
    return Float64MultiArray(layout=layout,
                             data=np.concatenate([[float(path.t0), float(path.tf)], c.ravel()]).tolist())


def bernstein_from_message(msg, name: str = ""):
    """Inverse of :func:`bernstein_message`: the same control points, span and frame."""
    from bb2_planner.bernstein import BernsteinPath, PathError

    dims = list(msg.layout.dim)
    data = np.asarray(msg.data, dtype=float)
    if (len(dims) != 2 or dims[0].label != BERNSTEIN_POINTS_LABEL or msg.layout.data_offset != 2
            or data.size != 2 + dims[0].size * dims[1].size):
        raise ConversionError(f"not a Bernstein path: layout {[(d.label, d.size) for d in dims]}, "
                              f"offset {msg.layout.data_offset}, {data.size} values")
    try:
        return BernsteinPath(data[2:].reshape(dims[0].size, dims[1].size), data[0], data[1],
                             frame=dims[1].label, name=name)
    except PathError as exc:
        raise ConversionError(f"bad Bernstein path message: {exc}") from None
