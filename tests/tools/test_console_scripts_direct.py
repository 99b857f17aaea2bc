"""Issue 13 (5): every console script works when called directly from the virtual environment, with no ROS
variable set (not through run.sh): it finds the venv's ament prefix and the middleware itself, or says in one
line what to set."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from bb2_msgs_py.ros_env import RosEnvironmentError, ensure_ros_environment

from rosenv import claimed_domain  # noqa: E402  (tests/rosenv.py)

REPO = Path(__file__).resolve().parents[2]
VENV_BIN = Path(sys.prefix) / "bin"


def bare_env(**extra: str) -> dict[str, str]:
    """What a user's shell has before anything ROS is sourced: no AMENT_PREFIX_PATH, no RMW_IMPLEMENTATION."""
    env = {"PATH": "/usr/bin:/bin", "HOME": os.environ.get("HOME", "/root"), "MPLBACKEND": "Agg",
           "PYTHONDONTWRITEBYTECODE": "1", "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}
    env.update(extra)
    return env


def test_ensure_ros_environment_fills_in_the_venv_prefix_and_middleware(tmp_path):
    index = tmp_path / "share" / "ament_index" / "resource_index" / "packages"
    index.mkdir(parents=True)
    for pkg in ("rclpy", "rmw_fastrtps_cpp"):
        (index / pkg).write_text("")
    env: dict[str, str] = {}
    assert ensure_ros_environment(env, prefix=tmp_path) == [f"AMENT_PREFIX_PATH={tmp_path}",
                                                             "RMW_IMPLEMENTATION=rmw_fastrtps_cpp"]
    assert env == {"AMENT_PREFIX_PATH": str(tmp_path), "RMW_IMPLEMENTATION": "rmw_fastrtps_cpp"}
    mine = {"AMENT_PREFIX_PATH": "/opt/ros/jazzy", "RMW_IMPLEMENTATION": "rmw_cyclonedds_cpp"}
    assert ensure_ros_environment(mine, prefix=tmp_path) == [] and mine["AMENT_PREFIX_PATH"] == "/opt/ros/jazzy"
    with pytest.raises(RosEnvironmentError, match="AMENT_PREFIX_PATH is not set .* source /opt/ros/jazzy"):
        ensure_ros_environment({}, prefix=tmp_path / "nothing")


@pytest.mark.ros
def test_console_scripts_run_directly_from_the_venv(tmp_path):
    """bb2-launch flies a short mission and records it, bb2-analyze and bb2-replay read the bag, and a node's
    executable (<venv>/lib/bb2_ros/simulator, what ros2 run starts) runs: all without any ROS variable set."""
    mission = tmp_path / "short.yaml"
    mission.write_text(f"extends: {REPO / 'missions' / 'canyon.yaml'}\nname: short\nduration_s: 2\n")
    r = subprocess.run([str(VENV_BIN / "bb2-launch"), str(mission), "--out", str(tmp_path / "run"),
                        "--timeout", "120"], cwd=tmp_path, env=bare_env(), capture_output=True, text=True,
                       timeout=180)
    assert r.returncode == 0, r.stderr[-3000:]
    assert "mission complete" in r.stderr and (tmp_path / "run" / "metadata.yaml").is_file()
    r = subprocess.run([str(VENV_BIN / "bb2-analyze"), str(tmp_path / "run"), "--out", str(tmp_path / "an")],
                       cwd=tmp_path, env=bare_env(), capture_output=True, text=True, timeout=180)
    assert r.returncode == 0, r.stderr[-3000:]
    assert (tmp_path / "an" / "report.html").is_file()
    r = subprocess.run([str(VENV_BIN / "bb2-replay"), str(tmp_path / "run"), "--rate", "50", "--topics",
                        "/bb2/mission/progress"], cwd=tmp_path, env=bare_env(ROS_DOMAIN_ID=str(claimed_domain())),
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr[-3000:]
    assert "published" in r.stderr + r.stdout
    exe = Path(sys.prefix) / "lib" / "bb2_ros" / "simulator"
    if not exe.is_file():
        pytest.skip(f"{exe} not installed (bb2_ros_ws/install_into_venv.py)")
    r = subprocess.run([str(exe), "--ros-args", "-p", f"mission_file:={REPO / 'missions' / 'canyon.yaml'}",
                        "-p", "time_mode:=realtime", "-p", "rate_hz:=200.0", "-p", "duration_s:=0.5",
                        "-p", "exit_at_end:=true", "-p", "realtime_priority:=0", "-p", "hold_cpu_dma_latency:=false"],
                       cwd=tmp_path, env=bare_env(ROS_DOMAIN_ID=str(claimed_domain())), capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr[-3000:]
    assert "mission duration reached" in r.stderr + r.stdout


def test_a_venv_without_ros_says_what_to_set_in_one_line(tmp_path):
    """A copy of the interpreter with no ament index beside it (a prefix without the ROS wheels)."""
    env = bare_env(PYTHONPATH=str(REPO))
    r = subprocess.run([sys.executable, "-c",
                        "import sys, bb2_msgs_py.ros_env as e; sys.prefix = '/nonexistent'; "
                        "from bb2_tools.launcher import main; sys.exit(main(['x.yaml']))"],
                       env=env, capture_output=True, text=True, timeout=60)
    assert r.returncode == 2
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("bb2-launch: error: no ROS 2 environment"), r.stderr


def test_every_command_the_docs_name_is_installed_and_answers_help():
    """Each ``bb2-*`` command the README, the missions' README or the architecture names is a console script of
    the venv that answers ``--help`` with no ROS variable set (``bb2-record`` was named, not installed, until
    2026-12-07: ``python -m bb2_tools.recorder`` was the only way)."""
    import re

    docs = "".join((REPO / f).read_text() for f in ("README.md", "missions/README.md", "docs/ARCHITECTURE.md"))
    named = set(re.findall(r"`(bb2-[a-z]+)\b", docs))
    assert {"bb2-sim", "bb2-launch", "bb2-record", "bb2-analyze", "bb2-replay", "bb2-campaign"} <= named
    for cmd in sorted(named):
        exe = VENV_BIN / cmd
        assert exe.is_file(), f"{cmd} is named in the docs but not installed (pyproject [project.scripts])"
        r = subprocess.run([str(exe), "--help"], env=bare_env(), capture_output=True, text=True, timeout=120)
        assert r.returncode == 0 and r.stdout.startswith(f"usage: {cmd}"), (cmd, r.stdout[:300], r.stderr[-500:])


def test_every_option_the_docs_show_a_command_with_is_in_its_help():
    """An option the README (or the missions' README) writes after a command, on the same line (``bb2-launch ...
    --compose``), is one that command's ``--help`` lists: the docs do not drift from the CLIs."""
    import re

    docs = (REPO / "README.md").read_text() + (REPO / "missions" / "README.md").read_text()
    helps: dict[str, str] = {}
    missing, seen = set(), 0
    pattern = r"(bb2-(?:sim (?:maneuver|mission|sea)|launch|record|analyze|replay|campaign))\b([^`|]*)"
    for line in docs.splitlines():
        for m in re.finditer(pattern, line):
            cmd, rest = m.group(1), m.group(2)
            rest = re.sub(r"\bfor --[a-z0-9-]+", "", rest)  # "--wave-heading-deg D for --heading-deg": a rename
            for opt in re.findall(r"(?<![\w-])(--[a-z][a-z0-9-]*)", rest):
                if cmd not in helps:
                    exe, *sub = cmd.split()
                    r = subprocess.run([str(VENV_BIN / exe), *sub, "--help"], env=bare_env(), capture_output=True,
                                       text=True, timeout=120)
                    assert r.returncode == 0, (cmd, r.stderr[-500:])
                    helps[cmd] = r.stdout
                seen += 1
                if not re.search(rf"(?<![\w-]){re.escape(opt)}(?![\w-])", helps[cmd]):
                    missing.add((cmd, opt))
    assert seen > 50 and not missing, sorted(missing)
