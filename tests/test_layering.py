"""The layers run one way: importing any package (and every module in it) never imports a package above it,
the numerical cores and the mission layer import neither rclpy nor a message package, and no two modules of the
project import each other (directly or around a longer cycle)."""
from __future__ import annotations

import ast
import json
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
# bottom up: each package may import only those before it (docs/ARCHITECTURE.md)
LAYERS = ("bb2_sim", "bb2_planner", "bb2_control", "bb2_mission", "bb2_msgs_py", "bb2_ros", "bb2_tools")
ROS_FREE = ("bb2_sim", "bb2_planner", "bb2_control", "bb2_mission")
ROS_MODULES = ("rclpy", "rcl_interfaces", "builtin_interfaces", "std_msgs", "geometry_msgs", "sensor_msgs",
               "nav_msgs", "rosgraph_msgs", "diagnostic_msgs", "visualization_msgs", "tf2_msgs", "mcap_ros2")

PROBE = r"""
import importlib, json, pkgutil, sys
pkg = sys.argv[1]
mod = importlib.import_module(pkg)
for info in pkgutil.walk_packages(mod.__path__, pkg + "."):
    if info.name.rsplit(".", 1)[-1] != "__main__":
        importlib.import_module(info.name)
print(json.dumps(sorted({m.split(".")[0] for m in sys.modules})))
"""


@pytest.mark.parametrize("pkg", LAYERS)
def test_importing_a_package_never_imports_one_above_it(pkg):
    r = subprocess.run([sys.executable, "-c", PROBE, pkg], capture_output=True, text=True, cwd=REPO, timeout=120)
    assert r.returncode == 0, r.stderr
    loaded = set(json.loads(r.stdout.strip().splitlines()[-1]))
    above = set(LAYERS[LAYERS.index(pkg) + 1:])
    assert not loaded & above, f"importing {pkg} imported {sorted(loaded & above)}"
    if pkg in ROS_FREE:
        assert not loaded & set(ROS_MODULES), f"{pkg} must not need ROS: it imported {sorted(loaded & set(ROS_MODULES))}"


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(REPO).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _import_graph() -> dict[str, set[str]]:
    """module -> project modules it imports (at any depth of the file: module level or inside functions)."""
    files = [p for pkg in LAYERS for p in (REPO / pkg).rglob("*.py") if "__pycache__" not in p.parts]
    names = {_module_name(p) for p in files}
    graph: dict[str, set[str]] = {}
    for p in files:
        me = _module_name(p)
        pkg_of_me = me if p.name == "__init__.py" else me.rsplit(".", 1)[0]
        out: set[str] = set()
        for node in ast.walk(ast.parse(p.read_text(), str(p))):
            targets: list[str] = []
            if isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    anchor = pkg_of_me.split(".")
                    anchor = anchor[:len(anchor) - (node.level - 1)]
                    base = ".".join(anchor + ([base] if base else []))
                targets = [base] + [f"{base}.{a.name}" for a in node.names]
            for t in targets:
                while t and t not in names:
                    t = t.rpartition(".")[0]
                if t and t != me and not me.startswith(t + "."):  # a module's own package __init__ is not a cycle
                    out.add(t)
        graph[me] = out
    return graph


def test_no_two_modules_import_each_other():
    graph = _import_graph()
    # Tarjan's strongly connected components: any component of more than one module is a cycle
    index, low, stack, on, comps, counter = {}, {}, [], set(), [], [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in graph.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            comps.append(comp)

    sys.setrecursionlimit(10000)
    for v in graph:
        if v not in index:
            visit(v)
    cycles = [sorted(c) for c in comps if len(c) > 1]
    assert not cycles, f"modules that import each other: {cycles}"


def test_no_module_imports_a_layer_above_its_own():
    bad = []
    for me, deps in _import_graph().items():
        mine = LAYERS.index(me.split(".")[0])
        bad += [f"{me} -> {d}" for d in deps if LAYERS.index(d.split(".")[0]) > mine]
    assert not bad, bad
