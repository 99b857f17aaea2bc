"""The measurements the sensor models produce: time-stamped values in the sensor's own frame (no ROS).

``t`` is the time of validity (the header stamp of the message), ``t_available`` when the measurement is out of the
sensor (``t`` + latency).  Frames are REP-103 (``frame_id`` is the sensor's mounting frame, published on
/tf_static); covariances are 3x3 arrays in that frame, honest: the per-sample noise plus the sigma of the errors
the model keeps unknown to the user (biases, offsets, scale factors at the current value).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from .config import SENSOR_NAMES
from .geodesy import enu_to_geodetic

__all__ = ["Sample", "ImuSample", "PressureSample", "DvlSample", "AltimeterSample", "GpsSample", "sample_order"]

_SENSOR_ORDER = {name: i for i, name in enumerate(SENSOR_NAMES)}


def sample_order(s: "Sample") -> tuple[int, int, int]:
    """The order samples come out of the sensors: by the time they are out of the sensor, then their time of
    validity, both to the nanosecond (as the message stamps carry them, so samples read back from the topics sort
    the same), then the sensor (:data:`~bb2_sim.sensors.config.SENSOR_NAMES`)."""
    return (round(s.t_available * 1e9), round(s.t * 1e9), _SENSOR_ORDER[s.sensor])


@dataclass(frozen=True)
class Sample:
    sensor: str
    t: float
    t_available: float
    frame_id: str

    def restamped(self, t: float, t_available: float) -> "Sample":
        return replace(self, t=t, t_available=t_available)

    def with_bias(self, field: str, bias) -> "Sample":  # pragma: no cover - each kind overrides
        raise NotImplementedError


@dataclass(frozen=True)
class ImuSample(Sample):
    angular_velocity: np.ndarray        #: rad/s, imu frame
    specific_force: np.ndarray          #: m/s^2, imu frame (at rest and level: (0, 0, +g))
    orientation_xyzw: np.ndarray        #: quaternion of the imu frame in ENU (REP-145: the IMU's own attitude)
    orientation_covariance: np.ndarray  #: 3x3, rad^2 (roll, pitch, yaw about the world axes)
    angular_velocity_covariance: np.ndarray
    specific_force_covariance: np.ndarray

    def with_bias(self, field: str, bias) -> "ImuSample":
        if field == "gyro":
            return replace(self, angular_velocity=self.angular_velocity + np.asarray(bias, float))
        return replace(self, specific_force=self.specific_force + np.asarray(bias, float))


@dataclass(frozen=True)
class PressureSample(Sample):
    pressure_pa: float                  #: absolute pressure, Pa
    variance_pa2: float

    def with_bias(self, field: str, bias) -> "PressureSample":
        return replace(self, pressure_pa=self.pressure_pa + float(np.ravel(bias)[0]))


@dataclass(frozen=True)
class DvlSample(Sample):
    bottom_lock: bool                   #: True: velocity over the bottom; False: velocity through the water
    velocity: np.ndarray                #: m/s, dvl frame (of the DVL itself, over ground or through water)
    covariance: np.ndarray              #: 3x3, m^2/s^2
    beam_ranges_m: np.ndarray           #: slant range per beam, +inf = no echo (REP-117)
    beam_valid: np.ndarray              #: bool per beam

    def with_bias(self, field: str, bias) -> "DvlSample":
        return replace(self, velocity=self.velocity + np.asarray(bias, float))


@dataclass(frozen=True)
class AltimeterSample(Sample):
    range_m: float                      #: along the boresight; +inf no echo within max range, -inf below min
    variance_m2: float
    min_range_m: float
    max_range_m: float
    field_of_view_rad: float

    def with_bias(self, field: str, bias) -> "AltimeterSample":
        r = self.range_m + float(np.ravel(bias)[0]) if math.isfinite(self.range_m) else self.range_m
        return replace(self, range_m=r)


@dataclass(frozen=True)
class GpsSample(Sample):
    fix: bool
    latitude_deg: float                 #: NaN without a fix
    longitude_deg: float
    altitude_m: float                   #: ellipsoidal height
    position_enu: np.ndarray            #: the same fix in map (ENU), m (NaN without a fix)
    covariance_enu: np.ndarray          #: 3x3, m^2 (ENU, as NavSatFix.position_covariance)
    origin: tuple[float, float, float] = (0.0, 0.0, 0.0)   #: lat, lon (deg), alt (m) of map's origin

    def with_bias(self, field: str, bias) -> "GpsSample":
        if not self.fix:
            return self
        p = self.position_enu + np.asarray(bias, float)
        lat, lon, alt = enu_to_geodetic(p, *self.origin)
        return replace(self, position_enu=p, latitude_deg=float(lat), longitude_deg=float(lon), altitude_m=float(alt))
