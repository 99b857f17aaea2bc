"""Frames of the BB2 model and conversions to ROS REP-103 and marine NED.

Native frames (SPEC of the ROM, section 1):

* earth ``E`` (``*_native`` world): x_E, y_E horizontal, **z up**, z = 0 on the calm surface;
  with all angles zero the bow points to -x_E and starboard to +y_E.
* body ``N`` (``*_native`` body): origin at the CG, **x aft, y starboard, z up**.
* Euler angles (phi, theta, psi), ZYX: ``R_EN = Rz(psi) Ry(theta) Rx(phi)`` maps native body
  components to native earth components.  theta > 0 bow up, phi > 0 starboard up, psi > 0 bow to port.

ROS frames (REP-103/105):

* body ``FLU`` (``base_link``): x forward, y left (port), z up.  ``v_flu = D v_native``,
  ``D = diag(-1, -1, 1)`` (a rotation by pi about z).
* world ``ENU`` (``map``/``odom``): ``p_enu = D p_native_earth``, so with psi = 0 the bow points to +x_enu.
  ``R_enu_flu = D R_EN D = Rz(psi) Ry(-theta) Rx(-phi)``: yaw_enu = psi, pitch_enu = -theta, roll_enu = -phi.

Marine frames:

* body ``FRD``: x forward, y starboard, z down: ``v_frd = diag(1, -1, -1) v_flu``.
* world ``NED``: ``p_ned = (p_enu.y, p_enu.x, -p_enu.z)``.  Marine attitude of FRD in NED:
  heading = pi/2 - psi (clockwise from north), pitch = theta (bow up), roll = -phi (starboard down).

Everything here is plain numpy; angles in radians.
"""
from __future__ import annotations

import math

import numpy as np

D_FLIP = np.diag([-1.0, -1.0, 1.0])
"""Native body (x aft, y stbd, z up) <-> FLU, and native earth <-> ENU: both directions, D = D^-1."""

FLU_TO_FRD = np.diag([1.0, -1.0, -1.0])
ENU_TO_NED = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])


def rotation_native(phi: float, theta: float, psi: float) -> np.ndarray:
    """R = Rz(psi) Ry(theta) Rx(phi): native body components -> native earth components (SPEC 1.3).

    Angles as arrays of N boats give (3, 3, N), each boat's matrix bit for bit its own call's."""
    cf, sf = np.cos(phi), np.sin(phi)
    ct, st = np.cos(theta), np.sin(theta)
    cs, ss = np.cos(psi), np.sin(psi)
    return np.array([
        [ct * cs, -cf * ss + sf * st * cs, sf * ss + cf * st * cs],
        [ct * ss, cf * cs + sf * st * ss, -sf * cs + cf * st * ss],
        [-st, sf * ct, cf * ct],
    ])


def euler_rate_matrix(phi: float, theta: float) -> np.ndarray:
    """T(phi, theta) with d[phi, theta, psi]/dt = T [p, q, r] (native body rates; singular at |theta| = 90 deg)."""
    cf, sf = np.cos(phi), np.sin(phi)
    ct, tt = np.cos(theta), np.tan(theta)
    return np.array([[1.0, tt * sf, tt * cf], [0.0, cf, -sf], [0.0, sf / ct, cf / ct]])


def euler_from_rotation(R: np.ndarray) -> tuple[float, float, float]:
    """ZYX Euler angles (roll, pitch, yaw) of a rotation matrix R = Rz(yaw) Ry(pitch) Rx(roll)."""
    pitch = -np.arcsin(np.clip(R[2, 0], -1.0, 1.0))
    roll = np.arctan2(R[2, 1], R[2, 2])
    yaw = np.arctan2(R[1, 0], R[0, 0])
    return float(roll), float(pitch), float(yaw)


# ----------------------------------------------------------------------------------------- vectors
def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a x b for 3-vectors or stacks of them (..., 3); np.cross without its per-call overhead."""
    if a.ndim == 1 and b.ndim == 1:
        a0, a1, a2 = a
        b0, b1, b2 = b
        return np.array([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0])
    # [a1 b2 - a2 b1, a2 b0 - a0 b2, a0 b1 - a1 b0] with the components permuted: the same products and
    # differences element by element (bit for bit the written-out formula), in seven numpy calls instead of seventeen
    return a[..., _I120] * b[..., _I201] - a[..., _I201] * b[..., _I120]


_I120 = np.array([1, 2, 0])
_I201 = np.array([2, 0, 1])


def body_native_to_flu(v_native: np.ndarray) -> np.ndarray:
    """Body vector (velocity, rate, force, moment) native (x aft, y stbd, z up) -> FLU."""
    return np.asarray(v_native, dtype=float) @ D_FLIP.T


def body_flu_to_native(v_flu: np.ndarray) -> np.ndarray:
    """Body vector FLU -> native body."""
    return np.asarray(v_flu, dtype=float) @ D_FLIP.T


def earth_native_to_enu(p_native: np.ndarray) -> np.ndarray:
    """World vector native earth (z up, bow along -x at psi = 0) -> ENU (``map``)."""
    return np.asarray(p_native, dtype=float) @ D_FLIP.T


def earth_enu_to_native(p_enu: np.ndarray) -> np.ndarray:
    """World vector ENU -> native earth."""
    return np.asarray(p_enu, dtype=float) @ D_FLIP.T


def enu_to_ned(p_enu: np.ndarray) -> np.ndarray:
    """World vector ENU -> NED."""
    return np.asarray(p_enu, dtype=float) @ ENU_TO_NED.T


def ned_to_enu(p_ned: np.ndarray) -> np.ndarray:
    """World vector NED -> ENU (the same permutation matrix is its own inverse)."""
    return np.asarray(p_ned, dtype=float) @ ENU_TO_NED.T


def flu_to_frd(v_flu: np.ndarray) -> np.ndarray:
    """Body vector FLU -> FRD."""
    return np.asarray(v_flu, dtype=float) @ FLU_TO_FRD.T


def frd_to_flu(v_frd: np.ndarray) -> np.ndarray:
    """Body vector FRD -> FLU."""
    return np.asarray(v_frd, dtype=float) @ FLU_TO_FRD.T


# ----------------------------------------------------------------------------------------- attitude
def euler_native_to_enu(phi: float, theta: float, psi: float) -> tuple[float, float, float]:
    """Native Euler angles -> REP-103 (roll, pitch, yaw) of base_link (FLU) in ENU."""
    return -phi, -theta, psi


def euler_enu_to_native(roll: float, pitch: float, yaw: float) -> tuple[float, float, float]:
    """REP-103 (roll, pitch, yaw) of base_link in ENU -> native (phi, theta, psi)."""
    return -roll, -pitch, yaw


def rotation_enu_flu(phi: float, theta: float, psi: float) -> np.ndarray:
    """R_enu_flu (FLU body components -> ENU components) from the native Euler angles."""
    return D_FLIP @ rotation_native(phi, theta, psi) @ D_FLIP


def rotation_ned_frd(phi: float, theta: float, psi: float) -> np.ndarray:
    """R_ned_frd (FRD body -> NED) from the native Euler angles."""
    return ENU_TO_NED @ rotation_enu_flu(phi, theta, psi) @ FLU_TO_FRD


def euler_native_to_ned(phi: float, theta: float, psi: float) -> tuple[float, float, float]:
    """Native Euler angles -> marine (roll, pitch, heading) of FRD in NED.

    roll > 0 starboard down, pitch > 0 bow up, heading clockwise from north.  Heading is
    pi/2 - psi (psi = 0 heads east in ENU), wrapped to (-pi, pi].
    """
    return euler_from_rotation(rotation_ned_frd(phi, theta, psi))


def euler_ned_to_native(roll: float, pitch: float, heading: float) -> tuple[float, float, float]:
    """Marine (roll, pitch, heading) of FRD in NED -> native (phi, theta, psi) (psi wrapped)."""
    cr, sr = np.cos(roll), np.sin(roll)
    cp, sp = np.cos(pitch), np.sin(pitch)
    ch, sh = np.cos(heading), np.sin(heading)
    R_ned_frd = np.array([[cp * ch, -cr * sh + sr * sp * ch, sr * sh + cr * sp * ch],
                          [cp * sh, cr * ch + sr * sp * sh, -sr * ch + cr * sp * sh],
                          [-sp, sr * cp, cr * cp]])
    R_native = D_FLIP @ ENU_TO_NED.T @ R_ned_frd @ FLU_TO_FRD.T @ D_FLIP
    return euler_from_rotation(R_native)


def quaternion_enu_flu(phi: float, theta: float, psi: float) -> tuple[float, float, float, float]:
    """Unit quaternion (x, y, z, w), w >= 0, of ``R_enu_flu`` from the native Euler angles, in closed form.

    ``R_enu_flu = Rz(yaw) Ry(pitch) Rx(roll)`` with (roll, pitch, yaw) = (-phi, -theta, psi), so
    ``q = qz(yaw) qy(pitch) qx(roll)``.  Equal to ``quaternion_from_rotation(rotation_enu_flu(...))``
    to rounding (tested), at a small fraction of its cost (the simulator converts every state).
    """
    roll, pitch, yaw = -0.5 * phi, -0.5 * theta, 0.5 * psi
    cr, sr = math.cos(roll), math.sin(roll)
    cp, sp = math.cos(pitch), math.sin(pitch)
    cy, sy = math.cos(yaw), math.sin(yaw)
    w = cr * cp * cy + sr * sp * sy
    x = sr * cp * cy - cr * sp * sy
    y = cr * sp * cy + sr * cp * sy
    z = cr * cp * sy - sr * sp * cy
    return (x, y, z, w) if w >= 0.0 else (-x, -y, -z, -w)


def quaternion_from_rotation(R: np.ndarray) -> np.ndarray:
    """Unit quaternion (x, y, z, w) of a rotation matrix (the geometry_msgs ordering), w >= 0."""
    from scipy.spatial.transform import Rotation

    q = Rotation.from_matrix(R).as_quat()
    return q if q[3] >= 0 else -q


def rotation_from_quaternion(q_xyzw: np.ndarray) -> np.ndarray:
    """Rotation matrix of a quaternion (x, y, z, w)."""
    from scipy.spatial.transform import Rotation

    return Rotation.from_quat(np.asarray(q_xyzw, dtype=float)).as_matrix()
