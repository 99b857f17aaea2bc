"""The campaign's progress bar: done / total, rate (runs/s), ETA and the failures so far (stderr).

Runs that fly together in a batch land together, when their chunk ends: between, the bar, rate and ETA count what
the chunks in flight have flown (``flying``, runs' worth, from the engine: :meth:`Progress.flying_now`), and the
line says it (``+37.5 in flight``); the count before it is of the runs landed (in the results).

On a terminal it redraws one line; otherwise it prints a line every ``every_s`` seconds (logs, CI).
"""
from __future__ import annotations

import collections
import sys
import time
from typing import TextIO

__all__ = ["Progress", "format_duration"]


def format_duration(s: float) -> str:
    if s != s or s == float("inf"):
        return "--"
    s = int(round(s))
    h, rem = divmod(s, 3600)
    m, sec = divmod(rem, 60)
    return f"{h}h{m:02d}m{sec:02d}s" if h else f"{m}m{sec:02d}s" if m else f"{sec}s"


class Progress:
    def __init__(self, total: int, already: int = 0, stream: TextIO | None = None, enabled: bool = True,
                 every_s: float = 10.0, width: int = 28) -> None:
        self.total, self.already = int(total), int(already)
        self.done = 0
        self.stream = stream or sys.stderr
        self.enabled = enabled
        self.tty = enabled and hasattr(self.stream, "isatty") and self.stream.isatty()
        self.every_s, self.width = every_s, width
        self.t0 = time.monotonic()
        self._last = 0.0
        self.status: collections.Counter[str] = collections.Counter()
        self.flying = 0.0   #: runs' worth flown by the chunks in flight (not yet landed)

    def flying_now(self, flying: float = 0.0) -> None:
        """The engine's tick: what the chunks in flight have flown so far (runs' worth); redraws."""
        self.flying = max(0.0, float(flying))
        self.draw()

    def update(self, status: str | None = None) -> None:
        if status is not None:
            self.done += 1
            self.status[status] += 1
            self.flying = max(0.0, self.flying - 1.0)   # it was in flight: counted there until the engine's next tick
        self.draw()

    @property
    def rate(self) -> float:
        """Runs per second this session: those landed and what the chunks in flight have flown."""
        dt = time.monotonic() - self.t0
        return (self.done + self.flying) / dt if dt > 0 else 0.0

    def line(self) -> str:
        n = self.already + self.done
        flown = min(float(self.total), n + self.flying)
        frac = flown / self.total if self.total else 1.0
        fill = int(round(self.width * frac))
        rate = self.rate
        left = self.total - flown
        eta = left / rate if rate > 0 else float("inf")
        fails = sum(v for k, v in self.status.items() if k != "ok")
        flying = f" (+{self.flying:.1f} in flight)" if self.flying >= 0.05 and n < self.total else ""
        return (f"[{'#' * fill}{'.' * (self.width - fill)}] {n}/{self.total}{flying} {100 * frac:5.1f}%  "
                f"{rate:.2f} runs/s  ETA {format_duration(eta) if n < self.total else '0s'}  "
                f"elapsed {format_duration(time.monotonic() - self.t0)}  failed {fails}")

    def draw(self, force: bool = False) -> None:
        if not self.enabled:
            return
        now = time.monotonic()
        if self.tty:
            if force or now - self._last >= 0.2:
                self.stream.write("\r" + self.line() + "\x1b[K")
                self.stream.flush()
                self._last = now
        elif force or now - self._last >= self.every_s:
            self.stream.write(self.line() + "\n")
            self.stream.flush()
            self._last = now

    def close(self) -> None:
        if not self.enabled:
            return
        self.draw(force=True)
        if self.tty:
            self.stream.write("\n")
            self.stream.flush()
