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
ORDER = ["bb2_sim", "bb2_planner", "bb2_control", "bb2_mission", "bb2_msgs_py", "bb2_ros", "bb2_tools"]
UP_TO = {  # each package and what it declares, transitively
    "bb2_sim": {"bb2_sim"},
    "bb2_planner": {"bb2_sim", "bb2_planner"},
    "bb2_control": {"bb2_sim", "bb2_planner", "bb2_control"},
    "bb2_mission": {"bb2_sim", "bb2_planner", "bb2_control", "bb2_mission"},
    "bb2_msgs_py": {"bb2_sim", "bb2_planner", "bb2_msgs_py"},
    "bb2_ros": set(ORDER) - {"bb2_tools"},
    "bb2_tools": set(ORDER),
}

pytestmark = pytest.mark.ros


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
            ["bb2_ros"] * 5 + ["l1_autopilot", "mixer", "path_following", "planner", "simulator"])
