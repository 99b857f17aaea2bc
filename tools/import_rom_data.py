#!/usr/bin/env python3
"""Carry the published BB2 ROM numbers from ../shared/bb2_rom/data into the project's own data files.

Run once (or again when the reference material changes):  python tools/import_rom_data.py [SHARED_DIR]

Writes bb2_sim/data/rom_model.json (constants, mass, geometry, propeller, added mass, waves, actuators and
every hard-coded force coefficient, each with units and source) and bb2_sim/data/rom_tables.json (every
lookup table in the project's table format: axes with breakpoints, input clamp and units; values; gain).
The numbers are the published figures of Martin et al. (arXiv 2212.09821) as implemented in the authors'
IowaBB2model repository; the project never reads ../shared at run time.
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
SRC = Path(sys.argv[1]) if len(sys.argv) > 1 else REPO.parent / "shared" / "bb2_rom" / "data"
OUT = REPO / "bb2_sim" / "data"
PROVENANCE = ("Martin, Hammond, Rober, Kim, Cichella, Carrica, 'Reduced Order Model of a Generic Submarine for "
              "Maneuvering Near the Surface' (arXiv 2212.09821) and the authors' IowaBB2model repository "
              "(Model_6DOF.slx, load_data.m), as specified in the BB2 ROM implementation spec; imported by "
              "tools/import_rom_data.py")


def load(name):
    return json.loads((SRC / name).read_text())


def table(entry, *, gain=1.0, source_note=""):
    axes = []
    for a in entry["axes"]:
        clamp = a.get("input_saturation_before_lookup")
        axes.append({"name": a["name"], "units": a.get("units", ""), "breakpoints": a["breakpoints"],
                     "clamp": clamp, "fed_with": a.get("input", "")})
    return {"source": entry.get("simulink_block", source_note), "axes": axes, "values": entry["values"],
            "gain": gain, "used": bool(entry.get("used_in_force", True))}


def main() -> None:
    hull = load("hull_tables.json")
    planes = load("planes_tables.json")
    prop = load("propeller.json")
    gains = {"Muvw": 1.1, "Yuvw": 2.0, "Zuvw_b": 2.0, "Nuvw": 0.6, "Nvr": 0.5}
    tables = {"_about": "Lookup tables of the BB2 ROM. Multilinear interpolation, linear extrapolation from the "
                        "end segment, inputs clamped to 'clamp' first where given. values[i1][i2].. follow "
                        "'axes'. 'gain' is a constant post-table factor (sign factors such as sgn(beta) are "
                        "applied in the force equations, see bb2_sim/hull_forces.py; the numeric factors "
                        "of the model (x1.1 on Muvw, x2 on Yuvw and Zuvw_b, x0.6 on Nuvw, x0.5 on Nvr, x1.3 "
                        "and x1.5 on the plane M and N tables) are the gains).",
              "_provenance": PROVENANCE, "hull": {}, "unused_hull": {}, "planes": {}}
    for k, v in hull.items():
        if k.startswith("_") or k == "unused_tables":
            continue
        tables["hull"][k] = table(v, gain=gains.get(k, 1.0))
    for k, v in hull["unused_tables"].items():
        if not k.startswith("_"):
            tables["unused_hull"][k] = table(v)
    plane_gain = {"M": 1.3, "N": 1.5}
    for comp in "XYZKMN":
        items = [v for k, v in planes[comp].items() if not k.startswith("_")]
        tables["planes"][comp] = [table(v, gain=plane_gain.get(comp, 1.0)) for v in items]
    tables["thrust_deduction"] = table(prop["thrust_deduction_table"])
    tables["thrust_deduction"]["as_implemented"] = (
        "inputs swapped (quirk Q8): u enters the depth axis, z the speed axis -> t = 0.251322")
    (OUT / "rom_tables.json").write_text(json.dumps(tables, indent=1) + "\n")

    const = load("constants.json")
    mass = load("mass_properties.json")
    geo = load("geometry.json")
    am = load("added_mass.json")
    waves = load("waves.json")
    hc = load("hardcoded_terms.json")
    ctrl = load("controllers.json")
    model = {
        "_about": "Constants of the BB2 ROM (SI units unless a key says otherwise). Frames: body x aft, "
                  "y starboard, z up, origin at the CG; earth z up, z = 0 on the calm surface.",
        "_provenance": PROVENANCE,
        "rho_kg_m3": const["rho_kg_per_m3"], "g_m_s2": const["g_m_per_s2"], "L_m": const["L_m"],
        "Xcg_stl_m": const["Xcg_m"], "plane_pivot_reference_x_m": const["plane_pivot_reference_x_m"],
        "time_step_s": const["time_step_s"],
        "mass": {"Mb_kg": mass["mass_Mb_kg"], "Ixx_kg_m2": mass["Ixx_kg_m2"], "Iyy_kg_m2": mass["Iyy_kg_m2"],
                 "Izz_kg_m2": mass["Izz_kg_m2"], "cg_offset_m": mass["CG_offset_Xg_Yg_Zg_m"],
                 "note": "added mass is not in the rigid-body mass matrix; it enters as a force",
                 "trim_tolerance_kg": 1.0,
                 "trim_note": "the weight is trimmed to rho V of the surface set at start unless |rho V - Mb| <= "
                              "this tolerance (the authors' surfaces: 0.05 kg, kept as published)"},
        "planes": {
            "points_body_m": [geo["planes"][str(i)]["position_m"] for i in range(1, 6)],
            "span_unit_vectors_body": [geo["planes"][str(i)]["span_unit_vector"] for i in range(1, 6)],
            "incidence_gain": [2 ** 0.5] * 4 + [1.0],
            "incidence_gain_note": "sqrt(2) on the 45-deg stern planes, 1 on the sail planes",
            "hull_axis_unit_vector_body": geo["hull_axis_unit_vector_nh"],
            "names": [geo["planes"][str(i)]["name"] for i in range(1, 6)],
        },
        "added_mass": {"section_centres_stl_m": am["section_centres_CGi_m"], "Cvm_kg": am["Cvm_dm_kg"],
                       "columns": ["x", "y", "z"],
                       "implicit_matrix_6x6": am["equivalent_implicit_added_mass_matrix_6x6"]},
        "propeller": {"diameter_m": prop["diameter_m"], "KT_poly_descending": prop["KT_poly_descending"],
                      "KQ_poly_descending": prop["KQ_poly_descending"],
                      "thrust_deduction_as_implemented": prop["thrust_deduction_table"]["as_implemented_effective_value"]},
        "waves": {"sea_states": {k: {"L_wave_m": v["L_wave_m"], "A_wave_m": v["A_wave_m"]}
                                 for k, v in waves["sea_state_table"].items()},
                  "phase_rad": waves["phi_w"], "heading_parameter": waves["beta_w"],
                  "note": "regular deep-water wave towards +x_earth; k = 2 pi / L, omega = sqrt(g k); other "
                          "sea states are calm"},
        "actuators": {"plane_rate_deg_s": ctrl["actuators"]["plane_deflection"]["rate_limit_deg_per_s"],
                      "plane_limit_deg": ctrl["actuators"]["plane_deflection"]["saturation_deg"],
                      "rps_rate_per_s": ctrl["actuators"]["propeller_rps"]["rate_limit_rps_per_s"],
                      "rps_limits": ctrl["actuators"]["propeller_rps"]["saturation_rps"],
                      "dmass_rate_kg_s": ctrl["actuators"]["dmass_kg"]["rate_limit_kg_per_s"],
                      "dmass_limit_kg": ctrl["actuators"]["dmass_kg"]["saturation_kg"]},
        "table_inputs": {"us_clamp_X_m_s": [-5.14444, -1.543332], "us_clamp_Z_m_s": [-5.14444, -1.5433],
                         "zs_clamp_m": [-35.0624, -13.8724], "alpha_clamp_X_deg": [-30, 30],
                         "qs_clamp_Zqq_rad_s": [-0.02, 0.02],
                         "plane_speed_clamp_m_s": [-5.14444, -1.543332],
                         "thrust_deduction_depth_clamp_m": [-36.3724, -13.8724],
                         "thrust_deduction_speed_clamp_m_s": [-5.14444, -1.54333333]},
        "hardcoded": {
            "X_wq": hc["X"]["X_wq"]["c"], "T_wq": hc["X"]["T_wq"]["c"],
            "dXiuq_c2": hc["X"]["dXiuq"]["c2"], "dXiuq_c1": hc["X"]["dXiuq"]["c1"],
            "Y_r": hc["Y"]["Y_r"]["c"], "Z_uq": hc["Z"]["Z_uq"]["c"], "Z_uq_factor": 0.6,
            "Z_ur": hc["Z"]["Z_ur"]["c"], "speed_factor_m_s": 5.1444,
            "K_up": hc["K"]["K_up"]["c"], "K_ur": hc["K"]["K_ur"]["c"], "K_pp": hc["K"]["K_pp"]["c"],
            "M_uq": hc["M"]["M_uq"]["c"], "M_uq_factor": 1.1,
            "N_r": hc["N"]["N_r"]["c"], "N_r_factor": 0.8 * 0.5,
            "formulas": {k: {kk: vv.get("formula") for kk, vv in v.items() if isinstance(vv, dict)}
                         for k, v in hc.items() if not k.startswith("_") and isinstance(v, dict)},
        },
    }
    (OUT / "rom_model.json").write_text(json.dumps(model, indent=1) + "\n")
    print("wrote", OUT / "rom_tables.json", OUT / "rom_model.json")


if __name__ == "__main__":
    main()
