"""Maneuver campaigns fly their runs together in the batch ROM (issue 14, point 2: "used by the local engine to run
many cases per worker"): ``bb2-campaign`` gives the same results table whether each worker flies its runs in
batches (the default) or one by one (``--batch 1``, the single-run path that ``--only`` and the library
``run_maneuver`` take), to the last digit; a run that diverges in a batch is flown again alone for its own message.
"""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

pytest.importorskip("pyarrow")
import pyarrow.parquet as pq  # noqa: E402

from bb2_tools.campaign.spec import parse_spec  # noqa: E402

pytestmark = pytest.mark.slow(seconds=120)

REPO = Path(__file__).resolve().parents[2]
BIN = Path(sys.executable).parent

# 32 turning circles of 15 s (two workers: two batches of 16); speed 0 diverges at the first step (quirk Q13)
SPEC = {
    "maneuver": {"name": "turning-circle", "options": {"duration": 15}},
    "seed": 11,
    "samples": 32,
    "vary": {"rudder_deg": {"uniform": [15.0, 35.0]}, "sea_state": {"choice": [0, 3, 5]},
             "speed_mps": {"choice": [0.0, 4.0, 5.0, 5.5, 6.0]}},
    "collect": ["peak_roll_rad", "z_change_m", "initial_speed_m_s", "time_90_s"],
}


def _campaign(*args: str) -> subprocess.CompletedProcess:
    env = dict(os.environ)
    env["PYTHONPATH"] = str(REPO) + os.pathsep + env.get("PYTHONPATH", "")
    env.setdefault("MPLBACKEND", "Agg")
    return subprocess.run([str(BIN / "bb2-campaign"), *args, "--quiet", "--no-report"], cwd=REPO, env=env,
                          capture_output=True, text=True, timeout=600)


def test_batched_and_single_runs_give_the_same_table_to_the_last_digit(tmp_path):
    spec = tmp_path / "circles.yaml"
    spec.write_text(yaml.safe_dump(SPEC, sort_keys=False))
    tables = {}
    for label, extra in (("batched", []), ("alone", ["--batch", "1"])):
        r = _campaign(str(spec), "--out", str(tmp_path / label), "--workers", "2", *extra)
        assert r.returncode == 0, r.stderr[-3000:]
        rows = pq.read_table(tmp_path / label / "results.parquet").to_pylist()
        tables[label] = [{k: v for k, v in row.items() if k != "wall_time_s"} for row in rows]
    assert len(tables["alone"]) == 32
    assert tables["batched"] == tables["alone"]
    status = [r["status"] for r in tables["alone"]]
    assert status.count("ok") >= 16 and "diverged" in status, status
    assert {r["sea_state"] for r in tables["alone"]} == {0, 3, 5}


def test_a_chunk_of_maneuvers_flies_as_one_batch_and_only_the_diverged_runs_alone(monkeypatch):
    """``run_tasks``: the runs of a chunk fly together; ``run_task`` (the single run) is called only for those that
    diverged in the batch, whose rows then carry the single run's own message."""
    from bb2_tools.campaign import worker

    spec = parse_spec(SPEC)
    alone: list[int] = []
    single = worker.run_task

    def spy(s, i):
        alone.append(int(i))
        return single(s, i)

    monkeypatch.setattr(worker, "run_task", spy)
    rows = worker.run_tasks(spec, list(range(worker.BATCH_MIN)))
    assert [r["index"] for r in rows] == list(range(worker.BATCH_MIN))
    diverged = [r["index"] for r in rows if r["status"] == "diverged"]
    assert diverged and alone == diverged, (alone, diverged)
    assert all("non-finite model evaluation" in r["message"] for r in rows if r["status"] == "diverged")
    # fewer runs than a batch pays for: every one alone
    alone.clear()
    worker.run_tasks(spec, [0, 1, 2])
    assert alone == [0, 1, 2]
