"""Sensor models (ROS-free, layer 1): IMU, pressure, DVL, altimeter, GPS, their faults and the suite.

One module per sensor (``imu``, ``pressure``, ``dvl``, ``altimeter``, ``gps``), parameters as data
(``bb2_sim/data/sensors_tactical.yaml``, ``sensors_mems.yaml``: units and the device class of every figure),
each sensor seeded on its own.  :class:`SensorSuite` turns the truth at the ROM's steps into time-stamped
measurements at each sensor's own rate; :mod:`.allan` is the overlapping Allan deviation the tests use.
"""
from .config import PRESETS, FaultSpec, SensorConfigError, SuiteConfig, faults_from_list, load_suite_config
from .samples import AltimeterSample, DvlSample, GpsSample, ImuSample, PressureSample, Sample
from .suite import SensorEnvironment, SensorSuite, sea_of_model
from .truth import TruthBatch, TruthSample, interpolate, truth_from_step

__all__ = ["PRESETS", "FaultSpec", "SensorConfigError", "SuiteConfig", "faults_from_list", "load_suite_config",
           "AltimeterSample", "DvlSample", "GpsSample", "ImuSample", "PressureSample", "Sample",
           "SensorEnvironment", "SensorSuite", "sea_of_model", "TruthBatch", "TruthSample", "interpolate",
           "truth_from_step"]
