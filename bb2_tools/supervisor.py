"""Process supervision for bb2-launch: start, watch, restart and stop a set of processes.

Each process (:class:`ProcessSpec`) runs in its own process group, with its stdout and stderr copied into
``<log_dir>/<name>.log`` and a ring buffer of the last lines; on Linux it gets SIGTERM when the supervising
process dies.  A process that ends is reported as a :class:`NodeExit` (exit code or signal, last log lines)
and handled by its :class:`RestartPolicy` (``stop`` the rest, ``restart`` up to N times, ``ignore``).
Stopping sends SIGINT to the process groups, then SIGTERM, then SIGKILL after each spec's grace periods,
stage by stage (``stop_stage``: lower first).

Nothing here knows ROS: :class:`Supervisor` is usable on its own, from Python and tests
(:mod:`bb2_tools.launcher` runs the BB2 graph with it).
"""
from __future__ import annotations

import collections
import ctypes
import os
import signal
import subprocess
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Iterable, Mapping, Sequence

from bb2_sim.names import did_you_mean

POLICIES = ("stop", "restart", "ignore")
DEFAULT_MAX_RESTARTS = 3


class LaunchError(ValueError):
    """Bad launcher input (mission, params file, restart policy, domain id ...)."""


# ============================================================================ restart policies
@dataclass(frozen=True)
class RestartPolicy:
    """What to do when a node exits on its own: ``stop`` the graph, ``restart`` it up to
    ``max_restarts`` times (then stop), or ``ignore`` it."""

    action: str = "stop"
    max_restarts: int = DEFAULT_MAX_RESTARTS

    def __post_init__(self):
        if self.action not in POLICIES:
            raise LaunchError(f"unknown policy {self.action!r}" + did_you_mean(self.action, POLICIES)
                              + f"; policies: {', '.join(POLICIES)}")
        if self.max_restarts < 0:
            raise LaunchError(f"the restart count must be >= 0, got {self.max_restarts}")


def parse_restart_policies(specs: Iterable[str], known: Iterable[str],
                           default_max: int = DEFAULT_MAX_RESTARTS,
                           option: str = "--restart") -> dict[str, RestartPolicy]:
    """Parse ``["simulator=stop,recorder=restart:5", "mixer=ignore"]`` into policies per node; ``default_max``: the
    count of a ``restart`` without one (``--max-restarts``); ``option``: what the errors name (the launch files':
    ``launch argument restart``)."""
    if default_max < 0:
        raise LaunchError(f"--max-restarts must be >= 0, got {default_max}")
    known = list(known)
    out: dict[str, RestartPolicy] = {}
    for spec in specs:
        for item in filter(None, (s.strip() for s in spec.split(","))):
            name, sep, value = item.partition("=")
            if not sep or not name or not value:
                raise LaunchError(f"{option} expects NODE=POLICY items, got {item!r}")
            if name not in known and name != "all":
                raise LaunchError(f"{option}: unknown node {name!r}" + did_you_mean(name, [*known, "all"])
                                  + f"; nodes: {', '.join(known)} (or all)")
            action, _, n = value.partition(":")
            try:
                max_n = int(n) if n else default_max
            except ValueError:
                raise LaunchError(f"{option}: bad restart count in {item!r} (restart:N, N >= 0)") from None
            try:
                policy = RestartPolicy(action, max_n)
            except LaunchError as exc:  # which item, with the policy's own words
                raise LaunchError(f"{option} {item}: {exc}") from None
            if n and action != "restart":
                raise LaunchError(f"{option}: a count only goes with 'restart', got {item!r}")
            for target in (known if name == "all" else [name]):
                out[target] = policy
    return out


def uses_default_max(specs: Iterable[str]) -> bool:
    """Whether any ``--restart`` item is a ``restart`` without its own count (the one ``--max-restarts`` sets)."""
    return any(item.partition("=")[2].strip() == "restart"
               for spec in specs for item in filter(None, (s.strip() for s in spec.split(","))))


# ============================================================================ supervision
@dataclass
class ProcessSpec:
    """A supervised process.

    ``command`` is an argv, or a function of the attempt number (0 first, 1 first restart ...)
    returning one.  ``finishes_graph``: exit code 0 means the job is done (the rest is stopped
    cleanly, not a failure).  ``stop_stage``: lower stages are stopped first (the recorder is
    stopped last).  ``ready``: optional readiness probe used by :meth:`Supervisor.start`.
    """

    name: str
    command: Sequence[str] | Callable[[int], Sequence[str]]
    policy: RestartPolicy = field(default_factory=RestartPolicy)
    finishes_graph: bool = False
    stop_stage: int = 0
    sigint_grace_s: float = 10.0
    sigterm_grace_s: float = 3.0
    ready: Callable[[], bool] | None = None
    env: Mapping[str, str] | None = None
    nice: int = 0  # niceness increment (> 0: yields the CPU to the control loop; e.g. the recorder)
    early: bool = False  # started at once by run_graph, alongside the ready-gated ones (needs nothing before it)
    nodes: int = 1  # the ROS nodes the process runs (a container of composed nodes: several)

    def argv(self, attempt: int) -> list[str]:
        cmd = self.command(attempt) if callable(self.command) else self.command
        return [str(c) for c in cmd]


def signal_name(returncode: int | None) -> str | None:
    """``"SIGKILL"`` for a return code of -9 (Popen's convention for death by signal)."""
    if returncode is None or returncode >= 0:
        return None
    try:
        return signal.Signals(-returncode).name
    except ValueError:
        return f"signal {-returncode}"


def exit_cause(returncode: int | None) -> str:
    """``"exit code 3"`` or ``"killed by SIGKILL"``."""
    if returncode is None:
        return "still running"
    sig = signal_name(returncode)
    return f"killed by {sig}" if sig else f"exit code {returncode}"


@dataclass
class NodeExit:
    """A process that ended, and what the supervisor did about it.

    ``action``: ``stop`` (it failed, the graph is stopped), ``restart``, ``ignore``,
    ``finished`` (a ``finishes_graph`` process exited 0) or ``shutdown`` (it ended while the
    supervisor was stopping everything).
    """

    name: str
    returncode: int
    attempt: int
    action: str
    last_lines: list[str]
    log_path: Path
    wall_time: float

    @property
    def cause(self) -> str:
        return exit_cause(self.returncode)

    def report(self, n_lines: int = 10) -> str:
        """A human report: which node, why, its last log lines and where the full log is."""
        head = f"node '{self.name}' ended ({self.cause})"
        if self.attempt:
            head += f" on restart {self.attempt}"
        tail = self.last_lines[-n_lines:]
        body = "".join(f"\n    | {line}" for line in tail) if tail else "\n    | (no output)"
        return f"{head}; last log lines:{body}\n    full log: {self.log_path}"


def _set_parent_death_signal() -> None:  # runs in the child between fork and exec
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(1, signal.SIGTERM)  # PR_SET_PDEATHSIG: die with the launcher
    except Exception:
        pass


class _Child:
    """A running process with a thread copying its output into a log file and a ring buffer."""

    def __init__(self, spec: ProcessSpec, attempt: int, log_path: Path, ring_lines: int,
                 env: Mapping[str, str], cwd: Path | None, echo: Callable[[str, str], None] | None):
        self.spec, self.attempt, self.log_path = spec, attempt, log_path
        self.ring: collections.deque[str] = collections.deque(maxlen=ring_lines)
        self.argv = spec.argv(attempt)
        self.started = time.monotonic()
        self.log = open(log_path, "ab", buffering=0)
        stamp = time.strftime("%Y-%m-%d %H:%M:%S")
        self.log.write(f"---- {stamp} attempt {attempt}: {' '.join(self.argv)}\n".encode())
        full_env = dict(env)
        full_env.update(spec.env or {})
        nice = int(spec.nice)

        def preexec() -> None:  # in the child between fork and exec
            if sys.platform.startswith("linux"):
                _set_parent_death_signal()
            if nice > 0:
                os.nice(nice)
        try:
            self.popen = subprocess.Popen(self.argv, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                                          stderr=subprocess.STDOUT, env=full_env, cwd=cwd,
                                          start_new_session=True, preexec_fn=preexec)
        except OSError as exc:
            self.log.close()
            raise LaunchError(f"cannot start node '{spec.name}' ({self.argv[0]}): {exc}") from None
        self.pgid = self.popen.pid
        self._echo = echo
        self.reader = threading.Thread(target=self._copy_output, name=f"log-{spec.name}", daemon=True)
        self.reader.start()

    def _copy_output(self) -> None:
        assert self.popen.stdout is not None
        for raw in iter(self.popen.stdout.readline, b""):
            try:
                self.log.write(raw)
            except ValueError:  # log closed
                break
            line = raw.decode("utf-8", "replace").rstrip("\r\n")
            self.ring.append(line)
            if self._echo:
                self._echo(self.spec.name, line)

    def signal(self, sig: int) -> None:
        try:
            os.killpg(self.pgid, sig)
        except (ProcessLookupError, PermissionError):
            pass

    def finish(self) -> list[str]:
        """After exit: make sure nothing of its group survives, drain the output, close the log."""
        self.signal(signal.SIGKILL)  # leftovers in the group (e.g. the node under `ros2 run`)
        self.reader.join(timeout=2.0)
        rc = self.popen.returncode
        try:
            self.log.write(f"---- exited: {exit_cause(rc)}\n".encode())
        except ValueError:
            pass
        self.log.close()
        return list(self.ring)


class Supervisor:
    """Starts, watches, restarts and stops a set of processes (see :class:`ProcessSpec`).

    Typical use::

        with Supervisor(specs, log_dir) as sup:
            sup.start()
            while not sup.done:
                for ev in sup.poll():
                    print(ev.report())
                time.sleep(0.1)
        # leaving the block stops whatever still runs

    ``done`` is true once a process failed under the ``stop`` policy (:attr:`failure`), a
    ``finishes_graph`` process exited 0 (:attr:`finished`), or nothing is left running.
    """

    def __init__(self, specs: Sequence[ProcessSpec], log_dir: str | os.PathLike, *,
                 env: Mapping[str, str] | None = None, cwd: str | os.PathLike | None = None,
                 ring_lines: int = 200, restart_delay_s: float = 0.5,
                 echo: Callable[[str, str], None] | None = None):
        names = [s.name for s in specs]
        if len(set(names)) != len(names):
            raise LaunchError(f"duplicate process names in {names}")
        self.specs = {s.name: s for s in specs}
        self.order = names
        self.log_dir = Path(log_dir)
        self.log_dir.mkdir(parents=True, exist_ok=True)
        self.env = dict(os.environ if env is None else env)
        self.env.setdefault("PYTHONUNBUFFERED", "1")
        self.cwd = Path(cwd) if cwd else None
        self.ring_lines = ring_lines
        self.restart_delay_s = restart_delay_s
        self.echo = echo
        self.children: dict[str, _Child] = {}
        self.attempts: dict[str, int] = {}
        self.exits: list[NodeExit] = []
        self.failure: NodeExit | None = None
        self.finished: NodeExit | None = None
        self.stopping = False
        self._pending_restarts: dict[str, float] = {}

    # ------------------------------------------------------------------ starting
    def log_path(self, name: str) -> Path:
        return self.log_dir / f"{name}.log"

    def start(self, names: Iterable[str] | None = None, *, ready_timeout_s: float = 30.0,
              interrupted: Callable[[], bool] = lambda: False) -> None:
        """Start ``names`` (default: all, in order); for a spec with ``ready``, wait until it is
        ready (or raise :class:`LaunchError` if ``ready_timeout_s`` passes).  Returns early when
        a started process dies (:meth:`poll` reports it) or ``interrupted()`` becomes true."""
        for name in (self.order if names is None else list(names)):
            if interrupted():
                return
            self._spawn(name, 0)
            if self.specs[name].ready is not None and not self.wait_ready(name, ready_timeout_s, interrupted):
                return

    def wait_ready(self, name: str, timeout_s: float,
                   interrupted: Callable[[], bool] = lambda: False) -> bool:
        """Wait until ``name`` is ready; False if it died or ``interrupted()`` first."""
        spec, child = self.specs[name], self.children[name]
        deadline = time.monotonic() + timeout_s
        while not spec.ready():
            if child.popen.poll() is not None or interrupted():
                return False
            if time.monotonic() > deadline:
                raise LaunchError(f"node '{name}' not ready after {timeout_s:g} s; log: {child.log_path}")
            time.sleep(0.05)
        return True

    def _spawn(self, name: str, attempt: int) -> None:
        if name in self.children:
            raise LaunchError(f"node '{name}' is already running")
        self.attempts[name] = attempt
        self.children[name] = _Child(self.specs[name], attempt, self.log_path(name), self.ring_lines,
                                     self.env, self.cwd, self.echo)

    # ------------------------------------------------------------------ watching
    def running(self) -> list[str]:
        return [n for n in self.order if n in self.children and self.children[n].popen.poll() is None]

    def pid(self, name: str) -> int:
        return self.children[name].popen.pid

    def stopped(self) -> set[str]:
        """The running nodes with a stopped process in their process group (``/proc`` state ``T``: SIGSTOP,
        a terminal's Ctrl-Z; ``t``: a debugger): frozen, neither dead nor working."""
        groups = {c.popen.pid: n for n, c in self.children.items() if c.popen.poll() is None}
        out: set[str] = set()
        for stat in Path("/proc").glob("[0-9]*/stat"):
            try:
                text = stat.read_text()
            except OSError:  # ended meanwhile
                continue
            fields = text[text.rfind(")") + 2:].split()
            if len(fields) > 2 and fields[0] in ("T", "t") and int(fields[2]) in groups:
                out.add(groups[int(fields[2])])
        return out

    def last_lines(self, name: str, n: int = 20) -> list[str]:
        child = self.children.get(name)
        return list(child.ring)[-n:] if child else []

    @property
    def done(self) -> bool:
        return (self.failure is not None or self.finished is not None
                or (not self.children and not self._pending_restarts))

    def poll(self) -> list[NodeExit]:
        """Collect processes that ended, apply their policies; return what happened."""
        events: list[NodeExit] = []
        now = time.monotonic()
        for name in list(self.children):
            child = self.children[name]
            rc = child.popen.poll()
            if rc is None:
                continue
            lines = child.finish()
            del self.children[name]
            spec = self.specs[name]
            if self.stopping:
                action = "shutdown"
            elif rc == 0 and spec.finishes_graph:
                action = "finished"
            elif spec.policy.action == "restart" and child.attempt < spec.policy.max_restarts:
                action = "restart"
            elif spec.policy.action == "ignore":
                action = "ignore"
            else:
                action = "stop"
            ev = NodeExit(name, rc, child.attempt, action, lines, child.log_path, now - child.started)
            events.append(ev)
            self.exits.append(ev)
            if action == "restart":
                self._pending_restarts[name] = now + self.restart_delay_s * (child.attempt + 1)
            elif action == "finished" and self.finished is None:
                self.finished = ev
            elif action == "stop" and self.failure is None:
                self.failure = ev
        if not self.stopping and self.failure is None:
            for name, when in list(self._pending_restarts.items()):
                if now >= when:
                    del self._pending_restarts[name]
                    self._spawn(name, self.attempts[name] + 1)
        return events

    # ------------------------------------------------------------------ stopping
    def stop(self, *, hurry: bool | Callable[[], bool] = False) -> list[NodeExit]:
        """Stop everything still running, stage by stage (SIGINT, then SIGTERM, then SIGKILL after
        each spec's grace periods; ``hurry`` -- or ``hurry()`` becoming true, e.g. on a second
        Ctrl-C -- shortens them to 1 s).  Returns the exits."""
        self.stopping = True
        self._pending_restarts.clear()
        first = len(self.exits)
        stages = sorted({self.specs[n].stop_stage for n in self.children})
        for stage in stages:
            group = [c for n, c in self.children.items() if self.specs[n].stop_stage == stage]
            self._terminate(group, hurry=hurry)
            self.poll()  # exits are recorded stage by stage
        return self.exits[first:]

    def _terminate(self, group: list[_Child], *, hurry: bool | Callable[[], bool]) -> None:
        hurried = hurry if callable(hurry) else (lambda: bool(hurry))
        for sig, grace_attr in ((signal.SIGINT, "sigint_grace_s"), (signal.SIGTERM, "sigterm_grace_s"),
                                (signal.SIGKILL, None)):
            alive = [c for c in group if c.popen.poll() is None]
            if not alive:
                return
            for c in alive:
                c.log.write(f"---- launcher: sending {signal.Signals(sig).name}\n".encode())
                c.signal(sig)
            grace = 5.0 if grace_attr is None else max(getattr(c.spec, grace_attr) for c in alive)
            start = time.monotonic()
            while any(c.popen.poll() is None for c in alive):
                waited = time.monotonic() - start
                if waited > grace or (hurried() and waited > 1.0):
                    break
                time.sleep(0.02)

    def __enter__(self) -> "Supervisor":
        return self

    def __exit__(self, *exc) -> None:
        self.stop(hurry=exc[0] is not None)
