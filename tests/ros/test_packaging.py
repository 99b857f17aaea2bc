"""bb2_ros_ws: the colcon/ament_python packaging, checked statically (colcon is not available here),
by running colcon's own setup.py install command, and by installing it into a prefix with
bb2_ros_ws/install_into_venv.py and running the installed executables."""
from __future__ import annotations

import configparser
import importlib
import importlib.util
import os
import re
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from bb2_tools.launcher import CONTAINER, FOXGLOVE, GRAPH_NODES

REPO = Path(__file__).resolve().parents[2]
WS = REPO / "bb2_ros_ws"
PACKAGES = ("bb2_sim", "bb2_planner", "bb2_control", "bb2_mission", "bb2_msgs_py", "bb2_ros", "bb2_tools")
# the layers, bottom up: a package may import (and declares) only packages before it
LAYERS = PACKAGES
ROS_FREE = ("bb2_sim", "bb2_planner", "bb2_control", "bb2_mission")

# The executables the graph uses: ros2 package / executable -> Python entry point.
EXECUTABLES = {
    ("bb2_ros", "simulator"): "bb2_ros.simulator:main",
    ("bb2_ros", "planner"): "bb2_ros.planner:main",
    ("bb2_ros", "path_following"): "bb2_ros.path_following:main",
    ("bb2_ros", "l1_autopilot"): "bb2_ros.l1_autopilot:main",
    ("bb2_ros", "mixer"): "bb2_ros.mixer:main",
    ("bb2_tools", "recorder"): "bb2_tools.recorder:main",
}
CONTAINER_EXECUTABLE = {("bb2_ros", "container"): "bb2_ros.container:main"}  # the composed nodes' process
FOXGLOVE_EXECUTABLE = {("bb2_tools", "foxglove_bridge"): "bb2_tools.foxglove_live:main"}  # bb2-launch --foxglove

# package.xml format 3 dependency tags (REP 149)
DEP_TAGS = {"depend", "build_depend", "build_export_depend", "buildtool_depend", "buildtool_export_depend",
            "exec_depend", "test_depend", "doc_depend", "conflict", "replace", "group_depend", "member_of_group"}
# import name -> rosdep key for the non-ROS Python libraries the code uses
PY_KEYS = {"numpy": "python3-numpy", "scipy": "python3-scipy", "yaml": "python3-yaml",
           "matplotlib": "python3-matplotlib", "trimesh": "python3-trimesh-pip"}
ROS_PY_PACKAGES = re.compile(r"\b(rclpy|ament_index_python|rcl_interfaces|builtin_interfaces|[a-z_]+_msgs)\b")


def _load_ws_tool():
    spec = importlib.util.spec_from_file_location("bb2_ros_ws_install", WS / "install_into_venv.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


ws_tool = _load_ws_tool()


def manifest(pkg: str) -> ET.Element:
    return ET.parse(WS / "src" / pkg / "package.xml").getroot()


def exec_deps(pkg: str) -> set[str]:
    root = manifest(pkg)
    return {e.text.strip() for e in root if e.tag in ("exec_depend", "depend")}


LAUNCH_PACKAGES = ("bb2_bringup",)  # launch files, params file, missions: no Python module (issue 13)


def test_workspace_holds_exactly_the_seven_packages():
    assert [p.name for p in ws_tool.packages()] == sorted(PACKAGES + LAUNCH_PACKAGES)


@pytest.mark.parametrize("pkg", PACKAGES)
def test_package_xml_is_valid_format_3(pkg):
    root = manifest(pkg)
    assert root.tag == "package" and root.get("format") == "3"
    assert root.findtext("name") == pkg
    assert re.fullmatch(r"\d+\.\d+\.\d+", root.findtext("version") or "")
    assert (root.findtext("description") or "").strip()
    maint = root.findall("maintainer")
    assert maint and all(m.get("email") and "@" in m.get("email") and m.text.strip() for m in maint)
    assert root.findall("license") and all(lic.text.strip() for lic in root.findall("license"))
    assert root.find("export/build_type").text == "ament_python"
    allowed = {"name", "version", "description", "maintainer", "license", "url", "author", "export"} | DEP_TAGS
    assert {e.tag for e in root} <= allowed, {e.tag for e in root} - allowed
    deps = [e.text.strip() for e in root if e.tag in DEP_TAGS]
    assert ("rclpy" in deps) == (pkg not in ROS_FREE), "rclpy declared exactly where the code uses it"
    assert len(deps) == len(set(deps)), "every dependency once"
    # the XML prolog a ROS package.xml carries (the format 3 schema)
    head = (WS / "src" / pkg / "package.xml").read_text().splitlines()[:2]
    assert head[0].startswith("<?xml") and "package_format3.xsd" in head[1]


@pytest.mark.parametrize("pkg", PACKAGES)
def test_setup_cfg_and_resource_marker_for_ros2_run(pkg):
    cfg = configparser.ConfigParser()
    cfg.read(WS / "src" / pkg / "setup.cfg")
    assert cfg["develop"]["script_dir"] == f"$base/lib/{pkg}"
    assert cfg["install"]["install_scripts"] == f"$base/lib/{pkg}"
    marker = WS / "src" / pkg / "resource" / pkg
    assert marker.is_file()
    kw = ws_tool.read_setup(WS / "src" / pkg)
    assert kw["name"] == pkg and kw["version"] == manifest(pkg).findtext("version")
    data = {target: list(files) for target, files in kw["data_files"]}
    assert data["share/ament_index/resource_index/packages"] == [f"resource/{pkg}"]
    assert data[f"share/{pkg}"] == ["package.xml"]


@pytest.mark.parametrize("pkg", PACKAGES)
def test_code_lives_once_at_the_top_level(pkg):
    link = WS / "src" / pkg / pkg
    assert link.is_symlink() and os.readlink(link) == f"../../../{pkg}"
    assert link.resolve() == (REPO / pkg).resolve()
    kw = ws_tool.read_setup(WS / "src" / pkg)
    assert "package_dir" not in kw  # colcon --symlink-install breaks on package_dir paths outside the package
    want = sorted(".".join(p.parent.relative_to(REPO).parts) for p in (REPO / pkg).rglob("__init__.py")
                  if "__pycache__" not in p.parts)
    assert sorted(kw["packages"]) == want
    # data files of the top-level package are shipped as package data
    data_files = [p for p in (REPO / pkg / "data").rglob("*") if p.is_file()] if (REPO / pkg / "data").is_dir() else []
    shipped = {f for pattern in kw["package_data"][pkg] for f in (REPO / pkg).glob(pattern)}
    assert set(data_files) <= shipped, sorted(map(str, set(data_files) - shipped))


def test_console_scripts_are_the_graph_executables_and_resolve():
    found = {}
    for pkg in PACKAGES:
        for exe, ep in ws_tool.console_scripts(ws_tool.read_setup(WS / "src" / pkg)).items():
            found[(pkg, exe)] = ep
    every = EXECUTABLES | CONTAINER_EXECUTABLE | FOXGLOVE_EXECUTABLE
    # each console script is its package's entry (<pkg>.entry:<exe>: quiet on a SIGINT while it imports), which
    # runs the node's main
    assert found == {(pkg, exe): f"{pkg}.entry:{exe}" for pkg, exe in every}
    assert {(pkg, exe): importlib.import_module(f"{pkg}.entry").TARGETS[exe] for pkg, exe in every} == every
    assert {(n.package, n.executable): n.entry_point for n in GRAPH_NODES} == EXECUTABLES
    assert {(CONTAINER.package, CONTAINER.executable): CONTAINER.entry_point} == CONTAINER_EXECUTABLE
    assert {(FOXGLOVE.package, FOXGLOVE.executable): FOXGLOVE.entry_point} == FOXGLOVE_EXECUTABLE
    for (pkg, exe), ep in [*found.items(), *every.items()]:
        module, func = ep.split(":")
        assert module.split(".")[0] == pkg, f"{pkg}/{exe} must run code of its own package"
        obj = getattr(importlib.import_module(module), func)
        assert callable(obj), ep


def test_bb2_dependencies_are_acyclic_for_colcon():
    """colcon refuses to order packages whose run dependencies form a cycle."""
    deps = {p: {d for d in exec_deps(p) if d in PACKAGES} for p in PACKAGES}
    ordered: list[str] = []
    while len(ordered) < len(PACKAGES):
        ready = sorted(p for p in PACKAGES if p not in ordered and deps[p] <= set(ordered))
        assert ready, f"cycle among {sorted(set(PACKAGES) - set(ordered))}: {deps}"
        ordered += ready
    assert ordered[-1] == "bb2_tools"  # the tools use every other package


@pytest.mark.parametrize("pkg", PACKAGES)
def test_every_imported_bb2_package_is_declared_and_below(pkg):
    """Honest manifests: every bb2_* package the code imports is an exec_depend, and it is a layer below."""
    text = "\n".join(p.read_text() for p in (REPO / pkg).rglob("*.py") if "__pycache__" not in p.parts)
    used = set(re.findall(r"^\s*(?:from|import)\s+(bb2_\w+)", text, re.M)) - {pkg}
    declared = {d for d in exec_deps(pkg) if d.startswith("bb2_")}
    assert used <= declared, f"imported but not declared: {sorted(used - declared)}"
    below = set(LAYERS[:LAYERS.index(pkg)])
    assert declared <= below, f"declared above its layer: {sorted(declared - below)}"


def _code_names(pkg: str) -> str:
    """What the code of ``pkg`` names: its imports and its string constants ("nav_msgs/msg/Odometry" for
    message_class), not its docstrings (a docstring mentioning a message package is no dependency)."""
    import ast

    out = []
    for p in (REPO / pkg).rglob("*.py"):
        if "__pycache__" in p.parts:
            continue
        tree = ast.parse(p.read_text())
        docs = {id(n.body[0].value) for n in ast.walk(tree)
                if isinstance(n, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)) and n.body
                and isinstance(n.body[0], ast.Expr) and isinstance(n.body[0].value, ast.Constant)}
        for n in ast.walk(tree):
            if isinstance(n, ast.Import):
                out += [a.name for a in n.names]
            elif isinstance(n, ast.ImportFrom) and n.module:
                out.append(n.module)
            elif isinstance(n, ast.Constant) and isinstance(n.value, str) and id(n) not in docs:
                out.append(n.value)
    return "\n".join(out)


@pytest.mark.parametrize("pkg", PACKAGES)
def test_every_imported_ros_and_python_dependency_is_declared(pkg):
    declared = exec_deps(pkg)
    text = "\n".join(p.read_text() for p in (REPO / pkg).rglob("*.py") if "__pycache__" not in p.parts)
    code = "\n".join(line for line in text.splitlines() if not line.lstrip().startswith("#"))
    used_ros = set(ROS_PY_PACKAGES.findall(_code_names(pkg))) - {"bb2_msgs"}
    used_ros = {u for u in used_ros if importlib.util.find_spec(u) is not None}  # real ROS packages only
    assert used_ros - {"tf2_msgs"} <= declared, f"undeclared: {sorted(used_ros - declared)}"
    used_py = set(re.findall(r"^\s*(?:from|import)\s+(\w+)", code, re.M)) & set(PY_KEYS)
    assert {PY_KEYS[m] for m in used_py} <= declared, f"undeclared: {sorted(used_py)}"


def test_colcon_install_command_lays_out_lib_and_share(tmp_path):
    """What colcon's ament_python build runs (no --symlink-install), for every package."""
    env = dict(os.environ, PYTHONDONTWRITEBYTECODE="1")
    prefix = tmp_path / "install"
    for pkg in PACKAGES:
        build = tmp_path / "build" / pkg
        build.mkdir(parents=True)
        cmd = [sys.executable, "setup.py", "-q", "egg_info", "--egg-base", str(build), "build", "--build-base",
               str(build / "build"), "install", "--prefix", str(prefix), "--record", str(build / "install.log"),
               "--single-version-externally-managed"]
        r = subprocess.run(cmd, cwd=WS / "src" / pkg, env=env, capture_output=True, text=True, timeout=120)
        assert r.returncode == 0, r.stderr
        assert (prefix / "share" / "ament_index" / "resource_index" / "packages" / pkg).is_file()
        assert (prefix / "share" / pkg / "package.xml").is_file()
    site = next(prefix.glob("lib/python3*/site-packages"))
    assert (site / "bb2_planner" / "data" / "paths").is_dir() and (site / "bb2_ros" / "simulator.py").is_file()
    for pkg, exe in EXECUTABLES:
        script = prefix / "lib" / pkg / exe
        assert script.is_file() and os.access(script, os.X_OK)
        assert f"'{exe}'" in script.read_text()  # setuptools' console-script wrapper for this entry point
    assert (prefix / "share" / "bb2_tools" / "missions" / "canyon.yaml").is_file()
    assert not list((WS / "src").rglob("*.egg-info")), "colcon must leave the source space clean"


def installed_files(prefix: Path) -> set[Path]:
    """The files of install_into_venv.py's list for ``prefix`` that are there."""
    r = subprocess.run([sys.executable, str(WS / "install_into_venv.py"), "--list", "--prefix", str(prefix)],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    return {p for p in map(Path, r.stdout.split()) if p.is_file()}


def test_install_into_prefix_gives_what_ros2_run_looks_for(tmp_path):
    prefix = tmp_path / "venv"
    ours = installed_files(Path(sys.prefix))  # this environment's own install (run.sh setup), if it has one
    r = subprocess.run([sys.executable, str(WS / "install_into_venv.py"), "-q", "--prefix", str(prefix)],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stdout + r.stderr
    # left as it was: pip's --force-reinstall into another prefix first uninstalled this environment's copy, and
    # after the suite `ros2 run` and bb2-launch's lib runner found no executables here
    assert installed_files(Path(sys.prefix)) == ours, sorted(ours - installed_files(Path(sys.prefix)))[:5]
    for pkg in PACKAGES:
        assert (prefix / "share" / "ament_index" / "resource_index" / "packages" / pkg).is_file()
        assert (prefix / "share" / pkg / "package.xml").read_text() == (WS / "src" / pkg / "package.xml").read_text()
    for pkg, exe in EXECUTABLES:
        script = prefix / "lib" / pkg / exe
        assert os.access(script, os.X_OK) and script.read_text().startswith(f"#!{sys.executable}\n")
        assert f"from {pkg}.entry import {exe}" in script.read_text()
    for pkg in PACKAGES:  # no second copy of the code (the editable install provides it)
        assert not list(prefix.glob(f"lib/python3*/site-packages/{pkg}")), pkg
    env = dict(os.environ, AMENT_PREFIX_PATH=f"{prefix}{os.pathsep}{sys.prefix}")
    # the ament index finds the packages, and the launcher's `lib` runner uses the installed executables
    probe = ("from ament_index_python.packages import get_package_prefix as g; "
             "from bb2_tools.launcher import GRAPH_NODES, node_command; "
             "print(g('bb2_ros')); print(node_command(GRAPH_NODES[-2], 'lib')[0])")
    r = subprocess.run([sys.executable, "-c", probe], env=env, capture_output=True, text=True, timeout=60)
    assert r.returncode == 0, r.stderr
    assert r.stdout.split() == [str(prefix), str(prefix / "lib" / "bb2_ros" / "mixer")]
    # harmless calls of installed executables, run as `ros2 run` would (exec the file)
    r = subprocess.run([str(prefix / "lib" / "bb2_tools" / "recorder"), "--help"], env=env,
                       capture_output=True, text=True, timeout=60)
    assert r.returncode == 0 and "usage: bb2-record" in r.stdout, r.stderr
    r = subprocess.run([str(prefix / "lib" / "bb2_ros" / "mixer"), "--ros-args", "--params-file",
                        str(tmp_path / "missing.yaml")], env=env, capture_output=True, text=True, timeout=60)
    assert r.returncode == 2 and "Traceback" not in r.stderr, r.stderr  # the node's own bad-input exit
