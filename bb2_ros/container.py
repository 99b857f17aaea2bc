"""``container``: several BB2 nodes composed into one process and one executor.

Usage (what ``bb2-launch --compose`` starts; ``ros2 run bb2_ros container`` takes the same)::

    container --node simulator --ros-args -p time_mode:=lockstep ... -- --node mixer --ros-args ... --

Each ``--node NAME`` takes the arguments up to the next ``--node``: exactly what ``ros2 run bb2_ros NAME`` would
take alone.  Its ``--ros-args`` apply to it only (rclpy's ``cli_args`` with ``use_global_arguments=False``), so a
composed node has the parameters, remaps and topics it has in a process of its own; ``ros2 node list`` and
``ros2 param`` see each node by its name.  The nodes share one executor (:func:`bb2_ros.node_common.make_executor`)
and one DDS participant; their messages still go through the middleware (Fast DDS delivers them within the
process).  The process stops when a node is done (the simulator at the end of the mission) or on SIGINT/SIGTERM;
its exit status is the worst of its nodes' (0 clean, 1 runtime error, 2 bad input).  The recorder is not a
composable node: it waits on its own wait set (:mod:`bb2_tools.recorder`) and runs in a process of its own.
"""
from __future__ import annotations

import importlib
import sys
from typing import Any, Callable, Sequence

from bb2_ros.node_common import EXIT_BAD_INPUT, run_nodes

NODE_CLASSES: dict[str, str] = {
    "simulator": "bb2_ros.simulator:Simulator",
    "planner": "bb2_ros.planner:Planner",
    "path_following": "bb2_ros.path_following:PathFollowing",
    "l1_autopilot": "bb2_ros.l1_autopilot:L1Autopilot",
    "mixer": "bb2_ros.mixer:Mixer",
}
"""The composable nodes: name -> ``module:class`` (each class takes its argv, as under :func:`run_node`)."""

PROG = "container"


class UsageError(ValueError):
    """A container command line that names no node, an unknown node or one node twice."""


def split_nodes(args: Sequence[str]) -> list[tuple[str, list[str]]]:
    """``[(name, argv)]`` from ``--node NAME ARGS... --node NAME ARGS...`` (argv[0] of each is its name)."""
    args = list(args)
    if not args or args[0] != "--node":
        raise UsageError("expected --node NAME [ARGS ...] [--node NAME [ARGS ...] ...]")
    out: list[tuple[str, list[str]]] = []
    for a in args:
        if a == "--node":
            out.append(("", []))
        elif not out[-1][0]:
            out[-1] = (a, [a])
        else:
            out[-1][1].append(a)
    names = [n for n, _ in out]
    if "" in names:
        raise UsageError("--node needs a node name")
    unknown = [n for n in names if n not in NODE_CLASSES]
    if unknown:
        raise UsageError(f"unknown node(s) {unknown}: composable are {sorted(NODE_CLASSES)}")
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        raise UsageError(f"node(s) {twice} given twice: node names are unique in a graph")
    return out


def _factory(name: str) -> Callable[[list[str]], Any]:
    """Builds node ``name`` from its argv; its module is imported then (after the ROS environment is set)."""
    def build(argv: list[str]) -> Any:
        module, cls = NODE_CLASSES[name].split(":")
        return getattr(importlib.import_module(module), cls)(argv)

    return build


def main(args: Sequence[str] | None = None) -> int:
    """Entry point (``ros2 run bb2_ros container --node NAME ARGS ... [--node ...]``)."""
    argv = list(sys.argv if args is None else args)
    if len(argv) > 1 and argv[1] in ("-h", "--help"):
        print(__doc__)
        return 0
    try:
        nodes = split_nodes(argv[1:])
    except UsageError as exc:
        print(f"{PROG}: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    return run_nodes(PROG, [(name, _factory(name), node_argv) for name, node_argv in nodes], [argv[0]],
                     composed=True)


if __name__ == "__main__":
    sys.exit(main())
