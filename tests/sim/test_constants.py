"""Gravity and the water's density have one source, ``bb2_sim/data/rom_model.json``: ``bb2_sim.constants`` reads
them, and every model that takes them as a default (the sea, the sensors, the navigation filter) defaults to it,
with no number of its own written in the code."""
from __future__ import annotations

import inspect
import re
from pathlib import Path

import pytest

from bb2_sim.constants import G_M_S2, RHO_KG_M3
from bb2_sim.parameters import load_parameters

REPO = Path(__file__).resolve().parents[2]


def test_the_constants_are_the_rom_model_files():
    p = load_parameters()
    assert (G_M_S2, RHO_KG_M3) == (p.g, p.rho)


def _defaults():
    from bb2_control.navigation import NavigationFilter
    from bb2_sim.environment import Environment, SeaSpec
    from bb2_sim.sea import components, sea, spectra
    from bb2_sim.sensors import suite, truth

    yield "SeaSpec.wave_components", inspect.signature(SeaSpec.wave_components).parameters["g"].default
    yield "SeaSpec.steepness_warning", inspect.signature(SeaSpec.steepness_warning).parameters["g"].default
    yield "Environment.description", inspect.signature(Environment.description).parameters["g"].default
    yield "truth_from_step", inspect.signature(truth.truth_from_step).parameters["g"].default
    yield "read_components_csv", inspect.signature(components.read_components_csv).parameters["g"].default
    yield "AuthorsTableSea", inspect.signature(sea.AuthorsTableSea.__init__).parameters["g"].default
    nav = inspect.signature(NavigationFilter.__init__).parameters
    yield "NavigationFilter g", nav["g"].default
    yield "NavigationFilter rho", nav["rho"].default
    for cls in (suite, truth, spectra, components):
        for name, obj in vars(cls).items():
            fields = getattr(obj, "__dataclass_fields__", {})
            if getattr(obj, "__module__", None) == cls.__name__ and ("g" in fields or "rho" in fields):
                for f in ("g", "rho"):
                    if f in fields:
                        yield f"{name}.{f}", fields[f].default


@pytest.mark.parametrize("what,default", list(_defaults()))
def test_every_default_is_the_rom_models(what, default):
    assert default in (G_M_S2, RHO_KG_M3), what
    assert default == (RHO_KG_M3 if what.endswith("rho") else G_M_S2), what


def test_no_library_writes_gravity_or_the_density_as_a_number():
    """9.81 or 1025 in the libraries' code (not their data files, nor G0 = 9.80665, the unit 'g' of the sensors'
    specifications)."""
    found = []
    for pkg in ("bb2_sim", "bb2_planner", "bb2_control", "bb2_mission", "bb2_msgs_py", "bb2_ros", "bb2_tools"):
        for f in sorted((REPO / pkg).rglob("*.py")):
            for i, line in enumerate(f.read_text(encoding="utf-8").splitlines(), 1):
                if re.search(r"(?<![\d.])(9\.81|1025(\.0*)?)(?![\d])", line):
                    found.append(f"{f.relative_to(REPO)}:{i}: {line.strip()}")
    assert not found, "\n".join(found)
