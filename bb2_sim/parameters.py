"""Numerical parameters of the BB2 ROM, loaded from ``data/rom_model.json`` (SI units, native body frame).

Body frame: origin at the CG, x aft, y starboard, z up (SPEC 1.2). Everything here is read from data; the
derived quantities (dynamic-pressure factors, body positions of the added-mass sections, lift directions)
are computed once at load time.
"""
from __future__ import annotations

import json
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

DATA_DIR = Path(__file__).resolve().parent / "data"


@dataclass(frozen=True)
class RomParameters:
    rho: float                 # kg/m^3
    g: float                   # m/s^2
    L: float                   # m, reference length of every coefficient
    h: float                   # s, fixed step of the reference solver
    Xcg_stl: np.ndarray        # (3,) m: body origin in scaled STL coordinates
    Mb: float                  # kg
    trim_tolerance_kg: float   # kg: |rho V - Mb| below which the data's Mb is kept (no re-trim)
    inertia: np.ndarray        # (3,) Ixx, Iyy, Izz kg m^2
    cg_offset: np.ndarray      # (3,) m (zero: the origin is the CG)
    plane_points_body: np.ndarray   # (5, 3) m
    plane_spans_body: np.ndarray    # (5, 3) unit span vectors n_i
    plane_lift_dirs_body: np.ndarray  # (5, 3) d_i = n_i x nh
    plane_incidence_gain: np.ndarray  # (5,)
    hull_axis_body: np.ndarray      # (3,) nh, forward
    section_points_body: np.ndarray  # (15, 3) m, added-mass section centres
    Cvm: np.ndarray                  # (15, 3) kg, added masses along body x, y, z
    implicit_added_mass: np.ndarray  # (6, 6) equivalent calm-water matrix (not used by the literal scheme)
    prop_D: float
    KT_poly: np.ndarray
    KQ_poly: np.ndarray
    thrust_deduction_const: float
    sea_states: dict              # int -> (L_wave_m, A_wave_m)
    wave_phase: float
    wave_heading_param: float
    act: dict                     # actuator limits
    inputs: dict                  # input clamps of the tables
    hc: dict                      # hard-coded force coefficients
    provenance: str

    def __post_init__(self) -> None:
        # plain-float copies for the per-plane scalar arithmetic of planes.plane_flow
        object.__setattr__(self, "plane_points_list", [tuple(r) for r in self.plane_points_body.tolist()])
        object.__setattr__(self, "plane_spans_list", [tuple(r) for r in self.plane_spans_body.tolist()])
        object.__setattr__(self, "plane_lift_dirs_list", [tuple(r) for r in self.plane_lift_dirs_body.tolist()])
        object.__setattr__(self, "plane_incidence_gain_list", self.plane_incidence_gain.tolist())
        object.__setattr__(self, "hull_axis_list", tuple(self.hull_axis_body.tolist()))

    @property
    def q2(self) -> float:
        return 0.5 * self.rho * self.L ** 2

    @property
    def q3(self) -> float:
        return 0.5 * self.rho * self.L ** 3

    @property
    def q4(self) -> float:
        return 0.5 * self.rho * self.L ** 4


@lru_cache(maxsize=4)
def load_parameters(path: str | None = None) -> RomParameters:
    """Load ``rom_model.json`` (default: the project's own file)."""
    p = Path(path) if path else DATA_DIR / "rom_model.json"
    d = json.loads(p.read_text())
    xcg = np.array(d["Xcg_stl_m"], dtype=float)
    planes = d["planes"]
    spans = np.array(planes["span_unit_vectors_body"], dtype=float)
    nh = np.array(planes["hull_axis_unit_vector_body"], dtype=float)
    am = d["added_mass"]
    prop = d["propeller"]
    return RomParameters(
        rho=float(d["rho_kg_m3"]), g=float(d["g_m_s2"]), L=float(d["L_m"]), h=float(d["time_step_s"]),
        Xcg_stl=xcg, Mb=float(d["mass"]["Mb_kg"]),
        trim_tolerance_kg=float(d["mass"]["trim_tolerance_kg"]),
        inertia=np.array([d["mass"]["Ixx_kg_m2"], d["mass"]["Iyy_kg_m2"], d["mass"]["Izz_kg_m2"]]),
        cg_offset=np.array(d["mass"]["cg_offset_m"], dtype=float),
        plane_points_body=np.array(planes["points_body_m"], dtype=float),
        plane_spans_body=spans, plane_lift_dirs_body=np.cross(spans, nh),
        plane_incidence_gain=np.array(planes["incidence_gain"], dtype=float), hull_axis_body=nh,
        section_points_body=np.array(am["section_centres_stl_m"], dtype=float) - xcg,
        Cvm=np.array(am["Cvm_kg"], dtype=float), implicit_added_mass=np.array(am["implicit_matrix_6x6"]),
        prop_D=float(prop["diameter_m"]), KT_poly=np.array(prop["KT_poly_descending"], dtype=float),
        KQ_poly=np.array(prop["KQ_poly_descending"], dtype=float),
        thrust_deduction_const=float(prop["thrust_deduction_as_implemented"]),
        sea_states={int(k): (float(v["L_wave_m"]), float(v["A_wave_m"]))
                    for k, v in d["waves"]["sea_states"].items()},
        wave_phase=float(d["waves"]["phase_rad"]), wave_heading_param=float(d["waves"]["heading_parameter"]),
        act=d["actuators"], inputs=d["table_inputs"], hc=d["hardcoded"], provenance=d.get("_provenance", ""),
    )
