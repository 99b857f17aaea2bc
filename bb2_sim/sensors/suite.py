"""The sensor suite: every sensor at its own rate from the truth at the ROM's steps, deterministic per seed.

::

    suite = SensorSuite(load_suite_config("tactical"), seed=7, sea=sea, current=current)
    for each ROM step n:   samples = suite.step(truth_n, truth_n+1)     # TruthSample of bb2_sim.sensors.truth

Sensor ``s`` samples at ``t0 + k / rate_s`` (k = 0, 1, ...), independent of the ROM's step; ``step`` makes the
samples whose time falls in ``[t_n, t_n+1)`` from the truth interpolated between the two steps
(:func:`~.truth.interpolate`), applies the faults, and returns those out of the sensor (time of validity plus
latency) before ``t_n+1``, in the order (t_available, t, sensor).  Each sensor has its own random streams
(``SeedSequence([seed, sensor index, purpose])``) and draws a fixed number of normals per sample, so a run is a
function of the seed and the truth alone: the same in the library runner and through the graph, stepped in any
chunks.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from ..constants import G_M_S2, RHO_KG_M3
from .altimeter import AltimeterModel
from .config import SENSOR_NAMES, FaultSpec, SuiteConfig
from .dvl import DvlModel
from .faults import FaultInjector
from .gps import GpsModel
from .imu import ImuModel
from .pressure import PressureModel
from .samples import Sample, sample_order
from .truth import TruthSample, interpolate

__all__ = ["SensorEnvironment", "SensorSuite", "sea_of_model"]

_MODELS = {"imu": ImuModel, "pressure": PressureModel, "dvl": DvlModel, "altimeter": AltimeterModel,
           "gps": GpsModel}
_EPS = 1e-9


@dataclass(frozen=True)
class SensorEnvironment:
    """What the sensors see besides the vehicle: the sea (``bb2_sim.sea.Sea``: elevation, pressure head; None =
    calm), the current (``bb2_sim.current.Current``; None = none), sea-water density and gravity."""

    sea: Any = None
    current: Any = None
    rho: float = RHO_KG_M3
    g: float = G_M_S2


def sea_of_model(model: Any) -> Any:
    """The sea a :class:`~bb2_sim.model.BB2Model` flies in, as a ``Sea`` (None when calm)."""
    if getattr(model, "sea", None) is not None:
        return model.sea
    wave = getattr(model, "wave", None)
    if wave is not None and not wave.calm:
        from ..sea.sea import AuthorsTableSea
        return AuthorsTableSea(wave, float(model.params.g))
    return None


class SensorSuite:
    """The sensors of a :class:`~.config.SuiteConfig` (see the module docstring)."""

    def __init__(self, config: SuiteConfig, *, seed: int = 0, environment: SensorEnvironment | None = None,
                 t0: float = 0.0, faults: tuple[FaultSpec, ...] | None = None) -> None:
        self.config = config
        self.seed = int(seed)
        self.env = environment or SensorEnvironment()
        self.t0 = float(t0)
        self.models = {name: _MODELS[name](cfg, self.seed, SENSOR_NAMES.index(name), self.t0)
                       for name, cfg in config.sensors().items()}
        self._k = {name: 0 for name in self.models}
        self.faults = FaultInjector(config.faults + tuple(faults or ()))
        self._pending: list[Sample] = []

    @classmethod
    def for_model(cls, config: SuiteConfig, model: Any, *, seed: int = 0, t0: float = 0.0,
                  faults: tuple[FaultSpec, ...] | None = None) -> "SensorSuite":
        """A suite in the sea, current, density and gravity of a ROM (:class:`~bb2_sim.model.BB2Model`)."""
        env = SensorEnvironment(sea_of_model(model), getattr(model, "current", None), float(model.params.rho),
                                float(model.params.g))
        return cls(config, seed=seed, environment=env, t0=t0, faults=faults)

    def rate_hz(self, name: str) -> float:
        return float(self.models[name].cfg.rate_hz)

    def frame_ids(self) -> dict[str, str]:
        return {name: m.cfg.frame_id for name, m in self.models.items()}

    def _times(self, name: str, t_end: float) -> list[float]:
        m = self.models[name]
        out = []
        k = self._k[name]
        while True:
            t = self.t0 + k * m.period
            if t >= t_end - _EPS:
                break
            out.append(t)
            k += 1
        self._k[name] = k
        return out

    def step(self, a: TruthSample, b: TruthSample | None) -> list[Sample]:
        """The samples out of the sensors in ``[a.t, b.t)`` (``b`` None: sample at ``a.t`` only, holding it)."""
        t_end = b.t if b is not None else a.t + _EPS * 2
        for name, m in self.models.items():
            ts = self._times(name, t_end)
            if not ts:
                continue
            for s in m.sample(interpolate(a, b, ts), self.env):
                s = self.faults.apply(s)
                if s is not None:
                    self._pending.append(s)
        ready = sorted((s for s in self._pending if s.t_available < t_end - _EPS), key=sample_order)
        self._pending = [s for s in self._pending if not s.t_available < t_end - _EPS]
        return ready

    def flush(self) -> list[Sample]:
        """The samples still in the sensors' latency (at the end of a run)."""
        out = sorted(self._pending, key=sample_order)
        self._pending = []
        return out

    def run(self, truths: list[TruthSample]) -> list[Sample]:
        """All samples of a whole truth sequence (the ROM's steps), then the ones still in latency."""
        out: list[Sample] = []
        for a, b in zip(truths[:-1], truths[1:]):
            out.extend(self.step(a, b))
        return out + self.flush()
