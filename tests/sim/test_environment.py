"""bb2_sim.environment: the sea:/current: blocks validated, built and described (JSON) so that a run's sea can
be rebuilt exactly from its record."""
import json
import math

import numpy as np
import pytest

from bb2_sim.environment import (Environment, SeaSpec, current_from_mapping, environment_from_description,
                                 sea_from_mapping)
from bb2_sim.sea import AuthorsTableSea, ComponentSea, SeaInputError, write_components_csv


def test_default_is_calm_and_the_authors_table_goes_in_as_sea_state():
    assert Environment().model_kwargs() == {"sea_state": 0, "current": None}
    e = Environment.from_mappings({"sea_state": 5})
    assert e.sea.authors_table and e.model_kwargs() == {"sea_state": 5.0, "current": None}
    assert isinstance(e.sea.build(), AuthorsTableSea)


def test_spectrum_with_a_sea_state_takes_hs_tp_from_the_table():
    s = sea_from_mapping({"spectrum": "jonswap", "sea_state": 5})
    assert s.effective_hs_tp == (3.25, 9.7)
    c = s.wave_components()
    assert len(c) == 64 and c.hs == pytest.approx(3.25, rel=0.02)


def test_short_crested_sea_is_seeded_and_spread_about_the_heading():
    a = sea_from_mapping({"spectrum": "ittc", "hs": 2, "tp": 8, "heading_deg": 90, "spreading_s": 20,
                          "components": 200, "seed": 4}).wave_components()
    b = sea_from_mapping({"spectrum": "ittc", "hs": 2, "tp": 8, "heading_deg": 90, "spreading_s": 20,
                          "components": 200, "seed": 4}).wave_components()
    assert np.array_equal(a.phase, b.phase) and np.array_equal(a.direction, b.direction)
    mean = math.atan2(np.sin(a.direction).mean(), np.cos(a.direction).mean())
    assert mean == pytest.approx(math.pi / 2, abs=0.05)
    assert np.std(a.direction) > 0.1


def test_regular_wave_defaults_to_hs_over_2_and_tp():
    c = sea_from_mapping({"spectrum": "regular", "hs": 3, "tp": 10, "heading_deg": 45}).wave_components()
    assert c.amplitude[0] == 1.5 and c.omega[0] == pytest.approx(2 * math.pi / 10)
    assert c.direction[0] == pytest.approx(math.pi / 4)


def test_zero_hs_is_calm():
    s = sea_from_mapping({"spectrum": "jonswap", "hs": 0, "tp": 9})
    assert s.build().calm and s.wave_components() is None


def test_component_file_relative_to_the_base_dir(tmp_path):
    c = sea_from_mapping({"spectrum": "pm", "hs": 2, "components": 5}).wave_components()
    write_components_csv(tmp_path / "c.csv", c)
    s = sea_from_mapping({"components": "c.csv"}, base_dir=tmp_path)
    assert s.components == str(tmp_path / "c.csv")
    assert np.allclose(s.wave_components().amplitude, c.amplitude, rtol=0, atol=1e-15)


@pytest.mark.parametrize("block,needle", [
    ({"spectrum": "jonswap", "hs": -1, "tp": 9}, "hs must be >= 0"),
    ({"spectrum": "jonswap", "hs": 1, "tp": 0}, "tp must be > 0"),
    ({"spectrum": "jonswap", "hs": 1, "tp": 9, "gamma": 0.99}, "gamma must be >= 1"),
    ({"spectrum": "jonswap", "hs": 1, "tp": 9, "components": 0}, "components"),
    ({"spectrum": "jonswap", "hs": 1, "tp": 9, "components": 2.5}, "integer"),
    ({"spectrum": "jonswap", "hs": float("nan"), "tp": 9}, "finite"),
    ({"spectrum": "jonswap", "hs": 1, "tp": 9, "seed": -1}, "seed"),
    ({"spectrum": "jonswap", "hs": 1, "tp": 9, "spreading_s": 0}, "spreading_s must be > 0"),
    ({"spectrum": "jonswap", "hs": 1, "tp": 9, "typo": 1}, "unknown key"),
    ({"spectrum": "swell", "hs": 1, "tp": 9}, "spectrum must be one of"),
    ({"spectrum": "ittc", "hs": 1}, "needs tp"),
    ({"spectrum": "jonswap", "tp": 9}, "needs hs"),
    ({"hs": 3, "tp": 9}, "need a spectrum"),
    ({"components": 32}, "components need a spectrum"),                 # it was a calm sea, without a word
    ({"components": 32, "sea_state": 5}, "components need a spectrum"),  # it was the regular table's one wave
    ({"components": "no_such_file.csv"}, "not found"),
    ({"spectrum": "jonswap", "hs": 1, "tp": 9, "sea_state": 5}, "do not give hs and tp"),
    ({"spectrum": "jonswap", "sea_state": 11}, "not in the table"),
    ({"sea_state": 9}, "sea state"),
    ("jonswap", "must be a mapping"),
])
def test_bad_sea_blocks_one_message(block, needle):
    with pytest.raises(ValueError, match=needle):
        sea_from_mapping(block)


@pytest.mark.parametrize("block,needle", [
    ({"speed_mps": -0.1}, "speed_mps must be >= 0"),
    ({"speed_mps": 1, "heading_deg": float("inf")}, "finite"),
    ({"speed_mps": 1, "direction_deg": 10}, "unknown key"),
    ({"speed_mps": 1, "profile": {"depths_m": [0, 50], "factors": [1]}}, "equal-length"),
    ({"speed_mps": 1, "profile": {"depths_m": [50, 0], "factors": [1, 1]}}, "increasing"),
    ({"speed_mps": 1, "profile": {"water_depth_m": 0}}, "water_depth_m must be > 0"),
    ({"speed_mps": 1, "profile": {"shape": "log"}}, "profile must be"),
    ({"heading_deg": 90}, r"current: heading_deg without speed_mps: give the current's speed \(m/s, 0 for none\)"),
    ({"heading_deg": 90, "profile": {"water_depth_m": 200}}, "heading_deg, profile without speed_mps"),
])
def test_bad_current_blocks_one_message(block, needle):
    with pytest.raises(SeaInputError, match=needle):
        current_from_mapping(block)


def test_current_profiles():
    c = current_from_mapping({"speed_mps": 1.0, "heading_deg": 90,
                              "profile": {"depths_m": [0, 100], "factors": [1, 0]}}).build()
    assert c.velocity_earth(np.array(-50.0))[1] == pytest.approx(0.5)
    p = current_from_mapping({"speed_mps": 1.0, "profile": {"water_depth_m": 200}}).build()
    assert p.factor(np.array(-100.0)) == pytest.approx(0.5 ** (1 / 7))
    assert current_from_mapping({"speed_mps": 0}).build() is None


@pytest.mark.parametrize("sea", [
    {"spectrum": "jonswap", "hs": 3.25, "tp": 9.7, "spreading_s": 10, "components": 16, "seed": 7},
    {"spectrum": "regular", "amplitude_m": 1.2, "period_s": 7, "heading_deg": 20},
    {"sea_state": 5},
    {},
])
def test_description_rebuilds_the_same_sea_exactly(sea):
    e = Environment.from_mappings(sea, {"speed_mps": 0.4, "heading_deg": 45,
                                        "profile": {"water_depth_m": 150, "alpha": 0.2}})
    text = e.description_json()
    d = json.loads(text)
    assert d["format"] == "bb2_sea/1" and d["sea"]["seed"] == e.sea.seed
    r = environment_from_description(text)
    assert r.current == e.current
    kw_a, kw_b = e.model_kwargs(), r.model_kwargs()
    if "sea_state" in kw_a:
        assert kw_b["sea_state"] == kw_a["sea_state"]
        return
    a, b = kw_a["sea"], kw_b["sea"]
    if a.calm:
        assert b.calm
        return
    assert isinstance(b, ComponentSea)
    for f in ("amplitude", "omega", "direction", "phase"):
        assert np.array_equal(getattr(a.components, f), getattr(b.components, f))
    pts = np.array([[10.0, -5.0, -12.0], [0.0, 0.0, 0.5]])
    assert np.array_equal(a.pressure_head(pts, 3.3), b.pressure_head(pts, 3.3))


def test_spec_is_hashable_data():
    assert SeaSpec() == sea_from_mapping({})


@pytest.mark.parametrize("block, said", [
    ({"spectrum": "jonswap", "hs": 30, "tp": 9}, "has Hs / Lp = 30 / 126 m = 0.237, steeper than any deep-water"),
    ({"spectrum": "ittc", "hs": 3, "tp": 1.0}, "has Hs / Lp = 3 / 1.56 m = 1.921"),
    ({"spectrum": "regular", "amplitude_m": 3, "period_s": 3}, "has H / L = 6 / 14.1 m = 0.427"),
    ({"spectrum": "regular", "hs": 6, "tp": 3}, "has H / L = 6 / 14.1 m = 0.427"),
    ({"spectrum": "jonswap", "hs": 3.25, "tp": 9.7}, None),           # sea state 5 of the table
    ({"spectrum": "jonswap", "hs": 9.3, "tp": 6.5}, None),            # Hs / Lp 0.141: at the limit, not past it
    ({"spectrum": "pm", "hs": 15}, None),                              # PM: Tp follows from Hs
    ({"sea_state": 7}, None),                                           # the authors' table
    *[({"spectrum": sp, "sea_state": ss}, None) for ss in (5, 6, 7) for sp in ("jonswap", "ittc", "regular")],
])
def test_a_sea_steeper_than_any_deep_water_wave_is_warned(block, said):
    """Michell's limit (H / L = 0.142, data/sea_spectra.yaml): beyond it a sea does not exist (a typo, most
    likely); the warning says the numbers, and every sea of the table stays below it."""
    got = sea_from_mapping(block).steepness_warning()
    if said is None:
        assert got == ""
    else:
        assert said in got and got.endswith("the linear model flies it all the same"), got
