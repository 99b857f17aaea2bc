"""L1 channel: design matrices vs the shared check script, pass-through, and matched-uncertainty recovery."""
from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import numpy as np
import pytest
import yaml
from scipy import linalg

from bb2_control.l1_adaptive import (
    L1Augmentation,
    L1Channel,
    L1DesignError,
    NonFiniteInputError,
    design_channel,
    design_from_config,
)

DATA = Path(__file__).resolve().parents[2] / "bb2_control" / "data" / "l1_configs.yaml"


def _own_configs() -> dict:
    return yaml.safe_load(DATA.read_text())["configs"]


def _load_check_l1(path: Path):
    spec = importlib.util.spec_from_file_location("check_l1_shared", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _captured_build(mod, ch: dict, Ts: float, monkeypatch) -> dict[str, np.ndarray]:
    """Run check_l1.build and collect every array it prints, keyed by the label printed before it."""
    found: dict[str, np.ndarray] = {}

    def record(*args, **_kw):
        label = None
        for a in args:
            if isinstance(a, str):
                label = a.strip().rstrip("=").strip()
            elif isinstance(a, np.ndarray) and label is not None:
                found[label] = np.array(a, dtype=float)
                label = None

    monkeypatch.setattr(mod, "print", record, raising=False)
    mod.build(ch, Ts, "test")
    return found


def _channels(params: dict):
    for cname, cfg in params["l1"]["configs"].items():
        for chname, ch in cfg["channels"].items():
            if "same_as" not in ch:
                yield cname, chname, ch


def test_matrices_equal_check_l1(shared, monkeypatch):
    params = json.loads(shared("bb2_control", "params.json").read_text())
    mod = _load_check_l1(shared("bb2_control", "check_l1.py"))
    Ts = float(params["l1"]["Ts"])
    n_checked = 0
    for cname, chname, ch in _channels(params):
        ref = _captured_build(mod, ch, Ts, monkeypatch)
        d = design_from_config(ch, Ts)
        pairs = {
            "Kg": [d.Kg], "P": d.P, "sqrtP": d.sqrtP, "Lambda": d.Lam, "Phi(Ts)": d.Phi, "Phi^-1": d.Phiinv,
            "adaptation gain (sigma per unit yhat-y)": d.g_sigma.ravel(), "Ao": d.Ao, "Bo": d.Bo,
            "Co": d.Co.ravel(), "expm(Am Ts)": d.Em,
            "int expm(Am t) dt (x Bm gives input matrix)": d.Gamma, "expm(Ao Ts)": d.Eo,
            "int expm(Ao t) dt Bo expm(-Am Ts)": d.Go @ d.Em_inv,
        }
        if d.n_m > 1:
            pairs["D"] = d.D
        for key, ours in pairs.items():
            assert key in ref, f"check_l1 did not print {key!r} for {cname}/{chname}"
            np.testing.assert_allclose(np.asarray(ours, float).reshape(ref[key].shape), ref[key],
                                       rtol=1e-9, atol=1e-12, err_msg=f"{cname}/{chname}: {key}")
            n_checked += 1
    assert n_checked >= 4 * 14


def test_stored_source_matrices_reproduced(shared):
    """Lambda, Phi^-1 (and P, sqrt(P), D for the 2023 depth channel) equal the authors' stored numbers."""
    params = json.loads(shared("bb2_control", "params.json").read_text())
    Ts = float(params["l1"]["Ts"])
    for cname, chname, ch in _channels(params):
        ref = ch["reference_from_source"]
        d = design_from_config(ch, Ts)
        np.testing.assert_allclose(d.Lam, ref["Lambda"], rtol=1e-9, atol=1e-12)
        # the 2022 rate config stores Phi^-1 with 6 significant digits only
        rtol = 1e-9 if d.n_m > 1 else 1e-5
        np.testing.assert_allclose(d.Phiinv, ref["Phiinv"], rtol=rtol)
        for key, ours in (("P", d.P), ("sqrtP", d.sqrtP), ("D", d.D), ("Phi", d.Phi)):
            if key in ref:
                np.testing.assert_allclose(ours, ref[key], rtol=1e-9, atol=1e-12, err_msg=f"{cname}/{chname} {key}")


def test_own_data_carries_shared_numbers(shared):
    """bb2_control/data/l1_configs.yaml holds the same M and C as the published params."""
    params = json.loads(shared("bb2_control", "params.json").read_text())
    own = _own_configs()
    for cname, chname, ch in _channels(params):
        mine = own[cname]["channels"][chname]
        for block in ("M_tf", "C_tf"):
            for k in ("num", "den"):
                np.testing.assert_allclose(mine[block][k], ch[block][k], rtol=1e-15)
        for k in ("Am", "Bm", "Cm"):
            np.testing.assert_allclose(mine["M_ss"][k], ch["M_ss"][k], rtol=1e-15)
        assert own[cname]["Ts_s"] == params["l1"]["Ts"]


def test_documented_rate_values():
    d = design_from_config(_own_configs()["rate_2022"]["channels"]["q"], 0.05)
    assert d.Kg == pytest.approx(1.0, rel=1e-12)
    assert d.Phiinv.item() == pytest.approx(50.1251, rel=1e-5)
    assert d.g_sigma.item() == pytest.approx(-49.8751, rel=1e-5)
    # O(s) = 4 C_q(s): DC gain 4, third order
    Ao, Bo, Co = d.Ao, d.Bo, d.Co
    assert Ao.shape == (3, 3)
    assert (Co @ np.linalg.solve(-Ao, Bo)).item() == pytest.approx(4.0, rel=1e-12)


def test_realisation_of_O_does_not_change_the_law():
    """A similarity transform of (Ao, Bo, Co) gives identical u_ad (SPEC 5.2)."""
    d = design_from_config(_own_configs()["depth_heading_2023"]["channels"]["depth"], 0.05)
    T = np.array([[2.0, 1.0], [-0.5, 3.0]])
    Ti = np.linalg.inv(T)
    Ao, Bo, Co = T @ d.Ao @ Ti, T @ d.Bo, d.Co @ Ti
    Eo, Go = linalg.expm(Ao * 0.05), T @ d.Go
    d2 = type(d)(**{**d.__dict__, "Ao": Ao, "Bo": Bo, "Co": Co, "Eo": Eo, "Go": Go})
    rng = np.random.default_rng(3)
    a, b = L1Channel(d), L1Channel(d2)
    for i in range(300):
        y, r = rng.normal(), np.sin(0.01 * i)
        assert a.step(r, y) == pytest.approx(b.step(r, y), rel=1e-9, abs=1e-12)


def test_adaptation_off_passes_reference_through():
    aug = L1Augmentation.from_config(_own_configs()["rate_2022"], adaptive=False)
    rng = np.random.default_rng(0)
    for _ in range(50):
        ref = {"q": rng.normal(), "r": rng.normal()}
        out = aug.step(ref, {"q": rng.normal(), "r": rng.normal()})
        assert out == ref
    # states frozen while off
    assert np.all(aug.channels["q"].x_u == 0.0)


def _matched_plant_run(channel: L1Channel, theta: float, sigma0: float, T_end: float = 300.0):
    """Plant = desired system with a matched uncertainty f = theta*y + sigma0 + 0.002 sin(0.005 t) (inside the bandwidth of C(s)).

    u_ad is held over each Ts; the plant is integrated exactly over the tick for the linear part with the
    sine frozen at the tick start. Returns |y - y_desired| per tick.
    """
    d = channel.design
    Ts = d.Ts
    A = d.Am + d.Bm @ (theta * d.Cm)
    nm = d.n_m
    big = np.zeros((nm + 1, nm + 1))
    big[:nm, :nm] = A
    big[:nm, nm:] = d.Bm
    E = linalg.expm(big * Ts)
    x = np.zeros((nm, 1))
    xm = np.zeros((nm, 1))
    err = []
    for i in range(int(T_end / Ts)):
        t = i * Ts
        rho = 0.01 if t > 1.0 else 0.0
        y = (d.Cm @ x).item()
        u = channel.step(rho, y)
        f_ext = sigma0 + 0.002 * np.sin(0.005 * t)
        x = E[:nm, :nm] @ x + E[:nm, nm:] * (u + f_ext)
        xm = d.Em @ xm + d.Gamma @ d.Bm * (d.Kg * rho)
        err.append(abs((d.Cm @ x).item() - (d.Cm @ xm).item()))
    return np.array(err)


def test_l1_recovers_desired_response_under_matched_uncertainty():
    d = design_from_config(_own_configs()["rate_2022"]["channels"]["q"], 0.05)
    with_l1 = _matched_plant_run(L1Channel(d, adaptive=True), theta=-0.3, sigma0=0.004)
    without = _matched_plant_run(L1Channel(d, adaptive=False), theta=-0.3, sigma0=0.004)
    rms = lambda e: float(np.sqrt(np.mean(e**2)))  # noqa: E731
    assert rms(without) > 1e-3                 # the uncertainty really matters
    assert rms(with_l1) < 0.2 * rms(without)  # L1 brings the plant back to M(s)
    assert with_l1[-1000:].max() < 0.05 * without[-1000:].max()


def test_non_finite_input_is_rejected_and_state_unchanged():
    ch = L1Channel(design_from_config(_own_configs()["rate_2022"]["channels"]["q"], 0.05))
    ch.step(0.01, 0.0)
    xu, xh = ch.x_u.copy(), ch.x_hat.copy()
    with pytest.raises(NonFiniteInputError, match="not finite"):
        ch.step(float("nan"), 0.0)
    with pytest.raises(ValueError):
        ch.step(0.0, float("inf"))
    assert np.array_equal(ch.x_u, xu) and np.array_equal(ch.x_hat, xh)


@pytest.mark.parametrize(
    "kwargs, msg",
    [
        (dict(C_num=[1.0], C_den=[1.0, 1.0], Ts=0.05, M_ss=([[0.1]], [[1.0]], [[1.0]])), "Hurwitz"),
        (dict(C_num=[2.0], C_den=[1.0, 1.0], Ts=0.05, M_tf=([1.0], [1.0, 1.0])), "C\\(0\\)"),
        (dict(C_num=[1.0, 1.0], C_den=[1.0, 1.0], Ts=0.05, M_tf=([1.0], [1.0, 1.0])), "strictly proper"),
        (dict(C_num=[1.0], C_den=[1.0, 1.0], Ts=0.0, M_tf=([1.0], [1.0, 1.0])), "Ts"),
        (dict(C_num=[1.0], C_den=[1.0, 1.0], Ts=0.05, M_ss=([[-1.0]], [[1.0]], [[1.0]]),
              M_tf=([2.0], [1.0, 1.0])), "realise"),
    ],
)
def test_bad_designs_raise(kwargs, msg):
    with pytest.raises(L1DesignError, match=msg):
        design_channel(**kwargs)


def test_the_transfer_function_of_a_realisation_is_scipy_signal_ss2tf_to_the_last_digit():
    """design_channel builds M(s) and O(s)'s rows with ss2tf_siso (importing scipy.signal cost the autopilot node
    ~0.35 s of CPU at every start): the same arrays, bit for bit, as scipy.signal.ss2tf, for every shipped channel's
    realisation and each of its state rows, and for random stable systems; so the shipped designs are unchanged."""
    from scipy import signal

    from bb2_control.l1_adaptive import ss2tf_siso

    rng = np.random.default_rng(5)
    systems = [(ch["M_ss"]["Am"], ch["M_ss"]["Bm"], ch["M_ss"]["Cm"]) for cfg in _own_configs().values()
               for ch in cfg["channels"].values() if "M_ss" in ch]
    assert len(systems) >= 4
    systems += [(rng.normal(size=(n, n)) - 3 * np.eye(n), rng.normal(size=(n, 1)), rng.normal(size=(1, n)))
                for n in (1, 2, 3, 5)]
    for A, B, C in systems:
        n = np.shape(A)[0]
        for Bj in [B] + [np.eye(n)[:, [j]] for j in range(n)]:
            want = signal.ss2tf(A, Bj, C, np.zeros((1, 1)))
            got = ss2tf_siso(A, Bj, C)
            for g, w in zip(got, want):
                assert g.dtype == w.dtype and g.shape == w.shape and np.array_equal(g, w), (A, Bj, C)
    import subprocess
    import sys

    code = ("import sys\nfrom bb2_control.stacks import build_stack\nbuild_stack('rate_2022')\n"
            "print(sorted(n for n in ('scipy.signal', 'scipy.stats') if n in sys.modules))")
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert p.returncode == 0 and p.stdout.strip() == "[]", (p.stdout, p.stderr)   # the reason it is written so


def test_transfer_function_only_design_has_unit_dc_gain():
    d = design_channel([1.0], [1.0, 2.0, 1.0], 0.05, M_tf=([4.0], [1.0, 2.0, 4.0]))
    assert d.Kg * (d.Cm @ np.linalg.solve(-d.Am, d.Bm)).item() == pytest.approx(1.0)
    # O(s) has the DC gain of M(0)^-1 Cm (-Am)^-1 = Kg Cm (-Am)^-1 (row)
    dc_O = d.Co @ np.linalg.solve(-d.Ao, d.Bo)
    np.testing.assert_allclose(dc_O, d.Kg * d.Cm @ np.linalg.inv(-d.Am), rtol=1e-9)


@pytest.mark.parametrize("config, channel", [("rate_2022", "q"), ("depth_heading_2023", "depth"),
                                              ("depth_heading_dec2022", "heading")])
def test_the_tick_on_floats_is_the_matrix_law(config, channel):
    """The channel's tick (on floats; n_m = 1 written out, n_m > 1 by rows) equals SPEC 5's matrix law step by
    step to round-off, through an adaptation off/on switch (re-initialised from the measurement)."""
    ch = L1Augmentation.from_config(_own_configs()[config]).channels[channel]
    d = ch.design
    rng = np.random.default_rng(5)
    x_u, x_hat, init = np.zeros((d.n_o, 1)), np.zeros((d.n_m, 1)), False
    us = []
    for k in range(300):
        rho, y = float(rng.normal()), float(rng.normal())
        if k == 150:
            ch.adaptive = False
        if k == 160:
            ch.adaptive, init = True, False
        got = ch.step(rho, y)
        if not ch.adaptive:
            assert got == rho
            continue
        if not init:
            x_hat, x_u, init = d.Cm.T @ np.linalg.solve(d.Cm @ d.Cm.T, [[y]]), np.zeros((d.n_o, 1)), True
        sigma = d.g_sigma * ((d.Cm @ x_hat).item() - y)
        u = d.Kg * rho - (d.Co @ x_u).item()
        x_u = d.Eo @ x_u + d.Go @ (d.Em_inv @ sigma)
        x_hat = d.Em @ x_hat + d.Gamma @ (d.Bm * u + sigma)
        assert got == pytest.approx(u, rel=1e-12, abs=1e-12)
        np.testing.assert_allclose(ch.x_u, x_u, rtol=1e-11, atol=1e-12)
        np.testing.assert_allclose(ch.x_hat, x_hat, rtol=1e-11, atol=1e-12)
        np.testing.assert_allclose(ch.sigma_hat, sigma, rtol=1e-12, atol=1e-15)
        us.append(u)
    assert np.std(us) > 1e-3 and ch.x_u.shape == (d.n_o, 1) and ch.x_hat.shape == (d.n_m, 1)
