"""The node processes' entry points (``ros2 run bb2_ros simulator`` ...): each imports its node's module only once a
SIGINT that comes meanwhile ends the process quietly.

A node's module takes a second or more to import (numpy, scipy, rclpy, the ROM); a launch stopped in that second (a
run refused at start-up: every other node is stopped at once; in a fleet, a boat whose simulator failed at once)
used to print each node's ``KeyboardInterrupt`` traceback from deep inside an import, then launch's ``process has
died [exit code -2]``.  Here such a SIGINT ends the process at once with exit code 0, as a node told to stop once it
runs does (nothing had started: a clean stop; ``ros2 launch`` says ``process has finished cleanly``).  The node's
``main`` then installs its own handlers (:func:`bb2_ros.node_common.stop_signals`: a clean stop, exit 0), so a
SIGINT once it runs stops it as always.  This module imports nothing heavy.
"""
from __future__ import annotations

import importlib
import os
import signal
import sys


def _stop_before_start(_signum: int, _frame) -> None:
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except Exception:  # closed, gone, or the signal came inside its own write (reentrant)
            pass
    os._exit(0)   # at once: out of whatever import runs (an exception could be caught on its way up)


def run(target: str) -> int:
    """Import ``module:function`` and call it, a SIGINT before ``function`` installs its own handler ending the
    process quietly, exit code 0 (stopped before it started)."""
    signal.signal(signal.SIGINT, _stop_before_start)
    module, function = target.split(":")
    return getattr(importlib.import_module(module), function)()


TARGETS = {"simulator": "bb2_ros.simulator:main", "planner": "bb2_ros.planner:main",
           "path_following": "bb2_ros.path_following:main", "l1_autopilot": "bb2_ros.l1_autopilot:main",
           "mixer": "bb2_ros.mixer:main", "container": "bb2_ros.container:main"}
"""Executable -> the ``module:function`` it runs."""


def simulator() -> int:
    return run(TARGETS["simulator"])


def planner() -> int:
    return run(TARGETS["planner"])


def path_following() -> int:
    return run(TARGETS["path_following"])


def l1_autopilot() -> int:
    return run(TARGETS["l1_autopilot"])


def mixer() -> int:
    return run(TARGETS["mixer"])


def container() -> int:
    return run(TARGETS["container"])
