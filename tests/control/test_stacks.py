"""Named stacks: loading, errors, composition of the pieces, adaptation switch, NaN policy."""
from __future__ import annotations

import json
import math

import numpy as np
import pytest
import yaml

from bb2_control.config import load_data
from bb2_control.errors import ControlConfigError, NonFiniteInputError, UnknownStackError
from bb2_control.path_following import flow_to_body_rates
from bb2_control.stacks import available_stacks, build_stack, resolve_config
from bb2_sim import frames
from bb2_sim.state import VehicleState

pytest.importorskip("bb2_planner.paths", reason="bb2_planner is needed for the paths")

# circle scenario start (SPEC 2.5, params.json scenarios.circle_2023), native frames
X0 = np.array([0.0, -400.0, -100.0, 0.0, 0.0, -math.pi, -5.14444, 0.0, 0.0, 0.0, 0.0, 0.0])


def _states(n: int, seed: int = 0):
    """A wandering but plausible sequence of native states near the circle start."""
    rng = np.random.default_rng(seed)
    x = X0.copy()
    for k in range(n):
        x = x.copy()
        x[0:3] += 0.05 * np.array([-5.1 * math.cos(x[5]), -5.1 * math.sin(x[5]), 0.0])
        x[3:6] += rng.normal(scale=[1e-4, 2e-4, 3e-4])
        x[6:9] = [-5.14444, rng.normal(scale=0.05), rng.normal(scale=0.05)]
        x[9:12] = rng.normal(scale=[1e-3, 2e-3, 3e-3])
        yield VehicleState.from_vector(0.05 * k, x)


def test_named_stacks_build_and_step():
    assert {"rate_2022", "los_2023"} <= set(available_stacks())
    for name, rps in (("rate_2022", 4.78 / 4.0), ("los_2023", 5.14444 / 4.0)):
        st = build_stack(name)
        outs = [st.step(s) for s in _states(20)]
        o = outs[-1]
        assert o.rps == pytest.approx(rps)
        assert o.planes_deg.shape == (5,)
        assert np.all(np.isfinite(o.planes_deg)) and math.isfinite(o.dV_deg) and math.isfinite(o.dH_deg)
        assert outs[0].gamma == 0.0 and 0.5 < o.gamma < 1.5        # ~20 ticks at gamma_dot ~ 1
        np.testing.assert_allclose(o.p_d_native, st.path.to_frame("native")(o.gamma) if st.frame != "native"
                                   else st.path(o.gamma), atol=1e-9)


def test_default_stack_is_rate_2022():
    assert resolve_config(None)[0] == "rate_2022"
    assert type(build_stack()).__name__ == "RatePathFollowingStack"


def test_unknown_stack_name_is_one_clear_error():
    with pytest.raises(UnknownStackError, match="unknown control stack 'rate_2021'.*rate_2022") as e:
        build_stack("rate_2021")
    assert isinstance(e.value, ValueError)
    with pytest.raises(UnknownStackError, match="base"):
        build_stack({"base": "nope"})


def test_stack_from_yaml_and_json_files(tmp_path):
    y = tmp_path / "my_stack.yaml"
    y.write_text(yaml.safe_dump({"base": "rate_2022", "guidance": {"d_m": 100.0}, "adaptation": False}))
    st = build_stack(y)
    assert st.guidance.gains.d == 100.0 and st.guidance.gains.k_R == 0.1 and not st.adaptation
    j = tmp_path / "my_stack.json"
    j.write_text(json.dumps({"base": "los_2023", "l1": "depth_heading_dec2022"}))
    st = build_stack(j)
    assert st.inner.l1.channels["depth"].design.n_o == 3
    bad = tmp_path / "bad.yaml"
    bad.write_text(yaml.safe_dump({"type": "warp_drive"}))
    with pytest.raises(ControlConfigError, match="type"):
        build_stack(bad)
    with pytest.raises(ControlConfigError, match="not found"):
        build_stack(tmp_path / "missing.yaml")
    with pytest.raises(ControlConfigError, match="no entry"):
        build_stack("rate_2022", overrides={"l1": "rate_2099"})


def test_overrides_and_mixer_sail_sign():
    st = build_stack("rate_2022", overrides={"mixer": {"sail_sign": -1}, "speed": {"v_ref_mps": 4.0}})
    assert st.mixer.step(1.0, 0.0)[4] == -1.0
    assert st.speed.step() == pytest.approx(1.0)
    with pytest.raises(ControlConfigError, match="Ts"):
        build_stack("rate_2022", overrides={"guidance": {"Ts_s": 0.1}})


@pytest.mark.parametrize("doc, said", [
    ({"base": "rate_2022", "guidanc": {"d_m": 5.0}}, "guidanc (did you mean guidance?)"),
    ({"base": "rate_2022", "guidance": {"d_mm": 5.0}}, "guidance.d_mm (did you mean guidance.d_m?)"),
    ({"base": "los_2023", "autopilot": {"K_q_deg_per_radps": 3.0}}, "autopilot.K_q_deg_per_radps"),  # the rate loop's
    ({"base": "rate_2022", "mixer": {"sail_sing": -1}}, "mixer.sail_sing (did you mean mixer.sail_sign?)"),
    ({"base": "rate_2022", "speed": {"v_ref": 4.0}}, "speed.v_ref (did you mean speed.v_ref_mps?)"),
])
def test_a_key_the_stack_does_not_have_is_refused(doc, said):
    """A typo in a stack's changes (a mission's stack: block, a campaign's varied stack.guidance.d_m) changed
    nothing, without a word: a campaign 'varying' stack.guidance.d_mm flew every run with the stack's own d."""
    with pytest.raises(ControlConfigError, match="unknown key") as e:
        build_stack(doc)
    assert said in str(e.value) and "it would change nothing" in str(e.value)
    with pytest.raises(ControlConfigError, match="unknown key"):
        build_stack(doc["base"], overrides={k: v for k, v in doc.items() if k != "base"})


def test_the_keys_a_stack_reads_beyond_its_data_and_whole_sections_are_accepted():
    st = build_stack({"base": "rate_2022", "name": "mine", "description": "d", "source": "s",
                      "mixer": {"saturation_deg": 25.0},
                      "guidance": {"d_m": 120.0}, "autopilot": "rate_P_2022"})
    assert st.name == "mine" and st.guidance.gains.d == 120.0
    st2 = build_stack({"base": "rate_2022", "mixer": {"matrix_rows_planes_cols_dV_dH": [[1, 0], [0, 1], [1, 0],
                                                                                         [0, 1], [1, 0]]}})
    assert st2.mixer.step(1.0, 0.0)[0] == 1.0


def test_adaptation_off_equals_baseline_autopilot():
    st = build_stack("rate_2022", overrides={"adaptation": False})
    K = load_data("autopilots")["rate_P_2022"]["K_q_deg_per_radps"]
    for s in _states(60, seed=1):
        o = st.step(s)
        assert o.u_ad == {"q": o.q_up_ref, "r": o.r_left_ref}
        assert o.dV_deg == pytest.approx(K * (o.q_up_ref - s.w_body_native[1]), rel=1e-12)
        assert o.dH_deg == pytest.approx(K * (o.r_left_ref - s.w_body_native[2]), rel=1e-12)
    on = build_stack("rate_2022")
    outs = [on.step(s) for s in _states(60, seed=1)]
    assert max(abs(o.u_ad["q"] - o.q_up_ref) for o in outs) > 1e-6   # with adaptation the reference is modified


def test_pieces_compose_to_the_stack():
    """A ROS split (PF node -> L1/autopilot node -> mixer node) reproduces the in-process stack exactly."""
    st = build_stack("rate_2022")
    pf_only, inner_only, mixer_only = build_stack("rate_2022"), build_stack("rate_2022"), build_stack("rate_2022")
    for s in _states(40, seed=2):
        ref = st.step(s)
        R_BI = frames.rotation_native(*s.euler_native) @ frames.D_FLIP
        v_flu = frames.body_native_to_flu(s.v_body_native)
        pf = pf_only.guidance.step(s.p_native, R_BI, v_flu)
        q_ref, r_ref = flow_to_body_rates(pf.q_c, pf.r_c, v_flu)
        dV, dH, _ = inner_only.inner.step(q_ref, r_ref, s.w_body_native[1], s.w_body_native[2])
        planes = mixer_only.mixer.step(dV, dH)
        assert (pf.q_c, pf.r_c, dV, dH) == (ref.q_c, ref.r_c, ref.dV_deg, ref.dH_deg)
        np.testing.assert_array_equal(planes, ref.planes_deg)


def test_rate_stack_is_invariant_to_the_working_frame():
    a = build_stack("rate_2022")
    b = build_stack("rate_2022", overrides={"frame": "controller"})
    for s in _states(30, seed=3):
        oa, ob = a.step(s), b.step(s)
        assert oa.dV_deg == pytest.approx(ob.dV_deg, rel=1e-9, abs=1e-9)
        assert oa.dH_deg == pytest.approx(ob.dH_deg, rel=1e-9, abs=1e-9)
        np.testing.assert_allclose(oa.p_d_native, ob.p_d_native, atol=1e-9)
    with pytest.raises(ControlConfigError, match="z-up"):
        build_stack("rate_2022", overrides={"frame": "ned"})


def test_los_stack_heading_in_controller_frame_is_native_psi():
    st = build_stack("los_2023", overrides={"adaptation": False})
    o = st.step(VehicleState.from_vector(0.0, X0))
    # SPEC 2.5: tangent heading at gamma = 0 is -178.27 deg in frame C, vehicle psi = -180 deg
    assert math.degrees(o.psi_ref) == pytest.approx(-178.27, abs=0.01)
    assert o.dH_deg == pytest.approx(3.0 * (math.degrees(o.psi_ref) + 180.0), rel=1e-9)   # no D kick


def test_nan_policy_raise_and_hold():
    good = VehicleState.from_vector(0.0, X0)
    bad_x = X0.copy()
    bad_x[10] = np.nan
    bad = VehicleState.from_vector(0.05, bad_x)
    st = build_stack("rate_2022")
    first = st.step(good)
    g = st.guidance.gamma
    with pytest.raises(NonFiniteInputError, match="non-finite vehicle state"):
        st.step(bad)
    assert st.guidance.gamma == g                         # nothing advanced
    hold = build_stack("rate_2022", overrides={"nan_policy": "hold"})
    with pytest.raises(NonFiniteInputError, match="no previous output"):
        hold.step(bad)
    first = hold.step(good)
    again = hold.step(bad)
    assert again.held and again.dV_deg == first.dV_deg and hold.guidance.gamma == pytest.approx(first.gamma
                                                                                                 + 0.05 * first.gamma_dot)
    with pytest.raises(ControlConfigError, match="nan_policy"):
        build_stack("rate_2022", overrides={"nan_policy": "ignore"})


def test_reset_restarts_everything():
    st = build_stack("los_2023")
    a = [st.step(s) for s in _states(10)]
    st.reset()
    b = [st.step(s) for s in _states(10)]
    assert [o.dV_deg for o in a] == [o.dV_deg for o in b] and a[-1].gamma == b[-1].gamma


def test_speed_data_carried_from_shared(shared):
    prop = json.loads(shared("bb2_control", "params.json").read_text())["actuators"]["propeller"]
    st = load_data("stacks")["stacks"]
    assert st["rate_2022"]["speed"]["v_ref_mps"] == prop["v_ref_mps_2022_pf"]
    assert st["los_2023"]["speed"]["v_ref_mps"] == prop["v_ref_mps_2023"]
    assert build_stack("los_2023").speed.step() == pytest.approx(prop["n_rps_2023"], abs=1e-5)
    assert build_stack("rate_2022").speed.step() == pytest.approx(prop["n_rps_2022_pf"], abs=1e-9)


def test_stacks_prepared_together_step_as_alone():
    """prepare_stacks (the mission batch's tick): rate stacks of two look-aheads and a LOS stack; each stack's
    step of the prepared state is its twin's alone to the last bit, and one stepped with another state than it
    was prepared for computes it alone."""
    from bb2_control.stacks import prepare_stacks

    specs = ["rate_2022", {"base": "rate_2022", "guidance": {"d_m": 300.0}}, "los_2023",
             {"base": "rate_2022", "adaptation": False}]
    together = [build_stack(s) for s in specs]
    alone = [build_stack(s) for s in specs]
    runs = [list(_states(60, seed=k)) for k in range(len(specs))]
    for k in range(60):
        states = [r[k] for r in runs]
        prepare_stacks(together, states)
        assert [s._prepared_inputs is not None for s in together] == [True, True, False, True]
        if k == 20:   # another state than prepared
            states[1] = VehicleState.from_vector(states[1].t, states[1].as_vector() + 0.01)
        for a, b, s in zip(together, alone, states):
            oa, ob = a.step(s), b.step(s)
            fa, fb = ([o.q_c, o.r_c, o.dV_deg, o.dH_deg, o.gamma, o.gamma_dot, *o.planes_deg] for o in (oa, ob))
            assert np.array_equal(fa, fb, equal_nan=True), k


def test_inputs_computed_together_are_each_stacks_own_to_the_bit():
    """prepare_stacks computes the stacks' inputs together (one rotation for all, the frame changes stacked): for
    stacks in every frame a stack takes, and states with zero and negative-zero components (where a product's kernel could
    differ in the sign of a zero), each equals the stack's own Stack.inputs bit for bit."""
    from bb2_control.stacks import _inputs_together

    frames_ = ["native", "enu", "controller"]          # the frames a stack flies in (z up)
    stacks = [build_stack({"base": "rate_2022", "frame": f}) for f in frames_ for _ in range(3)]
    rng = np.random.default_rng(8)
    X = rng.normal(size=(len(stacks), 12)) * [50, 50, 10, 0.1, 0.2, 3, 3, 0.3, 0.3, 0.01, 0.02, 0.03]
    X[::2, 3] = 0.0                        # no roll
    X[1::3, 7:9] = -0.0                    # negative zeros
    X[2::4, [0, 4, 9]] = [0.0, -0.0, 0.0]
    got = _inputs_together(stacks, [VehicleState.from_vector(1.0, x) for x in X], X)
    assert len({s.frame for s in stacks}) == 3 and len({s._M.tobytes() for s in stacks}) == 2
    for st, x, g in zip(stacks, X, got):
        own = st.inputs(VehicleState.from_vector(1.0, x))
        assert own.keys() == g.keys()
        for k in own:
            a, b = np.asarray(own[k], dtype=float), np.asarray(g[k], dtype=float)
            assert a.shape == b.shape and a.tobytes() == b.tobytes(), (st.frame, k, a, b)
