"""Issue 14, point 2: missions flown together (bb2_mission.batch: one runner per mission, their ROMs one exact
batch) give each mission what it gives alone, bit for bit: every trajectory column and every summary figure."""
from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest
import yaml

from bb2_mission.batch import batch_refusal, run_missions_batch
from bb2_mission.runner import run_mission
from bb2_mission.schema import load_mission

MISSIONS = Path(__file__).resolve().parents[2] / "missions"


def _mission(tmp: Path, name: str, base: str, **changes) -> object:
    f = tmp / f"{name}.yaml"
    f.write_text(yaml.safe_dump({"extends": str(MISSIONS / f"{base}.yaml"), **changes}))
    return load_mission(f)


def _plain(v):
    """A summary value comparable with == (arrays as lists, NaN as a string)."""
    if isinstance(v, dict):
        return {k: _plain(x) for k, x in v.items()}
    if isinstance(v, np.ndarray):
        return _plain(v.tolist())
    if isinstance(v, (list, tuple)):
        return [_plain(x) for x in v]
    return "nan" if isinstance(v, float) and math.isnan(v) else v


def _summary(s) -> dict:
    d = dataclasses.asdict(s)
    d.pop("wall_time_s")
    return _plain(d)


def test_missions_flown_together_give_each_what_it_gives_alone(tmp_path):
    # different sea states, stacks (rate and LOS), paths, gains, durations; one grounded before its first step
    # (the canyon's lowest hull point starts 44.4 m above the floor) and one that ends on its path's end
    ms = [
        _mission(tmp_path, "calm", "canyon", duration_s=6.0),
        _mission(tmp_path, "ss5", "canyon", duration_s=5.0, sea_state=5),
        _mission(tmp_path, "ss3_no_l1", "canyon", duration_s=6.0, sea_state=3, adaptation=False),
        _mission(tmp_path, "gain", "canyon", duration_s=4.0, stack={"base": "rate_2022", "guidance": {"d_m": 300.0}}),
        _mission(tmp_path, "los", "canyon_los", duration_s=5.0),
        _mission(tmp_path, "circle", "circle", duration_s=3.0),
        _mission(tmp_path, "grounded", "canyon", duration_s=5.0, limits={"min_hull_clearance_m": 60.0}),
        _mission(tmp_path, "straight", "straight", duration_s=7.0),
    ]
    assert all(batch_refusal(m) is None for m in ms)
    told: list[float] = []
    together = run_missions_batch(ms, on_progress=told.append)
    # what a campaign's progress bar counts while the batch flies: missions' worth of ticks, from 0 to all of them
    assert told[0] == 0.0 and told[-1] == len(ms) and told == sorted(told), told
    assert any(0 < v < len(ms) for v in told), told
    ends = []
    for m, b in zip(ms, together):
        a = run_mission(m)
        assert list(b.traj) == list(a.traj)
        for c in a.traj:
            assert np.array_equal(a.traj[c], b.traj[c], equal_nan=True), (m.name, c)
        assert _summary(b.summary) == _summary(a.summary), m.name
        ends.append(str(a.summary.end_reason))
    assert ends.count("duration") == len(ms) - 1 and ends[6] == "grounded", ends
    assert len(together[6].traj["t_s"]) == 1 and len(together[0].traj["t_s"]) == 120


def test_missions_that_cannot_fly_together_are_refused_with_the_reason(tmp_path):
    irregular = _mission(tmp_path, "irr", "canyon", duration_s=2.0,
                         sea={"spectrum": "jonswap", "hs": 2.0, "tp": 8.0, "components": 8, "seed": 1})
    current = _mission(tmp_path, "cur", "canyon", duration_s=2.0, current={"speed_mps": 0.3, "heading_deg": 90})
    calm = _mission(tmp_path, "calm", "canyon", duration_s=2.0)
    assert "sea" in batch_refusal(irregular) and "current" in batch_refusal(current)
    assert batch_refusal(calm) is None
    with pytest.raises(ValueError, match="current"):
        run_missions_batch([calm, current])
    with pytest.raises(ValueError, match="physics profile"):
        run_missions_batch([calm, _mission(tmp_path, "p", "canyon", duration_s=2.0, profile="corrected")])
