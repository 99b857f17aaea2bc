"""Where the runs fly: ``local`` (a process pool on this machine) or ``ray`` (a Ray cluster).

Both call :func:`bb2_tools.campaign.worker.run_tasks` for a chunk of runs (one run, or for a campaign on the
library runner up to ``batch`` runs flown together by the batch ROM: :func:`chunk_size`) and hand each row to the
driver's ``on_row`` as it lands, so the results are the same whatever the engine, the number of workers, the
chunks or the order of completion.  At most a small window of chunks is in flight (about twice the workers), so
a 100,000-run campaign never holds more than that in memory.

A worker that dies (SIGKILL, out of memory) breaks the local pool: the pool is rebuilt and the runs that
were in flight are flown again; a run in flight at three such deaths is recorded as ``error``.  Ray retries
a task whose worker died by itself (``max_retries``) and the run is recorded as ``error`` if it still fails.
"""
from __future__ import annotations

import collections
import math
import os
from typing import Any, Callable, Iterable

from bb2_tools.campaign.spec import CampaignSpec
from bb2_tools.campaign.worker import BATCH_MIN, batched, may_batch, run_tasks

__all__ = ["LocalEngine", "RayEngine", "make_engine", "chunk_size", "ENGINES", "DEFAULT_BATCH"]

ENGINES = ("local", "ray")
DEFAULT_BATCH = 128
"""Most runs (maneuvers or missions) one worker flies together (``bb2-campaign --batch``)."""
_MAX_ATTEMPTS = 3
_PRELOAD = ["bb2_tools.campaign.worker", "bb2_mission.runner", "bb2_mission.schema", "bb2_sim.maneuvers",
            "bb2_sim.metrics", "scipy.spatial", "scipy.special"]

OnRow = Callable[[dict[str, Any]], None]
OnTick = Callable[..., None]
"""Called about twice a second while runs fly: ``on_tick(flying)``, the runs' worth flown by the chunks in flight
that have not landed yet (from the workers: the local pool through a shared array, Ray through an actor)."""

# ------------------------------------------------------------------------------------------ local
_SPEC: CampaignSpec | None = None
_FLYING: Any = None     # the pool's shared array: per slot of the window, the runs' worth its chunk has flown


def _init_worker(spec: CampaignSpec, flying: Any = None) -> None:
    global _SPEC, _FLYING
    _SPEC, _FLYING = spec, flying
    os.environ.setdefault("MPLBACKEND", "Agg")


def _local_task(indices: list[int], slot: int = -1) -> list[dict[str, Any]]:
    assert _SPEC is not None
    flying = _FLYING

    def on_progress(done: float) -> None:
        flying[slot] = done

    return run_tasks(_SPEC, indices, on_progress if flying is not None and slot >= 0 else None)


def chunk_size(spec: CampaignSpec, total: int, workers: int, batch: int = DEFAULT_BATCH) -> int:
    """Runs per task for ``total`` runs on ``workers``: 1, or for a maneuver or mission campaign on the library
    runner equal chunks of at most ``batch``, as many as a multiple of the workers (1000 runs, 2 workers, batch
    128: eight chunks of 125), so that every worker flies full batches to the end (a share recomputed from the
    runs left would shrink the last chunks below :data:`~bb2_tools.campaign.worker.BATCH_MIN` and fly them one
    by one, at half the batch's speed).  A share below BATCH_MIN, or a campaign none of whose runs can fly in a
    batch (:func:`~bb2_tools.campaign.worker.may_batch`: missions on their navigation estimate): 1, the runs go
    out one by one, each landing as it finishes."""
    if not batched(spec) or batch < BATCH_MIN or total <= 0:
        return 1
    workers = max(1, workers)
    rounds = math.ceil(total / (workers * int(batch)))
    share = math.ceil(total / (workers * rounds))
    return share if share >= BATCH_MIN and may_batch(spec) else 1


def _take(pending: collections.deque, n: int) -> list[int]:
    return [pending.popleft() for _ in range(min(n, len(pending)))]


def _lost_row(spec: CampaignSpec, index: int, why: str) -> dict[str, Any]:
    return {"index": int(index), "seed": spec.run_seed(index), "status": "error", "message": why,
            "wall_time_s": math.nan}


class LocalEngine:
    """A process pool of ``workers`` processes (forkserver, the project preloaded)."""

    name = "local"

    def __init__(self, workers: int | None = None, batch: int = DEFAULT_BATCH) -> None:
        self.workers = max(1, int(workers or os.cpu_count() or 1))
        self.batch = int(batch)

    def describe(self) -> str:
        return f"local, {self.workers} worker process{'es' if self.workers != 1 else ''}"

    def prepare(self) -> None:
        """Nothing to reach before the campaign: the pool starts with the runs."""

    def run(self, spec: CampaignSpec, indices: Iterable[int], on_row: OnRow, on_tick: OnTick | None = None) -> None:
        import multiprocessing as mp
        from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
        from concurrent.futures.process import BrokenProcessPool

        ctx = mp.get_context("forkserver")
        ctx.set_forkserver_preload(_PRELOAD)
        pending = collections.deque(indices)
        attempts: collections.Counter[int] = collections.Counter()
        window = 2 * self.workers
        flying = ctx.Array("d", window, lock=False)   # what each slot's chunk has flown (run_tasks' on_progress)
        while pending:
            broken = False
            size = chunk_size(spec, len(pending), self.workers, self.batch)
            flying[:] = [0.0] * window
            free = list(range(window))
            slots: dict[Any, int] = {}
            with ProcessPoolExecutor(self.workers, mp_context=ctx, initializer=_init_worker,
                                     initargs=(spec, flying)) as pool:
                inflight: dict[Any, list[int]] = {}
                while (pending or inflight) and not broken:
                    while pending and len(inflight) < window:
                        chunk = _take(pending, size)
                        try:
                            f = pool.submit(_local_task, chunk, free[-1])
                        except BrokenProcessPool:
                            pending.extendleft(reversed(chunk))
                            broken = True
                            break
                        inflight[f], slots[f] = chunk, free.pop()
                    if not inflight:
                        break
                    done, _ = wait(list(inflight), timeout=0.5, return_when=FIRST_COMPLETED)
                    for f in done:
                        exc = f.exception()
                        if isinstance(exc, BrokenProcessPool):
                            broken = True
                            continue
                        chunk = inflight.pop(f)
                        why = "" if exc is None else " ".join(f"{type(exc).__name__}: {exc}".split())[:2000]
                        for row in (f.result() if exc is None else [_lost_row(spec, i, why) for i in chunk]):
                            on_row(row)
                        flying[slots[f]] = 0.0
                        free.append(slots.pop(f))
                    if on_tick:
                        on_tick(0.0 if broken else sum(flying[k] for k in slots.values()))
                if broken:   # a worker died: fly what was in flight again (a run at three deaths is an error)
                    for f, chunk in sorted(inflight.items(), key=lambda fc: -fc[1][0]):
                        if f.done() and f.exception() is None:
                            for row in f.result():
                                on_row(row)
                            continue
                        for i in reversed(chunk):
                            attempts[i] += 1
                            if attempts[i] >= _MAX_ATTEMPTS:
                                on_row(_lost_row(spec, i, f"worker process died {attempts[i]} times while this "
                                                          "run was in flight"))
                            else:
                                pending.appendleft(i)
                    pool.shutdown(wait=True, cancel_futures=True)


# ------------------------------------------------------------------------------------------ ray
ADDRESS_PROBE_TIMEOUT_S = 5.0  # a TCP connect to --address HOST:PORT before Ray's own (minutes of retries)


def _last_ray_cluster() -> str:
    """The address ``ray start`` last wrote on this machine (what ``ray.init(address="auto")`` connects to), or ''."""
    try:
        from ray._private.utils import read_ray_address  # (Ray's own reader of its address file)

        return read_ray_address() or ""
    except Exception:  # noqa: BLE001 -- another Ray version: leave "auto" to Ray
        return ""


class _FlyingSink:
    """A Ray actor (no CPU): what each chunk in flight has flown (``run_tasks``' ``on_progress``, by chunk key)."""

    def __init__(self) -> None:
        self.done: dict[int, float] = {}

    def set(self, key: int, done: float) -> None:
        self.done[key] = done

    def drop(self, key: int) -> None:
        self.done.pop(key, None)

    def total(self, keys: list[int]) -> float:
        """Of the chunks still in flight only (a report that arrives after its chunk landed is not counted)."""
        return float(sum(self.done.get(k, 0.0) for k in keys))


def _ray_task(spec: CampaignSpec, indices: list[int], sink: Any = None, key: int = -1) -> list[dict[str, Any]]:
    """A Ray task: :func:`run_tasks`, telling ``sink`` (a :class:`_FlyingSink` actor) what the chunk has flown."""

    def on_progress(done: float) -> None:
        sink.set.remote(key, done)

    return run_tasks(spec, indices, on_progress if sink is not None else None)


class RayEngine:
    """Ray tasks (1 CPU each) on a running cluster (``address`` = ``auto`` or ``HOST:PORT``) or, with no
    address, on a Ray instance started for this driver.  ``workers`` caps the runs in flight (default: twice
    the cluster's CPUs)."""

    name = "ray"

    def __init__(self, workers: int | None = None, address: str | None = None, batch: int = DEFAULT_BATCH) -> None:
        self.workers = workers
        self.address = address
        self.batch = int(batch)
        self._cpus = 0

    def prepare(self) -> None:
        """Reach the cluster before the campaign starts (and writes its folder): a wrong ``--address`` is one line
        and exit 2, not a driver waiting on Ray's connection retries."""
        self._connect()

    def _init_address(self) -> str:
        """What ``ray.init`` is given: ``--address`` as given; without one, ``RAY_ADDRESS`` when it is set (Ray's
        own convention, e.g. inside a Ray job), else ``local``: a Ray instance started for this driver.  (Left to
        Ray, no address also means the last cluster ``ray start`` ran on this machine, whose address file outlives
        it: the driver then retried a stopped cluster for minutes without a word.)"""
        if self.address:
            return str(self.address)
        return os.environ.get("RAY_ADDRESS", "") or "local"

    def _probe_address(self) -> None:
        """A ``HOST:PORT`` (or ``ray://HOST:PORT``) that no process listens on is said at once: Ray itself retries
        for minutes.  ``auto`` is probed where Ray would look (``RAY_ADDRESS``, else the address file of the last
        cluster started on this machine); with neither, Ray itself says at once that no cluster runs here."""
        import socket

        from bb2_tools.campaign.errors import SpecError

        addr = self._init_address()
        hostport = addr[len("ray://"):] if addr.startswith("ray://") else addr
        given = self._given()
        found = ""
        if hostport == "auto":  # where Ray would look: RAY_ADDRESS, else the last cluster started on this machine
            env = os.environ.get("RAY_ADDRESS", "")
            hostport = env or _last_ray_cluster()
            found = f" (auto: {hostport}, {'from RAY_ADDRESS' if env else 'the last Ray cluster started here'})"
        if not hostport or hostport in ("auto", "local"):
            return
        host, sep, port = hostport.rpartition(":")
        if not sep or not port.isdigit():
            raise SpecError(f"{given}: expected auto or HOST:PORT (the address `ray start --head` prints)")
        try:
            socket.create_connection((host or "127.0.0.1", int(port)), timeout=ADDRESS_PROBE_TIMEOUT_S).close()
        except OSError as e:
            raise SpecError(f"{given}{found}: no Ray cluster answers there ({e.strerror or e}); start "
                            f"one with `ray start --head` (it prints its address), or use --address auto on one of "
                            f"its machines") from None

    def _given(self) -> str:
        """Where the address came from, as the user gave it."""
        addr = self._init_address()
        return f"--address {addr}" if self.address else f"RAY_ADDRESS={addr} (no --address)"

    def _connect(self) -> Any:
        import logging

        try:
            import ray
        except ImportError:
            from bb2_tools.campaign.errors import SpecError

            raise SpecError("--engine ray: the ray package is not installed (bash run.sh setup installs it)") from None
        os.environ.setdefault("RAY_DEDUP_LOGS", "0")
        os.environ.setdefault("RAY_USAGE_STATS_ENABLED", "0")
        if not ray.is_initialized():
            self._probe_address()
            address = self._init_address()
            kw: dict[str, Any] = {"log_to_driver": False, "logging_level": logging.WARNING}
            if address == "local":
                kw["include_dashboard"] = False
            try:
                ray.init(address=address, **kw)
            except ConnectionError as e:  # something answers there, not a Ray cluster (an OSError: not the folder)
                from bb2_tools.campaign.errors import SpecError

                raise SpecError(f"--engine ray: {self._given()}: {' '.join(str(e).split())}; start a cluster with "
                                "`ray start --head` (it prints its address)") from None
        self._cpus = int(ray.cluster_resources().get("CPU", 1))
        return ray

    def describe(self) -> str:
        addr = self._init_address()
        where = "a local Ray instance" if addr == "local" else addr + ("" if self.address else " (RAY_ADDRESS)")
        return f"ray at {where}" + (f", {self._cpus} CPUs" if self._cpus else "")

    def run(self, spec: CampaignSpec, indices: Iterable[int], on_row: OnRow, on_tick: OnTick | None = None) -> None:
        ray = self._connect()
        task = ray.remote(num_cpus=1, max_retries=_MAX_ATTEMPTS - 1)(_ray_task)
        spec_ref = ray.put(spec)
        window = int(self.workers) if self.workers else 2 * max(1, self._cpus)
        pending = collections.deque(indices)
        inflight: dict[Any, list[int]] = {}
        size = chunk_size(spec, len(pending), max(1, self._cpus), self.batch)
        sink = ray.remote(num_cpus=0)(_FlyingSink).remote() if on_tick and size > 1 else None
        keys: dict[Any, int] = {}   # each chunk's key in the sink
        serial = 0
        try:
            while pending or inflight:
                while pending and len(inflight) < window:
                    chunk = _take(pending, size)
                    ref = task.remote(spec_ref, chunk, sink, serial)
                    inflight[ref], keys[ref] = chunk, serial
                    serial += 1
                done, _ = ray.wait(list(inflight), num_returns=1, timeout=0.5)
                for ref in done:
                    chunk = inflight.pop(ref)
                    try:
                        rows = ray.get(ref)
                    except Exception as e:  # noqa: BLE001 -- worker died through the retries, object lost, ...
                        rows = [_lost_row(spec, i, " ".join(f"ray: {type(e).__name__}: {e}".split())[:2000])
                                for i in chunk]
                    for row in rows:
                        on_row(row)
                    if sink is not None:
                        sink.drop.remote(keys[ref])
                    del keys[ref]
                if on_tick:
                    on_tick(self._flying(ray, sink, list(keys.values())))
        finally:
            if sink is not None:
                try:
                    ray.kill(sink)
                except Exception:  # noqa: BLE001 -- the cluster gone: the actor went with it
                    pass

    @staticmethod
    def _flying(ray: Any, sink: Any, keys: list[int]) -> float:
        """What the chunks in flight have flown (0 with no sink, or if it does not answer within a second)."""
        if sink is None or not keys:
            return 0.0
        try:
            return float(ray.get(sink.total.remote(keys), timeout=1.0))
        except Exception:  # noqa: BLE001 -- a progress figure is not worth failing a campaign
            return 0.0

    def shutdown(self) -> None:
        try:
            import ray

            if ray.is_initialized():
                ray.shutdown()
        except ImportError:
            pass


def make_engine(name: str, workers: int | None = None, address: str | None = None,
                batch: int = DEFAULT_BATCH) -> Any:
    if name == "local":
        return LocalEngine(workers, batch)
    if name == "ray":
        return RayEngine(workers, address, batch)
    raise ValueError(f"unknown engine {name!r}; choose from {', '.join(ENGINES)}")
