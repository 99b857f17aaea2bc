"""The node processes' garbage collector (:mod:`bb2_ros.heap`): the start-up heap settled and frozen before the
nodes spin, so no later collection walks it (a full collection of a node process's start-up heap took 30-45 ms:
an overrun of the real-time stepping thread), and the pauses measured for the statuses.

Run in a child process of its own: freezing is per process, and the test process keeps its collector as it is."""
from __future__ import annotations

import json
import subprocess
import sys
import textwrap
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]

CHILD = textwrap.dedent("""
    import gc, json, sys, weakref
    sys.path.insert(0, {repo!r})
    import numpy, scipy.interpolate, trimesh  # what a node process holds, about
    import bb2_sim.model
    from bb2_ros import heap

    class Node:
        pass

    # start-up garbage: a cycle nobody holds, which the settling collection must free (not freeze)
    a, b = Node(), Node()
    a.other, b.other = b, a
    gone = weakref.ref(a)
    del a, b
    before = heap.PAUSES.status_values()
    tracked = len(gc.get_objects())
    frozen = heap.settle()
    out = {{"before": before, "tracked": tracked, "frozen": frozen, "freeze_count": gc.get_freeze_count(),
           "cycle_freed": gone() is None, "walked_after": len(gc.get_objects())}}
    # while running: a new cycle, then a full collection, measured
    c = Node(); c.me = c; del c
    gc.collect()
    out["after"] = heap.PAUSES.status_values()
    heap.settle()  # a second call: the meter is not installed twice
    out["callbacks"] = sum(1 for cb in gc.callbacks if getattr(cb, "__self__", None) is heap.PAUSES)
    print(json.dumps(out))
""")


def test_settle_frees_the_startup_garbage_freezes_the_rest_and_measures_the_pauses():
    r = subprocess.run([sys.executable, "-c", CHILD.format(repo=str(REPO))], capture_output=True, text=True,
                       timeout=120)
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout.strip().splitlines()[-1])
    # nothing measured before settling: the status says so (empty), not "0 collections"
    assert out["before"] == {"gc_frozen_objects": "0", "gc_collections": "", "gc_pause_max_ms": ""}, out
    assert out["cycle_freed"], out                      # collected before the freeze, not frozen for ever
    assert out["frozen"] == out["freeze_count"] >= 0.9 * out["tracked"] > 50_000, out  # the heap of the imports
    assert out["walked_after"] < 1_000, out              # what any later collection still walks
    after = out["after"]
    assert after["gc_frozen_objects"] == str(out["frozen"]), after
    assert int(after["gc_collections"]) >= 1 and float(after["gc_pause_max_ms"]) > 0.0, after
    assert out["callbacks"] == 1, out
