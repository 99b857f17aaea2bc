"""Child-process environment of the ROS tests: real DDS (Fast DDS) on an isolated domain, this checkout first."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def ros_env(domain_id: int | None = None) -> dict[str, str]:
    """os.environ plus the ament prefix (the venv), Fast DDS, this checkout on PYTHONPATH, unbuffered output,
    and ROS_DOMAIN_ID = ``domain_id`` (None: unset, the child picks or is told its domain)."""
    env = dict(os.environ)
    env["AMENT_PREFIX_PATH"] = env.get("AMENT_PREFIX_PATH") or sys.prefix
    env["RMW_IMPLEMENTATION"] = "rmw_fastrtps_cpp"
    env["PYTHONPATH"] = str(REPO) + os.pathsep + env.get("PYTHONPATH", "")
    env["PYTHONUNBUFFERED"] = "1"
    if domain_id is None:
        env.pop("ROS_DOMAIN_ID", None)
    else:
        env["ROS_DOMAIN_ID"] = str(domain_id)
    return env


def spawn_node(module: str, domain_id: int, *ros_args: str) -> subprocess.Popen:
    """``python -m module --ros-args ...`` on ``domain_id``, stdout+stderr captured as text."""
    return subprocess.Popen([sys.executable, "-m", module, "--ros-args", *ros_args], cwd=REPO,
                            env=ros_env(domain_id), stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
