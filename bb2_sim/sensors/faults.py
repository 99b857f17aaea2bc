"""Faults users test against: dropout windows, stuck values, bias steps (no ROS).

Applied to each sensor's samples in time order, by their time of validity (:class:`~.config.FaultSpec`):
a ``bias_step`` adds its bias to the field, a ``stuck`` window repeats the last sample before the window (with
the new stamps; the first sample of the window if there was none), a ``dropout`` window removes the samples (no
message).  Several faults may overlap; they act in that order.
"""
from __future__ import annotations

from typing import Iterable

from .config import FaultSpec
from .samples import Sample

__all__ = ["FaultInjector"]


class FaultInjector:
    def __init__(self, faults: Iterable[FaultSpec]) -> None:
        self.faults = tuple(faults)
        self._last: dict[str, Sample] = {}      # last sample outside a stuck window, per sensor
        self._held: dict[int, Sample] = {}      # per stuck fault: the value it holds

    def apply(self, s: Sample) -> Sample | None:
        active = [f for f in self.faults if f.sensor == s.sensor and f.active(s.t)]
        if not active:
            self._last[s.sensor] = s
            return s
        out = s
        for f in active:
            if f.kind == "bias_step":
                out = out.with_bias(f.field, f.bias)
        stuck = [f for f in active if f.kind == "stuck"]
        if stuck:
            key = id(stuck[0])
            if key not in self._held:
                self._held[key] = self._last.get(s.sensor, out)
            out = self._held[key].restamped(s.t, s.t_available)
        else:
            self._last[s.sensor] = out
        if any(f.kind == "dropout" for f in active):
            return None
        return out
