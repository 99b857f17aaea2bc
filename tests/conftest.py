"""Shared fixtures: where ../shared is, and a skip when it is absent."""
from __future__ import annotations

import os
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
SHARED = Path(os.environ.get("BB2_SHARED", REPO.parent / "shared")).resolve()


def shared_path(*parts: str) -> Path:
    """Path under ../shared, or skip the test with a clear reason if it is not there."""
    p = SHARED.joinpath(*parts)
    if not p.exists():
        pytest.skip(f"reference material not found: {p} (../shared is not beside this clone)")
    return p


@pytest.fixture
def shared():
    return shared_path


@pytest.fixture(scope="session")
def authors_surfaces():
    """The authors' hull surfaces from ../shared/bb2_rom/surface (skips without ../shared)."""
    from bb2_sim.geometry import load_surface_dir

    return load_surface_dir(shared_path("bb2_rom", "surface"))


def pytest_collection_modifyitems(config, items):
    """Long modules first (marked ``slow``; the longest first by its ``seconds``, their time measured here), then
    those with ROS tests, then the rest, each group in collection order: with several workers (``run.sh test``:
    ``-n 2 --dist loadfile --no-loadscope-reorder``) the files are handed out in this order, so the longest start
    first and the short library tests fill the end."""
    rank: dict = {}
    for item in items:
        slow = item.get_closest_marker("slow")
        r = (0, -slow.kwargs.get("seconds", 0)) if slow else (1, 0) if item.get_closest_marker("ros") else (2, 0)
        rank[item.path] = min(rank.get(item.path, (2, 0)), r)
    items.sort(key=lambda item: rank[item.path])   # stable: collection order within a group


def pytest_sessionfinish(session, exitstatus):
    """The ros2 CLI daemons of the domains this process claimed (tests/rosenv.py) end with it.  Once the whole
    session is over (not in an xdist worker: the others' nodes may still run), the Fast DDS shared-memory files of
    the nodes the tests killed on purpose are removed (``fastdds shm clean``: only those whose owner is gone)."""
    import sys

    rosenv = sys.modules.get("rosenv")
    if rosenv is not None and rosenv.claimed_ids:
        rosenv.stop_ros2_daemons(rosenv.claimed_ids)
    if not hasattr(session.config, "workerinput"):
        from bb2_tools.dds_shm import clean_stale_files

        cleaned = clean_stale_files()
        if cleaned is not None and (cleaned.segments or cleaned.ports):
            tr = session.config.pluginmanager.get_plugin("terminalreporter")
            if tr is not None:
                tr.ensure_newline()
                tr.write_line(f"tests: {cleaned.line()}")
