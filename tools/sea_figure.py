"""The README figure of "the sea and current options": docs/img/sea_and_current.png.

(a) the elevation record of a sea-state-5 JONSWAP sea (Hs 3.25 m, Tp 9.7 s, 64 components, seed 0) at the
earth origin, as ``bb2-sim sea`` writes it; (b) its spectrum (Welch estimate of a 3600 s record and the
realised components' energy) against the target JONSWAP; (c) a near-surface run in waves: the self-propulsion
maneuver at periscope depth in that sea (beam seas, short-crested s = 10) with a 0.5 m/s current, CG depth and
the elevation above the CG (``eta_cg_m``), against the same run in calm water.

    .venv/bin/python tools/sea_figure.py [--out docs/img/sea_and_current.png] [--duration 200]
"""
from __future__ import annotations

import argparse
import math
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]


def _bb2_sim(*args: str) -> str:
    p = subprocess.run([sys.executable, "-m", "bb2_tools.sim_cli", *args], cwd=REPO, capture_output=True, text=True)
    if p.returncode != 0:
        raise SystemExit(f"bb2-sim {' '.join(args)} failed:\n{p.stderr}")
    return p.stdout


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=str(REPO / "docs" / "img" / "sea_and_current.png"))
    ap.add_argument("--duration", type=float, default=200.0, help="maneuver length (s)")
    a = ap.parse_args(argv)
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from scipy.signal import welch

    from bb2_sim.environment import sea_from_mapping
    from bb2_sim.sea import spectrum

    tmp = Path(tempfile.mkdtemp(prefix="bb2_sea_fig_"))
    sea_args = ["--spectrum", "jonswap", "--hs", "3.25", "--tp", "9.7", "--seed", "0"]
    rec = tmp / "eta.csv"
    printed = _bb2_sim("sea", *sea_args, "--duration", "3600", "--out", str(rec))
    print(printed, end="")
    t, eta = np.loadtxt(rec, delimiter=",", skiprows=1, unpack=True)

    wave = ["--spectrum", "jonswap", "--hs", "3.25", "--tp", "9.7", "--wave-heading-deg", "90", "--spreading-s",
            "10", "--components", "32", "--seed", "0"]
    runs = {}
    for name, extra in (("calm", []), ("waves", wave + ["--current-mps", "0.5", "--current-heading-deg", "0"])):
        out = tmp / f"sp_{name}.csv"
        _bb2_sim("maneuver", "self-propulsion", "--depth", "18", "--duration", f"{a.duration:g}", "--quiet",
                 "--out", str(out), *extra)
        with open(out) as fh:
            head = fh.readline().strip().split(",")
        runs[name] = dict(zip(head, np.loadtxt(out, delimiter=",", skiprows=1, unpack=True)))

    fig, ax = plt.subplots(3, 1, figsize=(9, 10))
    k = t <= 300
    ax[0].plot(t[k], eta[k], lw=0.8)
    ax[0].set(xlabel="t [s]", ylabel="eta [m]", title="bb2-sim sea --spectrum jonswap --hs 3.25 --tp 9.7: "
                                                      "elevation at (0, 0), first 300 s of 3600 s")
    ax[0].grid(alpha=0.3)

    f, S_f = welch(eta - eta.mean(), fs=1.0 / (t[1] - t[0]), nperseg=4096)
    w = 2 * math.pi * f
    S_w = S_f / (2 * math.pi)
    target = spectrum("jonswap", hs=3.25, tp=9.7, gamma=3.3)
    comps = sea_from_mapping({"spectrum": "jonswap", "hs": 3.25, "tp": 9.7, "seed": 0}).wave_components()
    order = np.argsort(comps.omega)
    wc = comps.omega[order]
    edges = np.r_[wc[0] - (wc[1] - wc[0]) / 2, (wc[1:] + wc[:-1]) / 2, wc[-1] + (wc[-1] - wc[-2]) / 2]
    ax[1].plot(w, S_w, label="record (Welch, 3600 s)")
    ax[1].step(wc, (comps.amplitude[order] ** 2 / 2) / np.diff(edges), where="mid",
               label=f"{len(comps)} components: a^2/2 / d omega")
    wg = np.linspace(0.2, 2.5, 500)
    ax[1].plot(wg, target(wg), "k--", label="target JONSWAP (Hs 3.25 m, Tp 9.7 s, gamma 3.3)")
    ax[1].set(xlim=(0.2, 2.0), xlabel="omega [rad/s]", ylabel="S [m^2 s/rad]",
              title=f"spectrum: realisation Hs {comps.hs:.3f} m (4 sqrt(m0)), record {4 * np.std(eta):.3f} m")
    ax[1].legend()
    ax[1].grid(alpha=0.3)

    for name, r in runs.items():
        ax[2].plot(r["t_s"], -r["z_m"], label=f"CG depth, {name}")
    rw = runs["waves"]
    ax[2].plot(rw["t_s"], -rw["eta_cg_m"], lw=0.8, label="surface above the CG: -eta_cg_m (waves)")
    ax[2].invert_yaxis()
    ax[2].set(xlabel="t [s]", ylabel="depth [m]",
              title="self-propulsion from 18 m depth in sea state 5 (beam, s = 10) + 0.5 m/s current vs calm")
    ax[2].legend(loc="lower right", fontsize=8)
    ax[2].grid(alpha=0.3)
    fig.tight_layout()
    Path(a.out).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(a.out, dpi=100)
    for name, r in runs.items():
        sl = r["t_s"] >= a.duration / 2
        print(f"{name}: depth mean {-np.mean(r['z_m'][sl]):.2f} m, std {np.std(r['z_m'][sl]):.3f} m, "
              f"roll std {np.std(r['phi_deg'][sl]):.2f} deg, y drift {r['y_m'][-1]:.1f} m, x {r['x_m'][-1]:.1f} m "
              f"(second half)")
    print(f"figure: {a.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
