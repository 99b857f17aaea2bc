"""The ROS 2 environment of a console script called directly (``.venv/bin/bb2-launch``,
``<venv>/lib/bb2_ros/simulator``) rather than through ``run.sh`` or a sourced ``setup.bash``.

:func:`ensure_ros_environment` fills in what is missing before rclpy or the ament index is used:

* ``AMENT_PREFIX_PATH``: unset or empty -> the prefix of this interpreter (the virtual environment) when it
  holds an ament index with rclpy (the Jazzy wheels install one there);
* ``RMW_IMPLEMENTATION``: unset -> ``rmw_fastrtps_cpp`` when that middleware is in the index (what the wheels
  bring; rcl would pick it anyway, the launcher passes it on to every node).

A prefix without an ament index and no ``AMENT_PREFIX_PATH`` is :class:`RosEnvironmentError` with one line
that says what to set.  Variables already set are never changed.
"""
from __future__ import annotations

import os
import sys
from pathlib import Path
from typing import MutableMapping

DEFAULT_RMW = "rmw_fastrtps_cpp"


class RosEnvironmentError(RuntimeError):
    """No ROS 2 environment could be found (the message is one line saying what to set)."""


def _indexed(prefix: Path, package: str) -> bool:
    return (prefix / "share" / "ament_index" / "resource_index" / "packages" / package).is_file()


def ensure_ros_environment(environ: MutableMapping[str, str] | None = None,
                           prefix: str | os.PathLike | None = None) -> list[str]:
    """Set ``AMENT_PREFIX_PATH`` and ``RMW_IMPLEMENTATION`` in ``environ`` (default ``os.environ``) when they
    are missing; return what was set (``NAME=value`` strings)."""
    env = os.environ if environ is None else environ
    here = Path(sys.prefix if prefix is None else prefix)
    done: list[str] = []
    prefixes = [Path(p) for p in env.get("AMENT_PREFIX_PATH", "").split(os.pathsep) if p]
    if not prefixes:
        if not _indexed(here, "rclpy"):
            raise RosEnvironmentError(
                f"no ROS 2 environment: AMENT_PREFIX_PATH is not set and {here} has no ament index with rclpy; "
                "source /opt/ros/jazzy/setup.bash (or your workspace's install/setup.bash), or set "
                "AMENT_PREFIX_PATH to the virtual environment that holds the ROS 2 wheels")
        env["AMENT_PREFIX_PATH"] = str(here)
        prefixes = [here]
        done.append(f"AMENT_PREFIX_PATH={here}")
    if not env.get("RMW_IMPLEMENTATION") and any(_indexed(p, DEFAULT_RMW) for p in prefixes):
        env["RMW_IMPLEMENTATION"] = DEFAULT_RMW
        done.append(f"RMW_IMPLEMENTATION={DEFAULT_RMW}")
    return done


def ros_environment_or_error(prog: str) -> int | None:
    """:func:`ensure_ros_environment` for a console script: None when the environment is there, else the one
    line on stderr and exit status 2."""
    try:
        ensure_ros_environment()
    except RosEnvironmentError as exc:
        print(f"{prog}: error: {exc}", file=sys.stderr, flush=True)
        return 2
    return None
