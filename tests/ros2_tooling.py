"""The upstream ROS 2 Jazzy command-line tools (``ros2``, ``ros2 launch``, ``colcon``) for tests that check what
a ROS 2 user runs.

``../shared/ros2_tooling/assemble.sh`` builds them into a virtual environment of their own (about 90 s);
:func:`tooling_venv` does that once per machine into a cache directory keyed by the sha256 of the sources'
``COMMITS``, the script and the project's ``requirements.txt``, and reuses it.  Without ``../shared`` the
test is skipped with the reason.
"""
from __future__ import annotations

import fcntl
import hashlib
import os
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
SHARED = Path(os.environ.get("BB2_SHARED", REPO.parent / "shared")).resolve()
TOOLING = SHARED / "ros2_tooling"
CACHE = Path(os.environ.get("BB2_TOOLING_CACHE", Path.home() / ".cache" / "bb2_sim"))


def cache_key() -> str:
    h = hashlib.sha256()
    for f in (TOOLING / "src" / "COMMITS", TOOLING / "assemble.sh", REPO / "requirements.txt"):
        h.update(f.read_bytes())
    return h.hexdigest()[:16]


def tooling_venv() -> Path:
    """The assembled tooling venv (assembled now if this machine has none); skips when ../shared is absent."""
    if not (TOOLING / "assemble.sh").is_file():
        pytest.skip(f"ROS 2 tooling sources not found: {TOOLING} (../shared is not beside this clone)")
    venv = CACHE / f"ros2_tooling-{cache_key()}"
    CACHE.mkdir(parents=True, exist_ok=True)
    with open(CACHE / "ros2_tooling.lock", "w") as lock:  # one assembly at a time (parallel test runs)
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not (venv / ".assembled").is_file():
            r = subprocess.run(["bash", str(TOOLING / "assemble.sh"), str(venv), str(TOOLING / "src"),
                                str(REPO / "requirements.txt")], capture_output=True, text=True, timeout=1200)
            if r.returncode != 0:
                raise RuntimeError(f"assembling the ROS 2 tooling failed:\n{r.stdout[-3000:]}\n{r.stderr[-3000:]}")
            (venv / ".assembled").write_text(r.stdout[-500:])
    return venv


def tooling_env(venv: Path, **extra: str) -> dict[str, str]:
    """The environment a ROS 2 user has after sourcing: the tooling's bin first, its ament prefix."""
    env = dict(os.environ)
    env.update(PATH=f"{venv / 'bin'}{os.pathsep}{env.get('PATH', '')}", AMENT_PREFIX_PATH=str(venv),
               ROS_DISTRO="jazzy", ROS_VERSION="2", ROS_PYTHON_VERSION="3", RMW_IMPLEMENTATION="rmw_fastrtps_cpp",
               ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST", PYTHONDONTWRITEBYTECODE="1")
    env.pop("VIRTUAL_ENV", None)
    env.update(extra)
    return env


if __name__ == "__main__":  # assemble ahead of a test run: python tests/ros2_tooling.py
    print(tooling_venv())
    sys.exit(0)
