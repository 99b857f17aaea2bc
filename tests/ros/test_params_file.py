"""``config/bb2_graph.yaml`` documents every parameter the nodes declare, with the node's own default, and none
that no node declares (its header says it lists them all; before 2026-12-07 the simulator's ``end_at_progress``
and ``sensor_suite`` and the path follower's ``rejoin_run`` were missing, and ``wait_for_commands`` was declared in
real time only).  Each node is built as ``ros2 run`` builds it (its class, its argv) in a process of its own, in
lockstep and in real time, and its parameters are read from the node itself."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from bb2_sim.yaml_files import load as load_yaml
from rosenv import claimed_domain, ros_env  # noqa: E402  (tests/rosenv.py)

pytestmark = pytest.mark.ros

REPO = Path(__file__).resolve().parents[2]
NODES = ("simulator", "planner", "path_following", "l1_autopilot", "mixer")
RCLPY_OWN = {"use_sim_time", "start_type_description_service"}  # declared by rclpy for every node

PROBE = r"""
import importlib, json, sys
import rclpy
from bb2_ros.container import NODE_CLASSES
name, mode = sys.argv[1], sys.argv[2]
argv = [name, "--ros-args", "-p", f"mission_file:={sys.argv[3]}", "-p", f"time_mode:={mode}"]
rclpy.init(args=argv)
module, cls = NODE_CLASSES[name].split(":")
shell = getattr(importlib.import_module(module), cls)(argv)
node = getattr(shell, "node", shell)
print("PARAMS " + json.dumps({k: p.value for k, p in node._parameters.items()}))
"""


def _declared(mode: str) -> dict[str, dict]:
    env = ros_env(claimed_domain())
    procs = {n: subprocess.Popen([sys.executable, "-c", PROBE, n, mode, str(REPO / "missions" / "straight.yaml")],
                                 cwd=REPO, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
             for n in NODES}
    out = {}
    for n, p in procs.items():
        stdout, stderr = p.communicate(timeout=120)
        line = [x for x in stdout.splitlines() if x.startswith("PARAMS ")]
        assert line, (n, stderr[-2000:])
        out[n] = json.loads(line[-1][len("PARAMS "):])
    return out


@pytest.mark.parametrize("mode", ["lockstep", "realtime"])
def test_the_params_file_lists_every_declared_parameter_with_its_default(mode):
    doc = load_yaml((REPO / "config" / "bb2_graph.yaml").read_text())
    common = doc["/**"]["ros__parameters"]
    declared = _declared(mode)
    missing, differ = [], []
    for node, params in declared.items():
        own = doc.get(node, {}).get("ros__parameters", {})
        for name, value in params.items():
            if name in RCLPY_OWN or name.startswith("qos_overrides."):
                continue
            if name not in common and name not in own:
                missing.append((node, name))
            elif name != "mission_file" and name != "time_mode":  # (set on the probe's command line)
                doc_value = own.get(name, common.get(name))
                if doc_value != value and not (isinstance(value, float) and doc_value == value):
                    differ.append((node, name, value, doc_value))
    assert not missing, f"declared but not in config/bb2_graph.yaml: {missing}"
    assert not differ, f"(node, parameter, the node's default, the file's): {differ}"
    everyone = set().union(*declared.values())
    assert not sorted(set(common) - everyone), "in config/bb2_graph.yaml, declared by no node"
