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


def _as_alone(ms: list, together: list) -> list:
    """Assert that each mission's batch result is bit for bit its run alone (every column, every summary figure);
    returns the results alone."""
    alone = []
    for m, b in zip(ms, together):
        a = run_mission(m)
        assert list(b.traj) == list(a.traj)
        for c in a.traj:
            assert np.array_equal(a.traj[c], b.traj[c], equal_nan=True), (m.name, c)
        assert _summary(b.summary) == _summary(a.summary), m.name
        alone.append(a)
    return alone


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
    ends = [str(a.summary.end_reason) for a in _as_alone(ms, together)]
    assert ends.count("duration") == len(ms) - 1 and ends[6] == "grounded", ends
    assert len(together[6].traj["t_s"]) == 1 and len(together[0].traj["t_s"]) == 120


def test_missions_that_cannot_fly_together_are_refused_with_the_reason(tmp_path):
    sensors = _mission(tmp_path, "nav", "canyon", duration_s=2.0, sensors={"suite": "tactical", "seed": 1},
                       navigation="sensors")
    calm = _mission(tmp_path, "calm", "canyon", duration_s=2.0)
    assert "navigation" in batch_refusal(sensors)
    assert batch_refusal(calm) is None
    with pytest.raises(ValueError, match="navigation"):
        run_missions_batch([calm, sensors])
    with pytest.raises(ValueError, match="physics profile"):
        run_missions_batch([calm, _mission(tmp_path, "p", "canyon", duration_s=2.0, profile="corrected")])


def test_missions_in_spectrum_seas_and_currents_fly_together_as_alone(tmp_path):
    """Each mission keeps its own sea and current in the batch (the batch ROM takes them per boat): short-crested
    JONSWAP and Pierson-Moskowitz seas of different headings and seeds, a current, a sea with a current, the
    authors' regular sea and calm water in one batch, at periscope depth where the waves act: every trajectory
    column and summary figure bit for bit what each mission gives alone."""
    base = "canyon_periscope_ss5"
    ms = [
        _mission(tmp_path, "ss5", base, duration_s=6.0),
        _mission(tmp_path, "ss4_head", base, duration_s=5.0,
                 sea={"spectrum": "jonswap", "sea_state": 4, "heading_deg": 0.0, "spreading_s": 10.0,
                      "components": 16, "seed": 3}, current=None),
        _mission(tmp_path, "pm", base, duration_s=6.0, sea={"spectrum": "pm", "hs": 2.0, "components": 8, "seed": 9,
                                                            "heading_deg": 200.0}),
        _mission(tmp_path, "current", base, duration_s=4.0, sea=None),
        _mission(tmp_path, "table", base, duration_s=5.0, sea={"sea_state": 5}, current=None),
        _mission(tmp_path, "calm", base, duration_s=3.0, sea=None, current=None),
    ]
    assert ms[0].environment.current.build() is not None and not ms[0].environment.sea.authors_table
    assert ms[3].environment.sea.build() is None or ms[3].environment.sea.build().calm
    assert all(batch_refusal(m) is None for m in ms)
    together = run_missions_batch(ms)
    _as_alone(ms, together)
    # the seas act: the missions' depths part within seconds
    z = [r.traj["z_m"][-1] - r.traj["z_m"][0] for r in together]
    assert len({round(v, 6) for v in z}) == len(z), z
