"""The sea's physical constants, SI: gravity and the water's density.

One source: ``data/rom_model.json`` (``g_m_s2``, ``rho_kg_m3``: the authors' values, with that file's provenance),
which :func:`bb2_sim.parameters.load_parameters` reads too.  This module reads only those two numbers (plain json,
no numpy), so the sea, sensor and navigation models take them as defaults without loading the whole ROM.
"""
from __future__ import annotations

import json
from pathlib import Path

_MODEL = json.loads((Path(__file__).resolve().parent / "data" / "rom_model.json").read_text(encoding="utf-8"))

G_M_S2: float = float(_MODEL["g_m_s2"])
"""Gravity, m/s^2 (the ROM's: the same value the hydrostatics, the wave dispersion and the sensors use)."""

RHO_KG_M3: float = float(_MODEL["rho_kg_m3"])
"""Sea water density, kg/m^3 (the ROM's)."""

del _MODEL
