"""The node executables' entry (:mod:`bb2_ros.entry`): a SIGINT while a node's module still imports ends the process
with exit code 0 and without a traceback (a launch that stops its nodes in their first second printed each one's
``KeyboardInterrupt`` from deep inside an import, then ``process has died``); once the node's ``main`` runs, its own
handler stops it (exit 0 too)."""
from __future__ import annotations

import signal
import subprocess
import sys

SLOW = '''import sys, time
print("importing", flush=True)
time.sleep(60)   # a heavy import (numpy, scipy, rclpy, the ROM) in slow motion


def main():
    return 0
'''

MAIN_STOPS = '''import signal, sys, threading


def main():
    stop = threading.Event()
    signal.signal(signal.SIGINT, lambda *_: stop.set())   # a node's own handler (node_common.stop_signals)
    print("running", flush=True)
    stop.wait(60)
    print("stopped cleanly", flush=True)
    return 0
'''


def _interrupted(tmp_path, code: str, module: str, wait_for: str) -> subprocess.CompletedProcess:
    (tmp_path / f"{module}.py").write_text(code)
    p = subprocess.Popen([sys.executable, "-c", code_line(module)], cwd=tmp_path, stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True, env={"PYTHONPATH": str(tmp_path), "PATH": "/usr/bin"})
    assert p.stdout.readline().strip() == wait_for
    p.send_signal(signal.SIGINT)
    out, err = p.communicate(timeout=30)
    return subprocess.CompletedProcess(p.args, p.returncode, out, err)


def code_line(module: str) -> str:
    return f"import sys; from bb2_ros.entry import run; sys.exit(run('{module}:main'))"


def test_a_sigint_while_the_node_imports_ends_it_quietly_and_cleanly(tmp_path):
    r = _interrupted(tmp_path, SLOW, "slow_node", "importing")
    assert r.returncode == 0, (r.returncode, r.stderr)   # a clean stop, as once it runs (launch: finished cleanly)
    assert "Traceback" not in r.stderr and "KeyboardInterrupt" not in r.stderr, r.stderr
    # the plain import it replaces: the traceback this avoids
    p = subprocess.Popen([sys.executable, "-c", "import slow_node"], cwd=tmp_path, stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True, env={"PYTHONPATH": str(tmp_path), "PATH": "/usr/bin"})
    assert p.stdout.readline().strip() == "importing"
    p.send_signal(signal.SIGINT)
    _out, err = p.communicate(timeout=30)
    assert "KeyboardInterrupt" in err


def test_once_main_runs_its_own_handler_stops_it_cleanly(tmp_path):
    r = _interrupted(tmp_path, MAIN_STOPS, "running_node", "running")
    assert r.returncode == 0 and r.stdout.strip() == "stopped cleanly", (r.returncode, r.stdout, r.stderr)
