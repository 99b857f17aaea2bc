"""How a node process takes its stop signals (``bb2_ros.node_common.stop_signals``): the first SIGINT or SIGTERM
asks it to stop, and says nothing; a SIGTERM after that (the launcher's escalation when the node did not stop on
SIGINT within its grace) writes every thread's Python stack to stderr -- the node's log -- and the process goes on
stopping; once stopped, further stop signals are ignored until it exits."""
from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]

SCRIPT = textwrap.dedent("""
    import os, signal, sys, threading, time
    from bb2_ros.node_common import restore_signals, stop_signals

    stop = threading.Event()
    previous = stop_signals(stop)
    os.kill(os.getpid(), signal.{first})
    time.sleep(0.2)
    print("asked to stop:", stop.is_set(), flush=True)
    print("---- first signal done", file=sys.stderr, flush=True)
    os.kill(os.getpid(), signal.SIGTERM)
    time.sleep(0.2)
    print("still running after the second signal", flush=True)
    restore_signals(previous, stop)
    os.kill(os.getpid(), signal.SIGINT)
    os.kill(os.getpid(), signal.SIGTERM)
    time.sleep(0.2)
    print("stop signals ignored once stopped", flush=True)
""")


# the line of the second signal, where the dump must show the main thread
SECOND_LINE = SCRIPT.splitlines().index("os.kill(os.getpid(), signal.SIGTERM)") + 1


def _run(first: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", SCRIPT.format(first=first)], cwd=REPO, capture_output=True,
                          text=True, timeout=60)


def test_a_second_sigterm_dumps_the_stacks_and_the_process_still_stops_cleanly():
    for first in ("SIGINT", "SIGTERM"):
        p = _run(first)
        assert p.returncode == 0, p.stderr
        assert p.stdout.splitlines() == ["asked to stop: True", "still running after the second signal",
                                         "stop signals ignored once stopped"], (first, p.stdout, p.stderr)
        before, after = p.stderr.split("---- first signal done", 1)
        assert "most recent call first" not in before, (first, p.stderr)  # the first signal says nothing
        # the escalation: where the main thread was, with the line that was running
        assert "most recent call first" in after and f'File "<string>", line {SECOND_LINE}' in after, (first, p.stderr)


WATCHDOG = textwrap.dedent("""
    import ctypes, sys, time
    from bb2_ros.node_common import ExitWatchdog

    ExitWatchdog.BACKSTOP_S = 1.0
    w = ExitWatchdog("stuck_node", timeout_s=0.5)
    w.arm(0)
    w.arm(3)   # armed again (the end of the spin loop with the node's code): the worst code is kept
    print("tearing down", flush=True)
    if sys.argv[1] == "releases":   # stuck in a call that lets the interpreter run (the middleware's waits)
        time.sleep(30)
    else:                           # stuck in a C call that holds the interpreter
        ctypes.PyDLL(None).sleep(30)
    print("never reached", flush=True)
""")


def test_a_stuck_teardown_ends_the_process_with_its_stacks_and_code():
    """The exit watchdog: a node process still there TEARDOWN_S after its stop request writes where it was stuck and
    exits -- with its own exit code when the interpreter is free, or 1 from faulthandler's thread when it is not."""
    import time

    for how, code, line in (("releases", 3, "stuck_node: still running 0.5 s after it was told to stop"),
                            ("holds", 1, None)):
        t0 = time.monotonic()
        p = subprocess.run([sys.executable, "-c", WATCHDOG, how], cwd=REPO, capture_output=True, text=True,
                           timeout=25)
        took = time.monotonic() - t0
        assert p.returncode == code, (how, p.returncode, p.stderr)
        assert p.stdout == "tearing down\n" and took < 20, (how, p.stdout, took)  # not the 30 s of the stuck call
        assert "most recent call first" in p.stderr and 'File "<string>", line' in p.stderr, (how, p.stderr)
        if line:
            assert f"{line} (stacks above): exiting with code 3" in p.stderr, p.stderr
