"""The project's YAML files read numbers as YAML 1.2 (and ROS 2's parameter files) do: ``1e-3`` is a float.

PyYAML alone (YAML 1.1) reads ``1e9``, ``1e-3`` and ``1.0e9`` as strings, so a mission or campaign written with
them failed with "must be a number, got '1e-3'" (found by hand on 2026-12-07 with ``current: {speed_mps: 1e9}``).
"""
from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
import yaml

from bb2_mission.schema import load_mission
from bb2_sim.yaml_files import load as load_yaml
from bb2_tools.campaign.spec import load_spec

REPO = Path(__file__).resolve().parents[2]


@pytest.mark.parametrize("text, value", [
    ("1e9", 1e9), ("1e-3", 1e-3), ("-2E+3", -2000.0), ("+1e3", 1000.0), ("1.0e9", 1e9), ("1.5e3", 1500.0),
    (".5e3", 500.0), ("-.5E-1", -0.05), ("1_000e-3", 1.0),
])
def test_exponent_forms_are_floats(text, value):
    assert isinstance(yaml.safe_load(f"v: {text}")["v"], str)  # what PyYAML alone gives: the reason for the loader
    got = load_yaml(f"v: {text}")["v"]
    assert type(got) is float and got == value


@pytest.mark.parametrize("text", [
    "1", "-7", "0x1F", "0o17", "1.5", "-0.25", "1.", ".5", "1.0e+9", ".inf", "-.inf", "yes", "off", "true", "null",
    "1e", "e9", "1.2.3", "1e9x", "2026-12-07", "'1e9'", "\"1e-3\"", "[1, 2.5, a]", "{a: 1}", "12:30", "abc",
])
def test_everything_else_is_the_safe_loaders(text):
    assert load_yaml(f"v: {text}") == yaml.safe_load(f"v: {text}")


def test_nan_is_still_nan():
    assert np.isnan(load_yaml("v: .nan")["v"])


def test_malformed_yaml_raises_a_yaml_error_in_one_line():
    with pytest.raises(yaml.YAMLError, match=r"^line 1, column 9: expected ',' or '\]', but got '<stream end>'"):
        load_yaml("a: [1, 2")
    with pytest.raises(yaml.YAMLError, match="^line 1, column 1: could not determine a constructor for the tag "
                                             "'tag:yaml.org,2002:python/object/apply:os.system'$"):
        load_yaml("!!python/object/apply:os.system ['true']")   # safe: no Python objects


@pytest.mark.parametrize("text, said", [
    ("duration_s: 2\nname: x\nduration_s: 5\n", "line 3, column 1: found the key 'duration_s' twice (first on line 1)"),
    ("boats:\n  b1: straight\n  b1: canyon\n", "line 3, column 3: found the key 'b1' twice (first on line 2)"),
    ("sea: {hs: 1, hs: 2}\n", "line 1, column 14: found the key 'hs' twice (first on line 1)"),
])
def test_a_key_written_twice_is_an_error(text, said):
    """PyYAML keeps the last of a key written twice without a word: a mission's second duration_s, or a fleet's
    boat written twice, flew silently."""
    with pytest.raises(yaml.YAMLError) as e:
        load_yaml(text)
    assert str(e.value) == said


def test_a_merge_may_be_overridden():
    assert load_yaml("base: &b {x: 1, y: 2}\nd:\n  <<: *b\n  x: 5\n")["d"] == {"x": 5, "y": 2}


def test_a_mission_written_with_exponents_is_the_one_written_with_decimals(tmp_path):
    base = REPO / "missions" / "straight.yaml"
    (tmp_path / "decimals.yaml").write_text(
        f"extends: {base}\nduration_s: 30.0\nsea: {{spectrum: jonswap, hs: 2.5, tp: 9.0, seed: 3}}\n"
        "current: {speed_mps: 0.5, heading_deg: 90.0}\ninitial: {offset_m: [0.0, 20.0, -1.5]}\n")
    (tmp_path / "exponents.yaml").write_text(
        f"extends: {base}\nduration_s: 3e1\nsea: {{spectrum: jonswap, hs: 2.5e0, tp: 9E0, seed: 3}}\n"
        "current: {speed_mps: 5e-1, heading_deg: +9e1}\ninitial: {offset_m: [0e0, 2e1, -15e-1]}\n")
    a, b = load_mission(tmp_path / "decimals.yaml"), load_mission(tmp_path / "exponents.yaml")
    assert b.duration_s == 30.0 and b.initial == a.initial
    for f in dataclasses.fields(a):
        if f.name == "path":
            assert np.array_equal(a.path.control_points, b.path.control_points)
        elif f.name != "source_file":
            assert getattr(a, f.name) == getattr(b, f.name), f.name
    assert a.environment.current is not None  # the blocks were read, not defaulted


def test_a_campaign_spec_takes_exponents_in_its_distributions_and_grids(tmp_path):
    spec = tmp_path / "spec.yaml"
    spec.write_text(f"mission: {REPO / 'missions' / 'straight.yaml'}\nseed: 7\nsamples: 2\n"
                    "vary:\n  duration_s: [1e1, 2e1]\n  current.speed_mps: {uniform: [1e-1, 5e-1]}\n")
    s = load_spec(spec)
    by_key = {v.key: v for v in s.vary}
    assert by_key["duration_s"].params == (10.0, 20.0)
    assert by_key["current.speed_mps"].kind == "uniform" and by_key["current.speed_mps"].params == (0.1, 0.5)
