"""The tools' node processes' entry points (``ros2 run bb2_tools recorder`` ...), started as the graph's nodes are
(:func:`bb2_ros.entry.run`: a SIGINT while the module still imports ends the process quietly)."""
from __future__ import annotations

from bb2_ros.entry import run


TARGETS = {"recorder": "bb2_tools.recorder:main", "foxglove_bridge": "bb2_tools.foxglove_live:main"}
"""Executable -> the ``module:function`` it runs."""


def recorder() -> int:
    return run(TARGETS["recorder"])


def foxglove_bridge() -> int:
    return run(TARGETS["foxglove_bridge"])
