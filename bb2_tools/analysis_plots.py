"""Paper-style figures of analysed bags (matplotlib, Agg canvas, one PNG each), one run or two overlaid.

Inputs are :class:`bb2_tools.analysis.Analysis` objects.  Positions are in the native earth frame
(x, y horizontal, z up, m); depth is -z; angles are plotted in degrees.  Figures (:data:`FIGURES`):

* ``track_3d``        path vs track(s) in 3-D;
* ``plan_view``       path vs track(s) from above (terrain contours when the mission's terrain is known);
* ``path_errors``     vertical and horizontal path errors vs time (stack's own, closest-point dashed),
                      and the ground clearance when known;
* ``commands``        deltaV / deltaH histories and the five actual plane angles;
* ``rate_commands``   the path-following rate commands q_c, r_c;
* ``speed_depth_fpa`` speed, depth and flight-path angle.

The first run is drawn in blue, the second in orange; the path is a red dashed line.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any, Sequence

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

__all__ = ["FIGURES", "plot_analyses", "flight_path_angle_rad"]

FIGURES = ("track_3d", "plan_view", "path_errors", "commands", "rate_commands", "speed_depth_fpa")
COLORS = ("tab:blue", "tab:orange")
PATH_STYLE = dict(color="tab:red", linestyle="--", linewidth=1.3, label="path")
RAD2DEG = 180.0 / np.pi


def flight_path_angle_rad(x: np.ndarray) -> np.ndarray:
    """Flight-path angle (rad, > 0 climbing) of native states (n, 12): elevation of the earth velocity."""
    from bb2_sim.frames import rotation_native

    v_e = np.array([rotation_native(xi[3], xi[4], xi[5]) @ xi[6:9] for xi in x])
    return np.arctan2(v_e[:, 2], np.hypot(v_e[:, 0], v_e[:, 1]))


def _save(fig: Figure, file: Path) -> Path:
    FigureCanvasAgg(fig)
    fig.savefig(file, dpi=110)
    return file


def _path_xyz(analyses: Sequence[Any]) -> np.ndarray | None:
    for a in analyses:
        if a.run.path is not None:
            return a.run.path.sample(2001)[1]
        if a.run.path_samples is not None:
            return a.run.path_samples
        if a.mission is not None:
            p = a.mission.path
            return (p.to_frame("native") if p.frame != "native" else p).sample(2001)[1]
    return None


def _terrain(analyses: Sequence[Any]) -> Any:
    for a in analyses:
        if a.mission is not None and getattr(a.mission, "terrain", None) is not None:
            return a.mission.terrain
    return None


def _title(fig: Figure, text: str, analyses: Sequence[Any]) -> None:
    if len(analyses) == 2:
        text += f"  ({analyses[0].label}  vs  {analyses[1].label})"
    else:
        text += f"  ({analyses[0].label})"
    fig.suptitle(text, fontsize=10)


def plot_track_3d(analyses: Sequence[Any], file: Path) -> Path:
    fig = Figure(figsize=(8.5, 6.5))
    ax = fig.add_subplot(111, projection="3d")
    pxyz = _path_xyz(analyses)
    if pxyz is not None:
        ax.plot(pxyz[:, 0], pxyz[:, 1], pxyz[:, 2], **PATH_STYLE)
    for a, c in zip(analyses, COLORS):
        x = a.run.x
        ax.plot(x[:, 0], x[:, 1], x[:, 2], color=c, lw=1.4, label=f"track {a.label}")
        ax.scatter([x[0, 0]], [x[0, 1]], [x[0, 2]], color=c, s=14)
    ax.set_xlabel("x native [m]")
    ax.set_ylabel("y native [m]")
    ax.set_zlabel("z (up) [m]")
    ax.legend(loc="upper left", fontsize=8)
    _title(fig, "path vs track (3-D)", analyses)
    fig.tight_layout()
    return _save(fig, file)


def plot_plan_view(analyses: Sequence[Any], file: Path) -> Path:
    fig = Figure(figsize=(8.0, 7.0))
    ax = fig.add_subplot(111)
    pxyz = _path_xyz(analyses)
    terrain = _terrain(analyses)
    xs = np.concatenate([a.run.x[:, 0] for a in analyses] + ([pxyz[:, 0]] if pxyz is not None else []))
    ys = np.concatenate([a.run.x[:, 1] for a in analyses] + ([pxyz[:, 1]] if pxyz is not None else []))
    if terrain is not None:
        pad = 250.0
        ix = (terrain.x >= xs.min() - pad) & (terrain.x <= xs.max() + pad)
        iy = (terrain.y >= ys.min() - pad) & (terrain.y <= ys.max() + pad)
        if ix.sum() > 1 and iy.sum() > 1:
            tz = terrain.z[np.ix_(ix, iy)]
            cs = ax.contourf(terrain.x[ix], terrain.y[iy], tz.T, levels=20, cmap="Greys_r", alpha=0.45)
            fig.colorbar(cs, ax=ax, label="sea floor z [m]", shrink=0.8)
    if pxyz is not None:
        ax.plot(pxyz[:, 0], pxyz[:, 1], **PATH_STYLE)
    for a, c in zip(analyses, COLORS):
        ax.plot(a.run.x[:, 0], a.run.x[:, 1], color=c, lw=1.4, label=f"track {a.label}")
        ax.plot([a.run.x[0, 0]], [a.run.x[0, 1]], "o", color=c, ms=4)
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x native [m]")
    ax.set_ylabel("y native [m]")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best", fontsize=8)
    _title(fig, "plan view", analyses)
    fig.tight_layout()
    return _save(fig, file)


def plot_path_errors(analyses: Sequence[Any], file: Path) -> Path:
    has_cl = any(np.isfinite(a.clearance).any() for a in analyses)
    fig = Figure(figsize=(8.5, 7.5 if has_cl else 5.8))
    axs = fig.subplots(3 if has_cl else 2, 1, sharex=True)
    for a, c in zip(analyses, COLORS):
        t = a.run.t[a.tick]
        for ax, stack, closest in ((axs[0], a.e_vertical, a.e_vertical_closest),
                                   (axs[1], a.e_horizontal, a.e_horizontal_closest)):
            if np.isfinite(stack).any():
                ax.plot(t, stack, color=c, lw=1.2, label=f"{a.label} (stack)")
            if np.isfinite(closest).any():
                ax.plot(t, closest, color=c, lw=0.9, ls="--", alpha=0.8, label=f"{a.label} (closest point)")
        if has_cl and np.isfinite(a.clearance).any():
            axs[2].plot(a.run.t, a.clearance, color=c, lw=1.2, label=f"{a.label} CG")
            if np.isfinite(a.hull_clearance).any():
                axs[2].plot(a.run.t, a.hull_clearance, color=c, lw=0.9, ls=":", label=f"{a.label} lowest hull point")
    axs[0].set_ylabel("vertical error [m]\n(> 0 above)")
    axs[1].set_ylabel("horizontal error [m]\n(> 0 left)")
    if has_cl:
        axs[2].set_ylabel("ground clearance [m]")
    for ax in axs:
        ax.axhline(0, color="k", lw=0.5)
        ax.grid(True, alpha=0.3)
        if ax.get_legend_handles_labels()[0]:
            ax.legend(fontsize=7)
    axs[-1].set_xlabel("t [s]")
    _title(fig, "path-following errors", analyses)
    fig.tight_layout()
    return _save(fig, file)


def plot_commands(analyses: Sequence[Any], file: Path) -> Path:
    fig = Figure(figsize=(8.5, 7.0))
    ax1, ax2, ax3 = fig.subplots(3, 1, sharex=True)
    for a, c in zip(analyses, COLORS):
        vh = a.run.vh_cmd
        if len(vh):
            ax1.plot(vh.t, vh.v[:, 0] * RAD2DEG, color=c, lw=1.2, label=a.label)
            ax2.plot(vh.t, vh.v[:, 1] * RAD2DEG, color=c, lw=1.2, label=a.label)
        pl = a.run.planes if len(a.run.planes) else a.run.planes_cmd
        for i in range(5):
            if len(pl):
                ax3.plot(pl.t, pl.v[:, i] * RAD2DEG, color=c, lw=0.9, alpha=1.0 - 0.13 * i,
                         label=rf"$\delta_{i + 1}$" if c == COLORS[0] else None)
    ax1.set_ylabel(r"$\delta_V$ [deg]" "\n(> 0 bow up)")
    ax2.set_ylabel(r"$\delta_H$ [deg]" "\n(> 0 bow to port)")
    ax3.set_ylabel("plane angles [deg]")
    ax3.set_xlabel("t [s]")
    for ax in (ax1, ax2, ax3):
        ax.grid(True, alpha=0.3)
        if ax.get_legend_handles_labels()[0]:
            ax.legend(fontsize=7, ncol=5 if ax is ax3 else 1)
    _title(fig, r"$\delta_V$ / $\delta_H$ commands and plane angles", analyses)
    fig.tight_layout()
    return _save(fig, file)


def plot_rate_commands(analyses: Sequence[Any], file: Path) -> Path:
    fig = Figure(figsize=(8.5, 5.0))
    ax1, ax2 = fig.subplots(2, 1, sharex=True)
    for a, c in zip(analyses, COLORS):
        rc = a.run.rate_cmd
        if len(rc):
            ax1.plot(rc.t, rc.v[:, 0] * RAD2DEG, color=c, lw=1.2, label=a.label)
            ax2.plot(rc.t, rc.v[:, 1] * RAD2DEG, color=c, lw=1.2, label=a.label)
    ax1.set_ylabel("$q_c$ [deg/s]\n(> 0 bow down)")
    ax2.set_ylabel("$r_c$ [deg/s]\n(> 0 bow to port)")
    ax2.set_xlabel("t [s]")
    for ax in (ax1, ax2):
        ax.grid(True, alpha=0.3)
        if ax.get_legend_handles_labels()[0]:
            ax.legend(fontsize=7)
    _title(fig, "path-following rate commands", analyses)
    fig.tight_layout()
    return _save(fig, file)


def plot_speed_depth_fpa(analyses: Sequence[Any], file: Path) -> Path:
    fig = Figure(figsize=(8.5, 8.0))
    ax1, ax2, ax3 = fig.subplots(3, 1, sharex=True)
    for a, c in zip(analyses, COLORS):
        t, x = a.run.t, a.run.x
        ax1.plot(t, np.linalg.norm(x[:, 6:9], axis=1), color=c, lw=1.2, label=a.label)
        ax2.plot(t, -x[:, 2], color=c, lw=1.2, label=f"{a.label} CG depth")
        if np.isfinite(a.terrain_z).any():
            ax2.plot(t, -a.terrain_z, color=c, lw=0.9, ls=":", label=f"{a.label} sea floor under the CG")
        ax3.plot(t, flight_path_angle_rad(x) * RAD2DEG, color=c, lw=1.2, label=rf"{a.label} $\gamma$")
        ax3.plot(t, x[:, 4] * RAD2DEG, color=c, lw=0.8, ls=":", label=rf"{a.label} pitch $\theta$")
    ax1.set_ylabel("speed U [m/s]")
    ax2.invert_yaxis()
    ax2.set_ylabel("depth [m]")
    ax3.set_ylabel("angle [deg] (> 0 up)")
    ax3.set_xlabel("t [s]")
    for ax in (ax1, ax2, ax3):
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7)
    _title(fig, "speed, depth and flight-path angle", analyses)
    fig.tight_layout()
    return _save(fig, file)


def plot_analyses(analyses: Sequence[Any], out_dir: str | Path) -> dict[str, Path]:
    """Write :data:`FIGURES` (and the maneuver plot of a maneuver run) into ``out_dir``; name -> PNG file."""
    if not 1 <= len(analyses) <= 2:
        raise ValueError(f"plot one or two analyses, got {len(analyses)}")
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    files = {
        "track_3d": plot_track_3d(analyses, out / "track_3d.png"),
        "plan_view": plot_plan_view(analyses, out / "plan_view.png"),
        "path_errors": plot_path_errors(analyses, out / "path_errors.png"),
        "commands": plot_commands(analyses, out / "commands.png"),
        "rate_commands": plot_rate_commands(analyses, out / "rate_commands.png"),
        "speed_depth_fpa": plot_speed_depth_fpa(analyses, out / "speed_depth_fpa.png"),
    }
    first = analyses[0]
    if first.maneuver_figures is not None and first.maneuver_traj is not None:
        from bb2_sim.plots import plot_maneuver

        ref = analyses[1].maneuver_traj if len(analyses) == 2 else None
        key = first.maneuver.strip().lower().replace("_", "-")
        files["maneuver"] = plot_maneuver(key, first.maneuver_traj, out / "maneuver.png",
                                          figures=first.maneuver_figures, reference=ref)
    return files
