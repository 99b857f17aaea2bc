"""The sea's data file (``bb2_sim/data/sea_spectra.yaml``): spectra constants, spreading, discretisation defaults."""
from __future__ import annotations

from functools import lru_cache
from pathlib import Path

from bb2_sim.yaml_files import load as load_yaml

DATA_DIR = Path(__file__).resolve().parents[1] / "data"


@lru_cache(maxsize=None)
def sea_data(name: str = "sea_spectra.yaml") -> dict:
    return load_yaml((DATA_DIR / name).read_text())
