"""The interpreter's garbage collector in a node process: the start-up heap settled, the pauses measured.

CPython's cyclic garbage collector stops every thread of the process while it runs, and a full (oldest
generation) collection walks every container object alive: in a node process, after numpy, scipy, trimesh, rclpy
and the message classes are imported and the mission is built, that is about 100,000 objects and 30-45 ms a
collection on this project's machines, so one full collection in a real-time run at 100 Hz is an
overrun of the stepping thread (three or four periods without a state).  Nearly all of those objects live as
long as the process.

:func:`settle` runs once per node process (:func:`bb2_ros.node_common.run_nodes`, the recorder), after the nodes
are built and before they spin: one full collection (what start-up left as garbage is freed), then
:func:`gc.freeze` moves every surviving object to the collector's permanent generation, which no later collection
walks.  Later collections only see the objects made while running (a full one then takes well under a
millisecond).  Nothing is lost: frozen objects are still freed by reference counting; only cycles among them
would stay (the process's start-up ones are collected just before).

:data:`PAUSES` measures every collection from then on (count and longest pause); the nodes' statuses say it
(``gc_frozen_objects``, ``gc_collections``, ``gc_pause_max_ms``).
"""
from __future__ import annotations

import gc
import time


class GcPauses:
    """The garbage collections of this process since :meth:`start`: how many, and the longest (s)."""

    def __init__(self) -> None:
        self.frozen_objects = 0          #: objects moved out of the collector's reach by :func:`settle`
        self.collections = 0
        self.max_pause_s = 0.0
        self.started = False
        self._since: float | None = None

    def start(self) -> None:
        """Measure from now on (once per process; again is a no-op)."""
        if not self.started:
            self.started = True
            gc.callbacks.append(self._on_gc)

    def _on_gc(self, phase: str, _info: dict) -> None:
        # called by the collector itself, with the interpreter lock held: collections never overlap
        if phase == "start":
            self._since = time.perf_counter()
        elif self._since is not None:
            pause = time.perf_counter() - self._since
            self._since = None
            self.collections += 1
            if pause > self.max_pause_s:
                self.max_pause_s = pause

    def status_values(self) -> dict[str, str]:
        """The keys every node's ``/bb2/status`` carries (``gc_collections`` and ``gc_pause_max_ms`` empty while
        nothing is measured: a node built outside :func:`bb2_ros.node_common.run_nodes`)."""
        return {"gc_frozen_objects": str(self.frozen_objects),
                "gc_collections": str(self.collections) if self.started else "",
                "gc_pause_max_ms": f"{self.max_pause_s * 1e3:.3f}" if self.started else ""}


PAUSES = GcPauses()
"""This process's collections (one collector per process: composed nodes share it)."""


def settle() -> int:
    """Free the start-up garbage, freeze what survives (out of every later collection's walk) and start
    measuring the pauses (:data:`PAUSES`).  Call it once the process's nodes are built, before they spin.
    Returns the number of objects frozen."""
    gc.collect()
    gc.freeze()
    PAUSES.frozen_objects = gc.get_freeze_count()
    PAUSES.start()
    return PAUSES.frozen_objects
