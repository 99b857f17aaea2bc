"""``bb2-sim``: command-line runner of the BB2 ROM.

    bb2-sim maneuver NAME [options]     one of: self-propulsion, depth-heading, turning-circle, hzz, vzz, open-loop
    bb2-sim sea [sea options] --duration T --out FILE.csv   the free-surface elevation record of a sea
    bb2-sim mission FILE.yaml [options] closed-loop mission (ROM + planner + guidance + autopilot), no ROS

Exit status: 0 done, 1 the simulation diverged (the CSV keeps every row up to it), 2 bad input.
"""
from __future__ import annotations

import argparse
import math
import sys
from dataclasses import asdict


class InputError(ValueError):
    """Bad command-line input (exit status 2)."""


def finite_float(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not math.isfinite(v):
        raise argparse.ArgumentTypeError(f"must be finite, got {text!r}")
    return v


def int_at_least(low: int):
    """An argparse type: an integer >= ``low`` ("not an integer: 'x'", "must be >= 1, got 0")."""
    def parse(text: str) -> int:
        try:
            v = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"not an integer: {text!r}") from None
        if v < low:
            raise argparse.ArgumentTypeError(f"must be >= {low}, got {v}")
        return v
    return parse


positive_int = int_at_least(1)


SUBSTEPS_HELP = ("ROM ode3 steps per 0.05 s step (default 1: the authors' fixed step, numerically unstable in a "
                 "steady cruise from about 11.6 m/s; 2 fly to about 15 m/s, 3 to about 18, 4 to about 20.5)")


def plane_list(text: str) -> tuple[float, ...]:
    parts = [p for p in text.replace(" ", "").split(",") if p != ""]
    vals = tuple(finite_float(p) for p in parts)
    if len(vals) != 5:
        raise argparse.ArgumentTypeError(f"needs exactly 5 comma-separated angles d1,d2,d3,d4,d5, got {len(vals)}")
    return vals


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # one clear line and status 2
        self.exit(2, f"{self.prog}: error: {message}\n")


def build_parser() -> argparse.ArgumentParser:
    """``bb2-sim`` with the ROM's own sub-command (``maneuver``); the tools layer adds ``mission``
    (:mod:`bb2_tools.sim_cli`)."""
    p = _Parser(prog="bb2-sim", description="BB2 reduced-order model: maneuvers and missions.")
    sub = p.add_subparsers(dest="command", required=True, parser_class=_Parser)
    add_maneuver_parser(sub)
    add_sea_parser(sub)
    return p


def components_arg(text: str) -> int | str:
    """``--components``: a number of components (integer >= 1) or a CSV component file."""
    try:
        v = float(text)
    except ValueError:
        return text          # a file name
    if not math.isfinite(v) or v != int(v) or v < 1:
        raise argparse.ArgumentTypeError(f"needs an integer number of components >= 1 (or a CSV file), got {text!r}")
    return int(v)


def seed_arg(text: str) -> int:
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"needs an integer >= 0, got {text!r}") from None
    if v < 0:
        raise argparse.ArgumentTypeError(f"needs an integer >= 0, got {text!r}")
    return v


def point_xy(text: str) -> tuple[float, float]:
    parts = [q for q in text.replace(" ", "").split(",") if q != ""]
    if len(parts) != 2:
        raise argparse.ArgumentTypeError(f"needs X,Y (two comma-separated numbers, m), got {text!r}")
    return finite_float(parts[0]), finite_float(parts[1])


def add_sea_options(p: argparse.ArgumentParser, heading_flag: str = "--heading-deg") -> None:
    """The sea options (the keys of a mission's ``sea:`` block, :mod:`bb2_sim.environment`)."""
    from .environment import SPECTRA

    g = p.add_argument_group("sea (irregular, directional; see bb2_sim.environment)")
    g.add_argument("--spectrum", choices=SPECTRA, help="wave spectrum (regular: one wave of --amplitude-m, "
                                                       "--period-s)")
    g.add_argument("--hs", type=finite_float, metavar="M", help="significant wave height (m, >= 0)")
    g.add_argument("--tp", type=finite_float, metavar="S", help="peak period (s, > 0)")
    g.add_argument("--gamma", type=finite_float, metavar="G", help="JONSWAP peak enhancement (>= 1, default 3.3)")
    g.add_argument("--amplitude-m", type=finite_float, metavar="A", help="regular wave amplitude (m; default Hs/2)")
    g.add_argument("--period-s", type=finite_float, metavar="T", help="regular wave period (s; default Tp)")
    g.add_argument(heading_flag, type=finite_float, metavar="D", dest="wave_heading_deg",
                   help="direction the waves travel towards (deg, native earth frame: 0 = +x, 90 = +y; default 0)")
    g.add_argument("--spreading-s", type=finite_float, metavar="S",
                   help="cos-2s spreading exponent s (> 0): short-crested about the heading")
    g.add_argument("--components", type=components_arg, metavar="N|FILE.csv",
                   help="number of spectral components (default 64) or a CSV component list "
                        "(amplitude_m, omega_rad_s, direction_deg, phase_deg)")
    g.add_argument("--seed", type=seed_arg, metavar="K", help="seed of the random phases (default 0)")


def sea_block_from_args(a: argparse.Namespace, sea_state: float | None = None) -> dict | None:
    """The ``sea:`` mapping of the sea options (None if none was given)."""
    keys = {"spectrum": a.spectrum, "hs": a.hs, "tp": a.tp, "gamma": a.gamma, "amplitude_m": a.amplitude_m,
            "period_s": a.period_s, "heading_deg": a.wave_heading_deg, "spreading_s": a.spreading_s,
            "components": a.components, "seed": a.seed}
    block = {k: v for k, v in keys.items() if v is not None}
    if not block:
        return None
    if sea_state is not None:
        block["sea_state"] = sea_state
    return block


def add_maneuver_parser(sub) -> argparse.ArgumentParser:
    """The ``maneuver`` sub-command on a sub-parsers object."""
    from .maneuvers import maneuver_names

    m = sub.add_parser("maneuver", help="run a standard maneuver and print its ITTC figures",
                       description="Run a standard maneuver of the BB2 ROM. Angles in the authors' native "
                                   "convention (psi > 0 bow to port); depths positive down.")
    m.add_argument("name", choices=maneuver_names(), metavar="NAME",
                   help="one of: " + ", ".join(maneuver_names()))
    m.add_argument("--depth", type=finite_float, metavar="M", help="initial CG depth (m, positive down)")
    m.add_argument("--depth-ref", type=finite_float, metavar="M",
                   help="depth held by the autopilot (m); default: --depth")
    m.add_argument("--heading-ref-deg", type=finite_float, metavar="D",
                   help="heading held by the autopilot (deg, native psi: positive = bow to port)")
    m.add_argument("--speed-mps", type=finite_float, metavar="U", help="initial forward speed (m/s, positive ahead)")
    m.add_argument("--rps", type=finite_float, metavar="N", help="propeller command (rps); default U/4 as the authors")
    m.add_argument("--sea-state", type=finite_float, metavar="S", help="sea state 0..7 (0, 1 calm; regular head waves)")
    m.add_argument("--rudder-deg", type=finite_float, metavar="D",
                   help="turning circle rudder (deg); positive = starboard turn (dh = -D)")
    m.add_argument("--amplitude-deg", type=finite_float, metavar="A", help="zig-zag deflection (deg)")
    m.add_argument("--check-deg", type=finite_float, metavar="C", help="zig-zag check angle (deg)")
    m.add_argument("--sail-planes", choices=["pid", "zero"], help="vzz: sail planes at zero or flown by the depth PID")
    m.add_argument("--planes-deg", type=plane_list, metavar="d1,d2,d3,d4,d5",
                   help="open loop: the five plane angles (deg, the authors' plane signs)")
    m.add_argument("--duration", type=finite_float, metavar="T", help="simulated time (s)")
    m.add_argument("--profile", default="iowa", choices=["iowa", "corrected"], help="physics profile")
    m.add_argument("--substeps", type=positive_int, metavar="K", help=SUBSTEPS_HELP)
    m.add_argument("--hull-mesh", metavar="DIR", help="directory of hull surface files (STL/OBJ); default: "
                                                      "the BB2 hull generated from the table of offsets")
    m.add_argument("--out", metavar="FILE.csv", help="write the trajectory (reference CSV columns and eta_cg_m, "
                                                     "every 0.1 s)")
    m.add_argument("--plot", metavar="FILE.png", help="draw the maneuver plot (PNG; .pdf, .svg, .eps, .ps by the "
                   "file's extension)")
    m.add_argument("--overwrite", action="store_true", help="replace existing --out/--plot files (else exit 2)")
    m.add_argument("--quiet", action="store_true", help="no progress line")
    add_sea_options(m, "--wave-heading-deg")
    c = m.add_argument_group("current")
    c.add_argument("--current-mps", type=finite_float, metavar="U", help="current speed (m/s, >= 0), uniform")
    c.add_argument("--current-heading-deg", type=finite_float, metavar="D",
                   help="direction the water moves towards (deg, native earth frame: 0 = +x, 90 = +y)")
    return m


def add_sea_parser(sub) -> argparse.ArgumentParser:
    """The ``sea`` sub-command: the elevation record of a sea at one earth point."""
    p = sub.add_parser("sea", help="write the free-surface elevation record of a sea and print its Hs and Tp",
                       description="Realise a sea (the options of a mission's sea: block) and write the elevation "
                                   "above the calm surface at one earth point, t_s,eta_m, every dt.")
    add_sea_options(p)
    p.add_argument("--sea-state", type=finite_float, metavar="S",
                   help="alone: the authors' regular table; with --spectrum: Hs and Tp of the sea-state table")
    p.add_argument("--duration", type=finite_float, metavar="T", required=True, help="record length (s, > 0)")
    p.add_argument("--dt", type=finite_float, metavar="S", default=0.1, help="sample interval (s, > 0; default 0.1)")
    p.add_argument("--at", type=point_xy, metavar="X,Y", default=(0.0, 0.0),
                   help="earth point (m, native frame; default 0,0)")
    p.add_argument("--out", metavar="FILE.csv", required=True, help="the record: t_s,eta_m")
    p.add_argument("--overwrite", action="store_true", help="replace an existing --out file (else exit 2)")
    return p


def current_block_from_args(a: argparse.Namespace) -> dict | None:
    """The ``current:`` mapping of the current options (None if none was given; a heading alone is refused by
    :func:`bb2_sim.environment.current_from_mapping`, as in a mission file)."""
    block = {k: v for k, v in (("speed_mps", a.current_mps), ("heading_deg", a.current_heading_deg)) if v is not None}
    return block or None


def _fmt(value) -> str:
    """A figure for printing: numbers to 4 significant digits, tuples element-wise."""
    if isinstance(value, (tuple, list)):
        return "(" + ", ".join(_fmt(v) for v in value) + ")"
    if isinstance(value, float):
        return f"{value:.4g}"
    return str(value)


def _progress(enabled: bool, total: float):
    if not enabled:
        return None

    def cb(t: float) -> None:
        sys.stderr.write(f"\r  t = {t:7.1f} / {total:.0f} s")
        sys.stderr.flush()
    return cb


def run_maneuver_cli(a: argparse.Namespace) -> int:
    from .geometry import HullMeshError
    from .maneuvers import (CsvWriter, ManeuverError, build_model, check_initial_depth, maneuver_settings,
                            channels, inapplicable_settings, run_maneuver, saturation_warning, with_sea)
    from .outputs import OutputError, check_output_file, os_error_line
    from .waves import SeaStateError

    try:
        s = maneuver_settings(a.name, depth=a.depth, depth_ref=a.depth_ref, heading_ref_deg=a.heading_ref_deg,
                              speed_mps=a.speed_mps, rps=a.rps, sea_state=a.sea_state, rudder_deg=a.rudder_deg,
                              amplitude_deg=a.amplitude_deg, check_deg=a.check_deg, sail_planes=a.sail_planes,
                              planes_deg=a.planes_deg, duration=a.duration, profile=a.profile,
                              substeps=a.substeps)
        unread = inapplicable_settings(s, [k for k in ("rudder_deg", "amplitude_deg", "check_deg", "planes_deg",
                                                       "sail_planes", "heading_ref_deg", "depth_ref")
                                           if getattr(a, k, None) is not None])
        if unread:
            opts = ", ".join("--" + k.replace("_", "-") for k in unread)
            raise ManeuverError(f"{opts} do{'es' if len(unread) == 1 else ''} not apply to maneuver {s.name} "
                                f"({channels(s)}): it would fly without {'it' if len(unread) == 1 else 'them'}")
        s = with_sea(s, sea_block_from_args(a, a.sea_state), current_block_from_args(a), a.sea_state)
        model = build_model(s, a.hull_mesh)
        check_initial_depth(s, model)
        if a.plot:
            from .plots import plot_format

            plot_format(a.plot)  # a format matplotlib writes, said before the run
    except (ManeuverError, SeaStateError, HullMeshError, ValueError) as e:
        print(f"bb2-sim: error: {e}", file=sys.stderr)
        return 2
    writer = None
    try:  # before the run: no silent overwrite, and a folder that does not take data fails now
        for f, what in ((a.out, "--out"), (a.plot, "--plot")):
            if f:
                check_output_file(f, overwrite=getattr(a, "overwrite", False), what=what)
        if a.out:
            writer = CsvWriter(a.out)
    except OSError as e:
        print(f"bb2-sim: error: {os_error_line(e, a.out)}", file=sys.stderr)
        return 2
    print(f"maneuver {s.name}: {s.doc}")
    from .step_stability import speed_warning

    warnings = (speed_warning(s.expected_speed_mps(), s.substeps, "--substeps", f"maneuver {s.name}"),
                saturation_warning(s, float(model.params.act["plane_limit_deg"])),
                s.environment.sea.steepness_warning(model.params.g) if s.environment is not None else "")
    for warning in filter(None, warnings):
        print(f"bb2-sim: warning: {warning}", file=sys.stderr)
    print(f"  hull: {model.surfaces.source} ({model.surfaces.n_triangles()} triangles, V = {model.volume:.3f} m^3"
          f"{', weight trimmed to buoyancy' if model.trimmed else ''}); profile {model.profile.name}; "
          + (f"sea state {model.wave.sea_state}" if s.environment is None else s.environment.summary()))
    try:
        res = run_maneuver(s, model, on_row=writer.write if writer else None,
                           progress=_progress(not a.quiet and sys.stderr.isatty(), s.duration))
    finally:
        if writer:
            writer.close()
    if not a.quiet and sys.stderr.isatty():
        sys.stderr.write("\n")
    sim_t = res.traj["t_s"][-1] if len(res.traj["t_s"]) else 0.0
    print(f"  simulated {sim_t:.1f} s in {res.wall_time_s:.2f} s wall "
          f"({sim_t / max(res.wall_time_s, 1e-9):.0f}x real time)")
    if res.error is not None:
        print(f"bb2-sim: {res.error}; the CSV keeps every row up to t = {sim_t:.2f} s"
              + (f" ({a.out})" if a.out else ""), file=sys.stderr)
        if hint := res.divergence_hint("--substeps"):
            print(f"bb2-sim: {hint}", file=sys.stderr)
    try:
        from .metrics import figures_for
        fig = figures_for(s.name, res.traj, **asdict(s))
    except Exception as e:  # figures of a truncated run may not exist
        fig = None
        print(f"  (no maneuver figures: {e})")
    if fig is not None:
        print("  figures:")
        for name, value, unit in fig.as_rows():
            print(f"    {name:<40s} {_fmt(value):>14} {unit}")
        unreached = fig.unreached()
        if unreached:
            print(f"  nan: not reached in this {sim_t:.1f} s run: {', '.join(unreached)}"
                  + _longer_hint(s, sim_t, res.error is None))
    if a.out:
        print(f"  trajectory: {a.out}")
    if a.plot and len(res.traj["t_s"]) > 1:
        from .plots import plot_maneuver
        try:
            plot_maneuver(s.name, res.traj, a.plot, figures=fig, settings=asdict(s))
        except (OSError, OutputError) as e:
            print(f"bb2-sim: error: {os_error_line(e, a.plot)}", file=sys.stderr)
            return 2
        except ValueError as e:  # no figures for a truncated run: the plot needs them
            print(f"  (no plot: {e})")
            return 1 if res.error is not None else 0
        print(f"  plot: {a.plot}")
    return 1 if res.error is not None else 0


def _longer_hint(s, sim_t: float, completed: bool) -> str:
    """For a completed maneuver run shorter than its catalogue duration: the duration that reaches its figures."""
    from .maneuvers import maneuver_settings

    default = maneuver_settings(s.name).duration
    if not completed or sim_t >= default:
        return ""
    return f" (--duration {sim_t:g} is shorter than maneuver {s.name}'s own {default:g} s)"


WELCH_TP_SEGMENT_PERIODS = 10.0
"""How many peak periods a Welch segment must span for the record's Tp to be said without a caveat: the spectrum's
bins are 1/segment apart, so its peak period is resolved to about Tp / segment (10 %: ten periods)."""


def _spectrum_peak_period(eta, dt: float) -> tuple[float, float]:
    """Tp of a record: the period of the peak of its Welch spectrum (Hann, 50 % overlap, >= 8 segments), and the
    length of its segments (s), which bounds how finely that peak is resolved."""
    import numpy as np
    from scipy.signal import welch

    n = len(eta)
    nper = min(int(2 ** max(4, math.floor(math.log2(max(n // 4, 16))))), n)
    f, S = welch(np.asarray(eta) - np.mean(eta), fs=1.0 / dt, nperseg=nper)
    k = int(np.argmax(S[1:])) + 1
    return (1.0 / f[k] if f[k] > 0 else math.inf), nper * dt


def _welch_caveat(tp_s: float, segment_s: float, duration_s: float) -> str:
    """'' or why a record's Welch Tp is coarse: its segments hold fewer than ``WELCH_TP_SEGMENT_PERIODS`` peak
    periods ``tp_s`` (the sea's own, the best known)."""
    if not (math.isfinite(tp_s) and math.isfinite(segment_s)) or segment_s >= WELCH_TP_SEGMENT_PERIODS * tp_s:
        return ""
    need = duration_s * WELCH_TP_SEGMENT_PERIODS * tp_s / segment_s
    return (f"; coarse: its segments of {segment_s:.3g} s hold {segment_s / tp_s:.2g} peak periods of "
            f"{tp_s:.3g} s, a record of about {math.ceil(need / 10) * 10:.0f} s resolves Tp to 10 %")


ALIASED_ENERGY_FRACTION = 0.01
"""The share of a sea's energy above the record's Nyquist frequency (periods under 2 dt) that ``bb2-sim sea`` warns of:
it folds onto longer periods in the record (its Hs holds, its spectrum and Welch Tp do not)."""


def aliasing_warning(comps, dt_s: float) -> str:
    """'' or why a record every ``dt_s`` misrepresents the sea: more than :data:`ALIASED_ENERGY_FRACTION` of its
    components' energy is at periods under ``2 dt_s`` (at a fixed point the elevation oscillates at omega)."""
    import numpy as np

    if comps is None or not len(comps):
        return ""
    w, e = np.asarray(comps.omega, dtype=float), np.asarray(comps.amplitude, dtype=float) ** 2
    if e.sum() <= 0:
        return ""
    above = float(e[w > math.pi / dt_s].sum() / e.sum())
    if above <= ALIASED_ENERGY_FRACTION:
        return ""
    tp = components_peak_period(comps)
    return (f"--dt {dt_s:g} s samples {above:.0%} of the sea's energy (periods under {2 * dt_s:.3g} s) below its "
            f"Nyquist rate: the record aliases it onto longer periods (its spectrum and Welch Tp are not the sea's); "
            f"take --dt <= {tp / 10:.3g} s (a tenth of Tp {tp:.3g} s)")


def components_peak_period(comps) -> float:
    """Tp of a component set: the peak of its energy a^2/2 spread over omega by a Gaussian kernel of three
    mean component spacings (one component: its period)."""
    import numpy as np

    w = np.asarray(comps.omega, dtype=float)
    e = np.asarray(comps.amplitude, dtype=float) ** 2 / 2.0
    u = np.unique(w)
    if len(u) == 1:
        return 2.0 * math.pi / float(u[0])
    sigma = 3.0 * (u[-1] - u[0]) / (len(u) - 1)
    grid = np.linspace(u[0], u[-1], 4001)
    S = np.exp(-0.5 * ((grid[:, None] - w[None, :]) / sigma) ** 2) @ e
    return 2.0 * math.pi / float(grid[int(np.argmax(S))])


SEA_SAMPLE_BYTES = 48  # a record's sample in memory: its time and elevation as float64, and the elevation's
# Python float on its way (peak measured with tracemalloc: 48.1 B a sample)


def run_sea_cli(a: argparse.Namespace) -> int:
    """``bb2-sim sea``: the elevation record t_s,eta_m of a sea at one earth point; prints its Hs and Tp."""
    import csv

    import numpy as np

    from .environment import Environment, sea_from_mapping
    from .outputs import check_output_file, os_error_line
    from .parameters import load_parameters
    from .waves import SeaStateError

    try:  # before the work: no silent overwrite, and a folder that does not take data fails now
        check_output_file(a.out, overwrite=a.overwrite, what="--out")
    except OSError as e:
        print(f"bb2-sim: error: {os_error_line(e, a.out)}", file=sys.stderr)
        return 2
    try:
        if a.duration <= 0:
            raise ValueError(f"duration must be > 0 s, got {a.duration:g}")
        if a.dt <= 0:
            raise ValueError(f"dt must be > 0 s, got {a.dt:g}")
        block = sea_block_from_args(a, a.sea_state)
        if block is None:
            block = {"sea_state": a.sea_state if a.sea_state is not None else 0}
        env = Environment(sea_from_mapping(block))
        params = load_parameters()
        sea = env.sea.build(params)
    except (SeaStateError, ValueError) as e:
        print(f"bb2-sim: error: {e}", file=sys.stderr)
        return 2
    if steep := env.sea.steepness_warning(params.g):
        print(f"bb2-sim: warning: {steep}", file=sys.stderr)
    if aliased := aliasing_warning(sea.components, a.dt):
        print(f"bb2-sim: warning: {aliased}", file=sys.stderr)
    n = int(math.floor(a.duration / a.dt + 1e-9)) + 1
    from .outputs import check_fits_in_memory

    check_fits_in_memory(n * SEA_SAMPLE_BYTES, f"a record of {n} samples ({a.duration:g} s every {a.dt:g} s)")
    t = np.arange(n) * a.dt
    x, y = a.at
    eta = np.array([float(sea.elevation(x, y, float(tk))) for tk in t])
    try:
        with open(a.out, "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(["t_s", "eta_m"])
            for tk, ek in zip(t, eta):
                w.writerow([f"{tk:.10g}", f"{ek:.12g}"])
    except OSError as e:
        print(f"bb2-sim: error: cannot write {a.out}: {e.strerror or e}", file=sys.stderr)
        return 2
    comps = sea.components
    m0 = 0.0 if comps is None else float(np.sum(comps.amplitude ** 2)) / 2.0
    hs_rec = 4.0 * float(np.std(eta))
    print(f"sea: {env.sea.summary()}")
    hs_t, tp_t = env.sea.effective_hs_tp
    if env.sea.spectrum == "pm" and hs_t:
        from .sea import spectrum
        tp_t = spectrum("pm", hs=hs_t, g=params.g).tp
    if hs_t is not None or tp_t is not None:
        print("  target:      " + (f"Hs = {hs_t:.4g} m" if hs_t is not None else "")
              + (f", Tp = {tp_t:.4g} s" if tp_t is not None else ""))
    n_c = 0 if comps is None else len(comps)
    print(f"  realisation: Hs = {4.0 * math.sqrt(m0):.4g} m (4 sqrt(m0) of its {n_c} components; "
          f"of the record: {hs_rec:.4g} m)")
    tp_rec, segment_s = _spectrum_peak_period(eta, a.dt) if hs_rec > 0 and n > 32 else (math.nan, math.nan)
    tp = components_peak_period(comps) if comps is not None and m0 > 0 else math.nan
    caveat = _welch_caveat(tp if math.isfinite(tp) else tp_rec, segment_s, float(t[-1]))
    print(f"  realisation: Tp = {tp:.4g} s (peak of its components' energy over omega; "
          f"of the record's Welch spectrum: {tp_rec:.4g} s{caveat})")
    print(f"  record: {a.out} ({n} samples, t = 0..{t[-1]:g} s every {a.dt:g} s at x, y = {x:g}, {y:g} m)")
    return 0


def main(argv: list[str] | None = None) -> int:
    """``python -m bb2_sim maneuver|sea ...`` (the ROM alone); ``bb2-sim`` is :func:`bb2_tools.sim_cli.main`."""
    from .outputs import run_cli

    args = build_parser().parse_args(argv)
    if args.command == "sea":
        return run_cli("bb2-sim", lambda: run_sea_cli(args))
    return run_cli("bb2-sim", lambda: run_maneuver_cli(args))


if __name__ == "__main__":
    sys.exit(main())
