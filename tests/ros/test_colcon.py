"""What a ROS 2 user runs on the workspace: upstream colcon and ros2 (assembled from ../shared/ros2_tooling once per
machine, see tests/ros2_tooling.py) order the seven packages by their declared dependencies, build any one of them
alone with the packages it needs (`colcon build --packages-up-to PKG`), and `ros2 pkg executables` finds the node
executables in the install space."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from ros2_tooling import tooling_env, tooling_venv  # noqa: E402  (tests/ros2_tooling.py)

REPO = Path(__file__).resolve().parents[2]
WS = REPO / "bb2_ros_ws"
ORDER = ["bb2_sim", "bb2_planner", "bb2_control", "bb2_mission", "bb2_msgs_py", "bb2_ros", "bb2_tools",
         "bb2_bringup"]  # bb2_bringup: launch files, params file and missions only (no Python module)
UP_TO = {  # each package and what it declares, transitively
    "bb2_sim": {"bb2_sim"},
    "bb2_planner": {"bb2_sim", "bb2_planner"},
    "bb2_control": {"bb2_sim", "bb2_planner", "bb2_control"},
    "bb2_mission": {"bb2_sim", "bb2_planner", "bb2_control", "bb2_mission"},
    "bb2_msgs_py": {"bb2_sim", "bb2_planner", "bb2_msgs_py"},
    "bb2_ros": set(ORDER) - {"bb2_tools", "bb2_bringup"},
    "bb2_tools": set(ORDER) - {"bb2_bringup"},
    "bb2_bringup": set(ORDER),
}

pytestmark = [pytest.mark.ros, pytest.mark.slow(seconds=200)]  # slow: started first (tests/conftest.py)


@pytest.fixture(scope="module")
def env():
    return tooling_env(tooling_venv())


def colcon(env, *args, cwd=WS, timeout=600):
    return subprocess.run(["colcon", *args], cwd=cwd, env=env, capture_output=True, text=True, timeout=timeout)


def test_colcon_orders_the_packages_by_their_declared_dependencies(env):
    r = colcon(env, "list", "--topological-order", "--names-only")
    assert r.returncode == 0, r.stderr
    names = r.stdout.split()
    assert sorted(names) == sorted(ORDER)
    for pkg, needs in UP_TO.items():  # every dependency comes before its dependant
        assert all(names.index(d) <= names.index(pkg) for d in needs), (pkg, names)
    for pkg, needs in UP_TO.items():
        r = colcon(env, "list", "--names-only", "--packages-up-to", pkg)
        assert r.returncode == 0, r.stderr
        assert set(r.stdout.split()) == needs, pkg


@pytest.mark.parametrize("pkg", ["bb2_sim", "bb2_ros"])
def test_colcon_build_packages_up_to_one_package(env, tmp_path, pkg):
    r = colcon(env, "--log-base", str(tmp_path / "log"), "build", "--packages-up-to", pkg,
               "--build-base", str(tmp_path / "build"), "--install-base", str(tmp_path / "install"))
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    built = {p.name for p in (tmp_path / "install").iterdir() if (p / "share" / p.name / "package.xml").is_file()}
    assert built == UP_TO[pkg]
    assert not list((WS / "src").rglob("*.egg-info")), "colcon must leave the source space clean"
    if pkg == "bb2_ros":  # the user's next step: source the install space, ros2 finds the executables
        r = subprocess.run(["bash", "-c", f"source {tmp_path / 'install' / 'setup.bash'} && "
                            "ros2 pkg executables bb2_ros"], env=env, capture_output=True, text=True, timeout=120)
        assert r.returncode == 0, r.stderr
        assert sorted(r.stdout.split()) == sorted(
            ["bb2_ros"] * 6 + ["container", "l1_autopilot", "mixer", "path_following", "planner", "simulator"])


@pytest.mark.parametrize("mode", ["copy", "symlink"])
def test_colcon_build_the_whole_workspace(env, tmp_path, mode):
    """colcon build and colcon build --symlink-install (colcon-core >= 0.20: the pinned setuptools is < 80) of
    every package; bb2_bringup installs its launch files, the params file and the missions into share/."""
    r = colcon(env, "--log-base", str(tmp_path / "log"), "build", *(["--symlink-install"] if mode == "symlink"
                                                                      else []),
               "--build-base", str(tmp_path / "build"), "--install-base", str(tmp_path / "install"))
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    built = {p.name for p in (tmp_path / "install").iterdir() if (p / "share" / p.name / "package.xml").exists()}
    assert built == set(ORDER)
    share = tmp_path / "install" / "bb2_bringup" / "share" / "bb2_bringup"
    for f in ("launch/bb2_graph.launch.py", "launch/fleet.launch.py", "config/bb2_graph.yaml",
              "config/foxglove_layout.json", "missions/canyon.yaml"):
        assert (share / f).is_file(), f
        assert (share / f).is_symlink() == (mode == "symlink"), f
    assert not list((WS / "src").rglob("*.egg-info")), "colcon must leave the source space clean"
    r = subprocess.run(["bash", "-c", f"source {tmp_path / 'install' / 'setup.bash'} && "
                        "ros2 launch bb2_bringup bb2_graph.launch.py --show-args"], env=env, capture_output=True,
                       text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    for arg in ("mission", "time_mode", "record", "namespace", "params_file", "compose", "group", "restart"):
        assert f"'{arg}'" in r.stdout, r.stdout


def test_the_setuptools_pin_allows_colcon_core_with_symlink_install(env):
    """colcon-core >= 0.20 (whose --symlink-install works) requires setuptools < 80: requirements.txt's pin must
    satisfy it, else pip falls back to colcon-core 0.19 (issue 13)."""
    import re

    pin = re.search(r"^setuptools==([\d.]+)", (REPO / "requirements.txt").read_text(), re.M).group(1)
    code = ("import importlib.metadata as m, json; print(json.dumps([m.version('colcon-core')] + "
            "[r for r in m.requires('colcon-core') if r.startswith('setuptools')]))")
    r = subprocess.run(["python", "-c", code], env=env, capture_output=True, text=True, timeout=60)
    import json

    version, *reqs = json.loads(r.stdout)
    assert tuple(int(x) for x in version.split(".")[:2]) >= (0, 20)
    from packaging.specifiers import SpecifierSet

    spec = SpecifierSet(reqs[0].split("(")[1].rstrip(")") if "(" in reqs[0] else reqs[0][len("setuptools"):])
    assert pin in spec, (pin, reqs)
