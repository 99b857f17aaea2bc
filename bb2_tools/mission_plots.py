"""Figures of a closed-loop mission, as in the paper's path-following example (matplotlib, Agg canvas).

Inputs are the mission CSV columns (:data:`bb2_mission.MISSION_COLUMNS`) as arrays, the path in the
native frame and, optionally, the terrain.  Positions are plotted in the native earth frame (x, y
horizontal, z up, metres); depth is -z.  Figures (one PNG each, see :func:`plot_mission`):

* ``track_3d.png``     path vs track in 3-D, with the terrain surface;
* ``plan_view.png``    path vs track seen from above, over terrain contours;
* ``path_errors.png``  vertical and horizontal path errors vs time (and ground clearance with terrain);
* ``commands.png``     deltaV / deltaH commands and the five plane angles;
* ``speed_depth_fpa.png``  speed, depth (with the desired depth and the sea floor) and flight-path angle.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any, Mapping

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

__all__ = ["plot_mission", "FIGURES"]

FIGURES = ("track_3d", "plan_view", "path_errors", "commands", "speed_depth_fpa")
PATH_STYLE = dict(color="tab:red", linestyle="--", linewidth=1.4, label="path")
TRACK_STYLE = dict(color="tab:blue", linewidth=1.4, label="track (CG)")


def _save(fig: Figure, file: Path) -> Path:
    FigureCanvasAgg(fig)
    fig.savefig(file, dpi=120)
    return file


def _terrain_window(terrain: Any, xs: np.ndarray, ys: np.ndarray, pad: float = 250.0
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    x0, x1 = np.nanmin(xs) - pad, np.nanmax(xs) + pad
    y0, y1 = np.nanmin(ys) - pad, np.nanmax(ys) + pad
    ix = (terrain.x >= x0) & (terrain.x <= x1)
    iy = (terrain.y >= y0) & (terrain.y <= y1)
    return terrain.x[ix], terrain.y[iy], terrain.z[np.ix_(ix, iy)]


def _title(fig: Figure, title: str) -> None:
    if title:
        fig.suptitle(title, fontsize=11)


def plot_track_3d(traj: Mapping[str, np.ndarray], path_xyz: np.ndarray, file: Path, terrain: Any = None,
                  title: str = "") -> Path:
    fig = Figure(figsize=(8.5, 6.5))
    ax = fig.add_subplot(111, projection="3d")
    x, y, z = traj["x_m"], traj["y_m"], traj["z_m"]
    if terrain is not None:
        tx, ty, tz = _terrain_window(terrain, np.r_[x, path_xyz[:, 0]], np.r_[y, path_xyz[:, 1]])
        step = max(1, int(max(len(tx), len(ty)) / 60))
        X, Y = np.meshgrid(tx[::step], ty[::step], indexing="ij")
        ax.plot_surface(X, Y, tz[::step, ::step], cmap="terrain", alpha=0.45, linewidth=0, antialiased=False)
    ax.plot(path_xyz[:, 0], path_xyz[:, 1], path_xyz[:, 2], **PATH_STYLE)
    ax.plot(x, y, z, **TRACK_STYLE)
    ax.scatter([x[0]], [y[0]], [z[0]], color="k", s=18, label="start")
    ax.set_xlabel("x native [m]")
    ax.set_ylabel("y native [m]")
    ax.set_zlabel("z (up) [m]")
    ax.legend(loc="upper left", fontsize=8)
    _title(fig, title or "path vs track (3-D)")
    fig.tight_layout()
    return _save(fig, file)


def plot_plan_view(traj: Mapping[str, np.ndarray], path_xyz: np.ndarray, file: Path, terrain: Any = None,
                   title: str = "") -> Path:
    fig = Figure(figsize=(8.0, 7.0))
    ax = fig.add_subplot(111)
    x, y = traj["x_m"], traj["y_m"]
    if terrain is not None:
        tx, ty, tz = _terrain_window(terrain, np.r_[x, path_xyz[:, 0]], np.r_[y, path_xyz[:, 1]])
        cs = ax.contourf(tx, ty, tz.T, levels=20, cmap="terrain", alpha=0.55)
        ax.contour(tx, ty, tz.T, levels=20, colors="0.35", linewidths=0.4)
        fig.colorbar(cs, ax=ax, label="sea floor z [m]", shrink=0.8)
    ax.plot(path_xyz[:, 0], path_xyz[:, 1], **PATH_STYLE)
    ax.plot(x, y, **TRACK_STYLE)
    ax.plot([x[0]], [y[0]], "ko", ms=4, label="start")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x native [m]")
    ax.set_ylabel("y native [m]")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best", fontsize=8)
    _title(fig, title or "plan view")
    fig.tight_layout()
    return _save(fig, file)


def plot_path_errors(traj: Mapping[str, np.ndarray], file: Path, title: str = "",
                     compare: Mapping[str, np.ndarray] | None = None, compare_label: str = "",
                     label: str = "this run") -> Path:
    t = traj["t_s"]
    has_cl = bool(np.isfinite(traj["clearance_m"]).any())
    fig = Figure(figsize=(8.5, 7.5 if has_cl else 5.5))
    axs = fig.subplots(3 if has_cl else 2, 1, sharex=True)
    for ax, col, lab in ((axs[0], "e_vertical_m", "vertical error [m]\n(> 0 above)"),
                         (axs[1], "e_horizontal_m", "horizontal error [m]\n(> 0 left)")):
        ax.plot(t, traj[col], color="tab:blue", lw=1.2, label=label)
        if compare is not None:
            ax.plot(compare["t_s"], compare[col], color="0.45", ls="--", lw=1.1, label=compare_label)
            ax.legend(fontsize=8)
        ax.axhline(0, color="k", lw=0.5)
        ax.set_ylabel(lab)
        ax.grid(True, alpha=0.3)
    if has_cl:
        axs[2].plot(t, traj["clearance_m"], color="tab:brown", lw=1.2, label="CG")
        axs[2].plot(t, traj["hull_clearance_m"], color="tab:orange", lw=1.0, label="lowest hull point")
        axs[2].set_ylabel("ground clearance [m]")
        axs[2].legend(fontsize=8)
        axs[2].grid(True, alpha=0.3)
    axs[-1].set_xlabel("t [s]")
    _title(fig, title or "path-following errors")
    fig.tight_layout()
    return _save(fig, file)


def plot_commands(traj: Mapping[str, np.ndarray], file: Path, title: str = "") -> Path:
    t = traj["t_s"]
    fig = Figure(figsize=(8.5, 6.5))
    ax1, ax2 = fig.subplots(2, 1, sharex=True)
    ax1.plot(t, traj["dV_deg"], lw=1.2, label=r"$\delta_V$ (> 0 bow up)")
    ax1.plot(t, traj["dH_deg"], lw=1.2, label=r"$\delta_H$ (> 0 bow to port)")
    ax1.set_ylabel("command [deg]")
    ax1.legend(fontsize=8)
    ax1.grid(True, alpha=0.3)
    for i in range(1, 6):
        ax2.plot(t, traj[f"d{i}_deg"], lw=1.0, label=rf"$\delta_{i}$")
    ax2.set_ylabel("plane angle [deg]")
    ax2.set_xlabel("t [s]")
    ax2.legend(fontsize=8, ncol=5)
    ax2.grid(True, alpha=0.3)
    _title(fig, title or r"$\delta_V$ / $\delta_H$ and plane angles")
    fig.tight_layout()
    return _save(fig, file)


def plot_speed_depth_fpa(traj: Mapping[str, np.ndarray], file: Path, title: str = "") -> Path:
    t = traj["t_s"]
    fig = Figure(figsize=(8.5, 8.0))
    ax1, ax2, ax3 = fig.subplots(3, 1, sharex=True)
    ax1.plot(t, traj["U_m_s"], lw=1.2)
    ax1.set_ylabel("speed U [m/s]")
    ax2.plot(t, -traj["z_m"], lw=1.2, label="CG depth")
    ax2.plot(t, -traj["zd_m"], color="tab:red", ls="--", lw=1.1, label="desired depth")
    if np.isfinite(traj["terrain_z_m"]).any():
        ax2.plot(t, -traj["terrain_z_m"], color="tab:brown", lw=1.0, label="sea floor under the CG")
    ax2.invert_yaxis()
    ax2.set_ylabel("depth [m]")
    ax2.legend(fontsize=8)
    ax3.plot(t, traj["flight_path_angle_deg"], lw=1.2, label=r"flight-path angle $\gamma$")
    ax3.plot(t, traj["theta_deg"], lw=1.0, ls=":", label=r"pitch $\theta$")
    ax3.set_ylabel("angle [deg] (> 0 up)")
    ax3.set_xlabel("t [s]")
    ax3.legend(fontsize=8)
    for ax in (ax1, ax2, ax3):
        ax.grid(True, alpha=0.3)
    _title(fig, title or "speed, depth and flight-path angle")
    fig.tight_layout()
    return _save(fig, file)


def plot_mission(traj: Mapping[str, np.ndarray], path_native: Any, out_dir: str | Path, *, terrain: Any = None,
                 title: str = "", compare: Mapping[str, np.ndarray] | None = None, compare_label: str = "",
                 label: str = "this run") -> dict[str, Path]:
    """Write the mission figures (:data:`FIGURES`) as PNGs into ``out_dir``; returns name -> file.

    ``path_native`` is a BernsteinPath in the native frame (sampled densely); ``compare`` an optional
    second trajectory (e.g. the run without adaptation) overlaid on the error plot.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    if len(traj["t_s"]) < 2:
        raise ValueError("the mission trajectory has fewer than two samples; nothing to plot")
    _, pxyz = path_native.sample(2001)
    pre = f"{title}: " if title else ""
    return {
        "track_3d": plot_track_3d(traj, pxyz, out / "track_3d.png", terrain, pre + "path vs track (3-D)"),
        "plan_view": plot_plan_view(traj, pxyz, out / "plan_view.png", terrain, pre + "plan view"),
        "path_errors": plot_path_errors(traj, out / "path_errors.png", pre + "path-following errors",
                                        compare, compare_label, label),
        "commands": plot_commands(traj, out / "commands.png", pre + r"$\delta_V$ / $\delta_H$ and plane angles"),
        "speed_depth_fpa": plot_speed_depth_fpa(traj, out / "speed_depth_fpa.png",
                                                pre + "speed, depth and flight-path angle"),
    }
