"""The node processes' entry points (``ros2 run bb2_ros simulator`` ...): each imports its node's module only once a
SIGINT that comes meanwhile ends the process quietly.

A node's module takes a second or more to import (numpy, scipy, rclpy, the ROM); a launch stopped in that second (a
run refused at start-up: every other node is stopped at once) used to print each node's ``KeyboardInterrupt``
traceback from deep inside an import.  Here such a SIGINT ends the process by that signal, as before, without the
traceback.  The node's ``main`` then installs its own handlers (:func:`bb2_ros.node_common.stop_signals`: a clean
stop), so a SIGINT once it runs stops it as always.  This module imports nothing heavy.
"""
from __future__ import annotations

import importlib
import os
import signal


def _end_by(signum: int, _frame) -> None:
    signal.signal(signum, signal.SIG_DFL)
    os.kill(os.getpid(), signum)   # the exit status says the signal (as an uncaught KeyboardInterrupt's did)


def run(target: str) -> int:
    """Import ``module:function`` and call it, a SIGINT before ``function`` installs its own handler ending the
    process quietly by that signal."""
    signal.signal(signal.SIGINT, _end_by)
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
