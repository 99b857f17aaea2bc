"""Maneuver plots for a naval architect: turning-circle plan view, zig-zag histories, straight-run histories.

Input trajectories are dicts of the maneuver-CSV columns (see :mod:`bb2_sim.metrics`); angles in the CSV
are degrees and are plotted in degrees.  Plots use matplotlib's object API with the Agg canvas (no pyplot,
so importing this module never changes the global backend).  An optional reference trajectory (e.g. one of
the authors' runs) is overlaid dashed in grey.

Plan view of a turn: the CG track relative to its start, in axes aligned with the *initial* heading
(vertical: along the approach course, "advance"; horizontal: across it, positive to the initial
starboard side), divided by L.  For psi0 = 0 these are -x_E/L and y_E/L.
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import Any, Mapping

import numpy as np
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from bb2_sim import metrics
from bb2_sim.metrics import Figures, Trajectory, TrajectoryError

__all__ = ["plot_maneuver", "maneuver_figure", "track_in_approach_axes"]

REF_STYLE = dict(color="0.45", linestyle="--", linewidth=1.1)
PLANE_COLORS = ("tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple")


# ------------------------------------------------------------------------------------------- helpers
def track_in_approach_axes(traj: Trajectory) -> tuple[np.ndarray, np.ndarray]:
    """CG track (m) relative to its start: (across the initial heading, + to initial starboard;
    along the initial heading, + ahead)."""
    x = np.asarray(traj["x_m"], float) - float(traj["x_m"][0])
    y = np.asarray(traj["y_m"], float) - float(traj["y_m"][0])
    psi0 = math.radians(float(traj["psi_deg"][0]))
    c, s = math.cos(psi0), math.sin(psi0)
    return -s * x + c * y, -c * x - s * y


def _col(traj: Trajectory, name: str) -> np.ndarray:
    if name not in traj:
        raise TrajectoryError(f"trajectory lacks column {name}")
    return np.asarray(traj[name], float)


def _line(ax: Axes, traj: Trajectory, col: str, label: str | None = None, scale: float = 1.0,
          ref: Trajectory | None = None, **kw: Any) -> None:
    if col in traj:
        ax.plot(_col(traj, "t_s"), scale * _col(traj, col), label=label, **kw)
    if ref is not None and col in ref:
        ax.plot(_col(ref, "t_s"), scale * _col(ref, col), **REF_STYLE)


def _depth(ax: Axes, traj: Trajectory, ref: Trajectory | None) -> None:
    _line(ax, traj, "z_m", "depth", scale=-1.0, ref=ref, color="tab:blue")
    ax.set_ylabel("depth −z [m]")
    ax.invert_yaxis()


def _speed(ax: Axes, traj: Trajectory, ref: Trajectory | None) -> None:
    _line(ax, traj, "U_m_s", "U", ref=ref, color="tab:blue")
    _line(ax, traj, "u_m_s", "−u (ahead)", scale=-1.0, ref=None, color="tab:cyan", linewidth=0.9)
    ax.set_ylabel("speed [m/s]")
    ax.legend(loc="best", fontsize=7)


def _attitude(ax: Axes, traj: Trajectory, ref: Trajectory | None, cols=("phi_deg", "theta_deg")) -> None:
    names = {"phi_deg": ("φ roll", "tab:red"), "theta_deg": ("θ pitch", "tab:green"),
             "psi_deg": ("ψ heading", "tab:blue")}
    for c in cols:
        _line(ax, traj, c, names[c][0], ref=ref, color=names[c][1])
    ax.set_ylabel("angle [deg]")
    ax.legend(loc="best", fontsize=7)


def _planes(ax: Axes, traj: Trajectory, ref: Trajectory | None) -> None:
    for c, color in zip(metrics.PLANE_COLUMNS, PLANE_COLORS):
        _line(ax, traj, c, c.removesuffix("_deg"), ref=ref, color=color, linewidth=1.0)
    ax.set_ylabel("planes [deg]")
    ax.margins(y=0.25)
    ax.legend(loc="upper center", fontsize=6.5, ncol=5, framealpha=0.8, handlelength=1.2, columnspacing=0.8)


def _propulsion(ax: Axes, traj: Trajectory, ref: Trajectory | None) -> None:
    _line(ax, traj, "n_rps", "n", ref=ref, color="tab:brown")
    ax.set_ylabel("n [1/s]", color="tab:brown")
    if "thrust_N" in traj:
        ax2 = ax.twinx()
        _line(ax2, traj, "thrust_N", "thrust", scale=1e-3, ref=ref, color="tab:olive")
        _line(ax2, traj, "thrust_net_N", "net thrust", scale=1e-3, color="k", linewidth=0.8)
        ax2.set_ylabel("thrust [kN]")
        ax2.legend(loc="lower right", fontsize=7)


def _summary_lines(figs: Figures | None, names: tuple[str, ...], one_line: bool = False) -> str:
    if figs is None:
        return ""
    lines = []
    for n in names:
        try:
            label, value, unit = figs.row(n)
        except KeyError:
            continue
        sep = " " if one_line else "\n    "
        lines.append(f"{label}:{sep}{metrics.format_value(value)} {unit}")
    return "\n".join(lines)


def _summary(target: Axes | Figure, figs: Figures | None, names: tuple[str, ...],
             loc: tuple[float, float] = (0.02, 0.98), va: str = "top", ha: str = "left",
             one_line: bool = False) -> None:
    """Key figures as a boxed text block (in axes or figure coordinates)."""
    text = _summary_lines(figs, names, one_line)
    if not text:
        return
    transform = target.transAxes if isinstance(target, Axes) else target.transFigure
    target.text(*loc, text, transform=transform, va=va, ha=ha, fontsize=7, family="monospace",
                bbox=dict(boxstyle="round", facecolor="white", alpha=0.9, edgecolor="0.7"))


def _finish_time_axes(axes: list[Axes], traj: Trajectory) -> None:
    t = _col(traj, "t_s")
    for ax in axes:
        ax.grid(True, alpha=0.3)
        ax.set_xlim(float(t[0]), float(t[-1]))
    axes[-1].set_xlabel("t [s]")


# ---------------------------------------------------------------------------------- turning circle
def _turning_circle(fig: Figure, traj: Trajectory, figs: metrics.TurningCircleFigures | None,
                    ref: Trajectory | None) -> None:
    L = figs.length_m if figs is not None else metrics.load_parameters().L
    gs = fig.add_gridspec(5, 2, width_ratios=(1.15, 1.0), hspace=0.12, wspace=0.28)
    ax = fig.add_subplot(gs[:4, 0])
    ax.set_gid("plan")
    box = fig.add_subplot(gs[4, 0])
    box.set_axis_off()
    box.set_gid("summary")
    across, along = track_in_approach_axes(traj)
    ax.plot(across / L, along / L, color="tab:blue", linewidth=1.4, label="CG track")
    if ref is not None:
        ra, rl = track_in_approach_axes(ref)
        ax.plot(ra / L, rl / L, label="reference", **REF_STYLE)
    ax.plot([0], [0], marker="o", color="k")
    if figs is not None:
        side = 1.0 if figs.turn_direction == "starboard" else -1.0
        if np.isfinite(figs.advance_90_m):
            a, tr = figs.advance_90_m / L, side * figs.transfer_90_m / L
            ax.plot([tr], [a], marker="s", color="tab:red")
            ax.annotate("", xy=(0, a), xytext=(0, 0), arrowprops=dict(arrowstyle="<->", color="tab:red"))
            ax.annotate(f"advance\n{figs.advance_90_m:.1f} m\n({a:.2f} L)", (0, a / 2), xytext=(-6 * side, 0),
                        textcoords="offset points", color="tab:red", fontsize=8,
                        ha="right" if side > 0 else "left", va="center")
            ax.annotate("", xy=(tr, a), xytext=(0, a), arrowprops=dict(arrowstyle="<->", color="tab:orange"))
            ax.text(tr / 2, a, f"transfer {figs.transfer_90_m:.1f} m ({abs(tr):.2f} L)", color="tab:orange",
                    fontsize=8, ha="center", va="bottom")
        if np.isfinite(figs.tactical_diameter_m):
            td, a180 = side * figs.tactical_diameter_m / L, figs.advance_180_m / L
            ax.plot([td], [a180], marker="s", color="tab:green")
            ax.annotate("", xy=(td, a180), xytext=(0, a180),
                        arrowprops=dict(arrowstyle="<->", color="tab:green"))
            ax.text(td / 2, a180, f"tactical diameter {figs.tactical_diameter_m:.1f} m ({abs(td):.2f} L)",
                    color="tab:green", fontsize=8, ha="center", va="top")
        names = ("steady_radius_m", "steady_diameter_m", "circle_fit_max_residual_m", "time_90_s",
                 "time_180_s", "time_360_s", "steady_yaw_rate_rad_s", "u_over_r_m", "steady_speed_m_s",
                 "speed_ratio", "drift_angle_rad", "steady_roll_rad", "peak_roll_rad", "steady_pitch_rad",
                 "z_change_m", "steady_thrust_N")
        half = (len(names) + 1) // 2
        _summary(box, figs, names[:half], loc=(0.0, 0.7), one_line=True)
        _summary(box, figs, names[half:], loc=(0.52, 0.7), one_line=True)
    ax.margins(0.12)
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("across initial heading / L  (+ = initial starboard)")
    ax.set_ylabel("along initial heading / L  (advance)")
    ax.set_title(f"Turning circle ({figs.turn_direction if figs else 'turn'}), plan view of the CG")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="lower right" if (figs is None or figs.turn_direction == "starboard") else "lower left",
              fontsize=8)

    axes = [fig.add_subplot(gs[0, 1])]
    axes += [fig.add_subplot(gs[i, 1], sharex=axes[0]) for i in range(1, 5)]
    _line(axes[0], traj, "psi_deg", "ψ", ref=ref, color="tab:blue")
    axes[0].set_ylabel("ψ [deg]")
    _line(axes[1], traj, "r_deg_s", "r", ref=ref, color="tab:purple")
    axes[1].set_ylabel("r [deg/s]")
    _speed(axes[2], traj, ref)
    _attitude(axes[3], traj, ref)
    _depth(axes[4], traj, ref)
    for a in axes[:-1]:
        a.tick_params(labelbottom=False)
    _finish_time_axes(axes, traj)


# -------------------------------------------------------------------------------------------- zig-zags
def _zigzag(fig: Figure, name: str, traj: Trajectory, figs: metrics.ZigzagFigures | None,
            ref: Trajectory | None) -> None:
    vertical = name == "vzz"
    angle_col = "theta_deg" if vertical else "psi_deg"
    gs = fig.add_gridspec(5, 1, height_ratios=(2.2, 1, 1, 1, 1), hspace=0.1)
    axes = [fig.add_subplot(gs[0])]
    axes += [fig.add_subplot(gs[i], sharex=axes[0]) for i in range(1, 5)]
    ax = axes[0]
    ax.set_gid("zigzag")
    t = _col(traj, "t_s")
    a = _col(traj, angle_col)
    sym, plane = ("θ", "stern planes δv") if vertical else ("ψ", "rudder δh")
    ax.plot(t, a - a[0], color="tab:blue", linewidth=1.4, label=f"{sym} − {sym}0")
    if all(c in traj for c in metrics.PLANE_COLUMNS[:4]):
        dv, dh = metrics.imposed_channels_deg(traj, commanded=False)
        ax.plot(t, dv if vertical else dh, color="tab:red", linewidth=1.1, label=f"{plane} (applied)")
    if ref is not None and angle_col in ref:
        ra = _col(ref, angle_col)
        ax.plot(_col(ref, "t_s"), ra - ra[0], label="reference", **REF_STYLE)
    if figs is not None:
        c = math.degrees(figs.check_rad)
        for lvl in (c, -c):
            ax.axhline(lvl, color="0.5", linewidth=0.7, linestyle=":")
        for tr in figs.reversal_times_s:
            ax.axvline(tr, color="0.8", linewidth=0.6)
        for tp, ap, os in zip(figs.peak_times_s, figs.peak_angles_rad, figs.overshoots_rad):
            ap_d = math.degrees(ap)
            ax.plot([tp], [ap_d], marker="v" if ap_d > 0 else "^", color="k", markersize=5)
            ax.annotate(f"{math.degrees(os):.2f}°", (tp, ap_d), textcoords="offset points",
                        xytext=(0, 6 if ap_d > 0 else -12), ha="center", fontsize=7)
        _summary(fig, figs, ("time_to_first_check_s", "first_overshoot_rad", "second_overshoot_rad",
                             "later_overshoots_positive_rad", "later_overshoots_negative_rad",
                             "first_period_s", "settled_period_s", "min_speed_m_s", "z_range_m",
                             "theta_range_rad", "phi_range_rad", "saturated_planes"), loc=(0.81, 0.94))
        a_d = math.degrees(figs.amplitude_rad)
        ax.set_title(f"{'Vertical' if vertical else 'Horizontal'} zig-zag {a_d:g}/{c:g}", loc="left")
    ax.set_ylabel(f"{sym}, {plane.split()[-1]} [deg]")
    ax.margins(y=0.18)
    ax.legend(loc="lower right", bbox_to_anchor=(1.0, 1.0), fontsize=7, ncol=3, frameon=False)
    _planes(axes[1], traj, ref=None)
    _speed(axes[2], traj, ref)
    _depth(axes[3], traj, ref)
    _attitude(axes[4], traj, ref, cols=("phi_deg", "psi_deg") if vertical else ("phi_deg", "theta_deg"))
    for x in axes[:-1]:
        x.tick_params(labelbottom=False)
    _finish_time_axes(axes, traj)


# ---------------------------------------------------------------------------------- straight runs
def _straight(fig: Figure, name: str, traj: Trajectory, figs: Figures | None, ref: Trajectory | None) -> None:
    gs = fig.add_gridspec(3, 2, hspace=0.12, wspace=0.25)
    axes = [fig.add_subplot(gs[0, 0])]
    axes += [fig.add_subplot(gs[i % 3, i // 3], sharex=axes[0]) for i in range(1, 6)]
    axes[0].set_gid("depth")
    _depth(axes[0], traj, ref)
    _speed(axes[1], traj, ref)
    _attitude(axes[2], traj, ref)
    _line(axes[3], traj, "psi_deg", "ψ", ref=ref, color="tab:blue")
    axes[3].set_ylabel("ψ [deg]")
    _planes(axes[4], traj, ref)
    _propulsion(axes[5], traj, ref)
    for i, x in enumerate(axes):
        if i % 3 != 2:
            x.tick_params(labelbottom=False)
    _finish_time_axes(axes[:3], traj)
    _finish_time_axes(axes[3:], traj)
    if figs is not None:
        keys = {
            "self-propulsion": ("forward_speed_m_s", "advance_coefficient", "thrust_N", "net_thrust_N",
                                "z_m", "z_error_m", "pitch_rad", "speed_drift_m_s", "z_drift_m"),
            "depth-heading": ("z_ref_m", "final_z_m", "z_rise_time_s", "z_overshoot_m", "psi_ref_rad",
                              "final_psi_rad", "psi_rise_time_s", "psi_overshoot_rad"),
            "open-loop": ("final_forward_speed_m_s", "z_change_m", "dive_rate_m_s", "final_pitch_rad",
                          "final_roll_rad", "steady_yaw_rate_rad_s"),
        }.get(name, ())
        _summary(fig, figs, keys, loc=(0.81, 0.94))
    fig.suptitle({"self-propulsion": "Self-propulsion", "depth-heading": "Depth and heading change",
                  "open-loop": "Open loop (imposed planes)"}.get(name, name))


# ------------------------------------------------------------------------------------------- public
def _infer_settings(name: str, traj: Trajectory) -> dict[str, Any]:
    """Zig-zag amplitude from the imposed command when the caller did not give it."""
    if name in ("hzz", "vzz") and all(c in traj for c in metrics.CMD_COLUMNS[:4]):
        dv, dh = metrics.imposed_channels_deg(traj)
        amp = float(np.round(np.max(np.abs(dv if name == "vzz" else dh)), 3))
        return {"amplitude_deg": amp, "check_deg": amp}
    return {}


def maneuver_figure(name: str, traj: Trajectory, figures: Figures | None = None,
                    reference: Trajectory | None = None, settings: Mapping[str, Any] | None = None) -> Figure:
    """Build (but do not save) the figure of a maneuver; ``name`` as in :data:`metrics.MANEUVER_NAMES`.

    Without ``figures`` they are computed with :func:`metrics.figures_for` from ``settings`` (zig-zag
    amplitude inferred from the command columns if absent).
    """
    key = name.strip().lower().replace("_", "-")
    if key not in metrics.MANEUVER_NAMES:
        raise TrajectoryError(f"unknown maneuver {name!r}; known: {', '.join(metrics.MANEUVER_NAMES)}")
    if figures is None:
        s = {**_infer_settings(key, traj), **(settings or {})}
        figures = metrics.figures_for(key, traj, **s)
    fig = Figure(figsize=(15, 9.5) if key == "turning-circle" else (13, 10), layout=None)
    FigureCanvasAgg(fig)
    if key == "turning-circle":
        _turning_circle(fig, traj, figures, reference)   # type: ignore[arg-type]
    elif key in ("hzz", "vzz"):
        _zigzag(fig, key, traj, figures, reference)      # type: ignore[arg-type]
    else:
        _straight(fig, key, traj, figures, reference)
    if reference is not None:
        fig.text(0.99, 0.005, "dashed grey: reference run", ha="right", va="bottom", fontsize=8, color="0.35")
    fig.subplots_adjust(left=0.06, right=0.95 if key == "turning-circle" else 0.8, top=0.94, bottom=0.06)
    return fig


PLOT_FORMATS = ("png", "pdf", "svg", "eps", "ps")
"""The formats a plot file may have, named by its extension (none: PNG)."""


def plot_format(path: str | Path) -> str:
    """The format of a plot file from its extension (``x.pdf``: pdf; none: png); :class:`ValueError` for another
    (a PNG was written into ``x.pdf`` and ``x.svg``)."""
    suffix = Path(path).suffix.lower().lstrip(".")
    if not suffix:
        return "png"
    if suffix not in PLOT_FORMATS:
        raise ValueError(f"{path}: a plot is written as {', '.join(PLOT_FORMATS)} (by its extension), not {suffix!r}")
    return suffix


def plot_maneuver(name: str, traj: Trajectory, out_png: str | Path, figures: Figures | None = None,
                  reference: Trajectory | None = None, settings: Mapping[str, Any] | None = None,
                  dpi: int = 110) -> Path:
    """Draw the maneuver plot and write it in the format of its extension (:func:`plot_format`: PNG, PDF, SVG
    ...); returns the path written."""
    out = Path(out_png)
    fmt = plot_format(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig = maneuver_figure(name, traj, figures=figures, reference=reference, settings=settings)
    fig.savefig(out, dpi=dpi, format=fmt)
    return out
