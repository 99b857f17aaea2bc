"""Gridded bathymetry, a synthetic canyon, thalweg extraction and terrain-following Bernstein paths.

Frame: everything here is in the ROM's **native inertial frame** (x, y horizontal, **z up**, metres,
z = 0 at the calm surface), so the sea floor has negative elevation.

* :class:`Terrain` — elevation ``z(x, y)`` on a regular grid, bilinear interpolation (the interpolant of
  ``scipy.interpolate.RegularGridInterpolator``, linear, written out), ground clearance of points and paths; loaders for
  ``.npz`` (arrays ``x``, ``y``, ``z``) and ``.csv`` (``x,y,z`` rows covering a full grid).
* :func:`synthetic_canyon` — a documented, seeded stand-in for the paper's Scripps / La Jolla canyon
  (parameters in ``data/terrain/synthetic_canyon.yaml``).
* :func:`extract_thalweg` — the lowest line along a valley: a least-cost route on the grid (Dijkstra,
  cost rising steeply with elevation) as a guide, then the minimum of each cross-section, then smoothing.
* :func:`thalweg_path` — a Bernstein path fitted (least squares) through the thalweg at a clearance,
  checked against the terrain (:class:`PathBelowTerrainError`).

Clearance is **vertical**: ``clearance(p) = p_z - z_terrain(p_x, p_y)`` (the paper's "50 m between the
CG and the bottom").  It does not measure the horizontal distance to a canyon wall.
"""
from __future__ import annotations

import csv
import math
from bisect import bisect_right
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from bb2_planner.bernstein import BernsteinPath, fit_control_points
from bb2_sim.yaml_files import load as load_yaml

__all__ = ["TerrainError", "TerrainOutOfBoundsError", "PathBelowTerrainError", "Terrain",
           "SyntheticCanyon", "synthetic_canyon", "load_canyon_parameters", "Thalweg",
           "extract_thalweg", "thalweg_path", "canyon_path", "DATA_DIR"]

DATA_DIR = Path(__file__).resolve().parent / "data" / "terrain"


class TerrainError(ValueError):
    """Bad terrain data (shapes, axes, holes) or a bad terrain query."""


class TerrainOutOfBoundsError(TerrainError):
    """A query point lies outside the terrain grid."""


class PathBelowTerrainError(ValueError):
    """A path comes closer to the terrain than the required minimum clearance."""

    def __init__(self, message: str, t: float, clearance: float):
        super().__init__(message)
        self.t = t                  #: path time of the worst point [s]
        self.clearance = clearance  #: clearance there [m]


# ------------------------------------------------------------------------------------------ Terrain
class Terrain:
    """Sea-floor elevation on a regular grid (native frame, z up, metres).

    Parameters
    ----------
    x : (nx,) strictly monotonic grid coordinates [m] (decreasing axes are flipped).
    y : (ny,) strictly monotonic grid coordinates [m].
    z : (nx, ny) elevations [m], ``z[i, j]`` at ``(x[i], y[j])`` ("ij" indexing); no NaN.
    """

    def __init__(self, x: np.ndarray, y: np.ndarray, z: np.ndarray, name: str = "",
                 provenance: dict[str, Any] | None = None):
        x = np.asarray(x, dtype=float)
        y = np.asarray(y, dtype=float)
        z = np.asarray(z, dtype=float)
        for label, a in (("x", x), ("y", y)):
            if a.ndim != 1 or a.size < 2:
                raise TerrainError(f"{label} axis must be 1-D with at least 2 values, got shape {a.shape}")
            if not np.all(np.isfinite(a)):
                raise TerrainError(f"{label} axis has non-finite values")
        if z.shape != (x.size, y.size):
            raise TerrainError(f"z has shape {z.shape}, expected (len(x), len(y)) = ({x.size}, {y.size}) "
                               "with z[i, j] at (x[i], y[j])")
        for label, a, axis in (("x", x, 0), ("y", y, 1)):
            d = np.diff(a)
            if np.all(d < 0):
                a = a[::-1]
                z = np.flip(z, axis=axis)
            elif not np.all(d > 0):
                k = int(np.flatnonzero(d <= 0)[0]) if np.any(d > 0) else int(np.flatnonzero(d >= 0)[0])
                raise TerrainError(f"{label} axis is not strictly monotonic (at index {k}: "
                                   f"{a[k]} then {a[k + 1]})")
            if label == "x":
                x = a
            else:
                y = a
        holes = ~np.isfinite(z)
        if holes.any():
            i, j = np.argwhere(holes)[0]
            raise TerrainError(f"terrain has {int(holes.sum())} hole(s) (NaN/inf elevation), first at "
                               f"x = {x[i]:.3f} m, y = {y[j]:.3f} m")
        self.x, self.y, self.z = x, y, z
        self._lists: tuple | None = None      # x, y, z as lists, for one point at a time (built on first use)
        self.name = name
        self.provenance = dict(provenance or {})

    def __repr__(self) -> str:
        return (f"Terrain(name={self.name!r}, x=[{self.x[0]}, {self.x[-1]}] ({self.x.size}), "
                f"y=[{self.y[0]}, {self.y[-1]}] ({self.y.size}), z=[{self.z.min():.1f}, {self.z.max():.1f}] m)")

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        """(x_min, x_max, y_min, y_max) [m]."""
        return float(self.x[0]), float(self.x[-1]), float(self.y[0]), float(self.y[-1])

    def contains(self, xy: np.ndarray) -> np.ndarray:
        """True where the horizontal position(s) ``xy`` (..., >=2) lie on the grid."""
        xy = np.asarray(xy, dtype=float)
        x0, x1, y0, y1 = self.bounds
        return (xy[..., 0] >= x0) & (xy[..., 0] <= x1) & (xy[..., 1] >= y0) & (xy[..., 1] <= y1)

    def elevation_or_nan(self, x: np.ndarray | float, y: np.ndarray | float) -> np.ndarray:
        """Bilinear elevation z(x, y) [m], NaN off the grid: the interpolant of ``RegularGridInterpolator``
        (linear) written out element by element, without its per-call overhead (one point, as the simulator's
        altimeter asks every step: a clearance in ~8 us against ~35 us through scipy). A point's value does not
        depend on the other points asked with it."""
        gx, gy, gz = self.x, self.y, self.z
        x, y = np.broadcast_arrays(np.asarray(x, dtype=float), np.asarray(y, dtype=float))
        if x.ndim == 0:                       # one point: the same arithmetic on Python floats (bit for bit)
            return np.array(self._elevation_1(float(x), float(y)))
        inside = (x >= gx[0]) & (x <= gx[-1]) & (y >= gy[0]) & (y <= gy[-1])
        i = np.clip(np.searchsorted(gx, x, side="right") - 1, 0, gx.size - 2)
        j = np.clip(np.searchsorted(gy, y, side="right") - 1, 0, gy.size - 2)
        fx = (x - gx[i]) / (gx[i + 1] - gx[i])
        fy = (y - gy[j]) / (gy[j + 1] - gy[j])
        z = (gz[i, j] * (1 - fx) * (1 - fy) + gz[i + 1, j] * fx * (1 - fy) + gz[i, j + 1] * (1 - fx) * fy
             + gz[i + 1, j + 1] * fx * fy)
        return np.where(inside, z, np.nan)

    def _elevation_1(self, x: float, y: float) -> float:
        if self._lists is None:
            self._lists = (self.x.tolist(), self.y.tolist(), self.z.tolist())
        gx, gy, gz = self._lists
        if not (gx[0] <= x <= gx[-1] and gy[0] <= y <= gy[-1]):
            return math.nan
        i = min(max(bisect_right(gx, x) - 1, 0), len(gx) - 2)
        j = min(max(bisect_right(gy, y) - 1, 0), len(gy) - 2)
        fx = (x - gx[i]) / (gx[i + 1] - gx[i])
        fy = (y - gy[j]) / (gy[j + 1] - gy[j])
        a, b = gz[i], gz[i + 1]
        return a[j] * (1 - fx) * (1 - fy) + b[j] * fx * (1 - fy) + a[j + 1] * (1 - fx) * fy + b[j + 1] * fx * fy

    def elevation(self, x: np.ndarray | float, y: np.ndarray | float) -> np.ndarray:
        """Bilinear elevation z(x, y) [m]; raises :class:`TerrainOutOfBoundsError` off the grid."""
        x, y = np.broadcast_arrays(np.asarray(x, dtype=float), np.asarray(y, dtype=float))
        out = self.elevation_or_nan(x, y)
        if np.isnan(out).any():
            k = np.flatnonzero(np.isnan(out.ravel()))[0]
            x0, x1, y0, y1 = self.bounds
            raise TerrainOutOfBoundsError(
                f"point ({x.ravel()[k]:.3f}, {y.ravel()[k]:.3f}) m is outside the terrain grid "
                f"x in [{x0}, {x1}], y in [{y0}, {y1}]")
        return out

    def clearance(self, p_native: np.ndarray) -> np.ndarray:
        """Vertical clearance ``p_z - z_terrain(p_x, p_y)`` [m] of native points (..., 3)."""
        p = np.asarray(p_native, dtype=float)
        if p.shape[-1] != 3:
            raise TerrainError(f"points must have 3 coordinates (x, y, z native), got shape {p.shape}")
        return p[..., 2] - self.elevation(p[..., 0], p[..., 1])

    def min_clearance(self, path: BernsteinPath, samples: int = 2001) -> tuple[float, float]:
        """(minimum clearance [m], path time where it occurs [s]) over ``samples`` uniform samples."""
        if path.frame != "native":
            path = path.to_frame("native")
        t, p = path.sample(samples)
        c = self.clearance(p)
        k = int(np.argmin(c))
        return float(c[k]), float(t[k])

    def check_path(self, path: BernsteinPath, min_clearance: float, samples: int = 2001) -> float:
        """Raise :class:`PathBelowTerrainError` if the path's clearance drops below ``min_clearance``."""
        c, t = self.min_clearance(path, samples)
        if c < min_clearance:
            p = path.to_frame("native")(t)
            raise PathBelowTerrainError(
                f"path {path.name!r} is {c:.2f} m above the terrain at t = {t:.2f} s "
                f"(native x = {p[0]:.1f}, y = {p[1]:.1f}, z = {p[2]:.1f} m); required >= {min_clearance} m",
                t, c)
        return c

    def gradient(self, x: np.ndarray | float, y: np.ndarray | float) -> np.ndarray:
        """(dz/dx, dz/dy) by central differences at half a grid step (shape (..., 2))."""
        hx, hy = 0.5 * np.min(np.diff(self.x)), 0.5 * np.min(np.diff(self.y))
        x = np.clip(np.asarray(x, dtype=float), self.x[0] + hx, self.x[-1] - hx)
        y = np.clip(np.asarray(y, dtype=float), self.y[0] + hy, self.y[-1] - hy)
        gx = (self.elevation(x + hx, y) - self.elevation(x - hx, y)) / (2 * hx)
        gy = (self.elevation(x, y + hy) - self.elevation(x, y - hy)) / (2 * hy)
        return np.stack([gx, gy], axis=-1)

    # ------------------------------------------------------------------ files
    @classmethod
    def load_npz(cls, file: str | Path, name: str = "") -> Terrain:
        """Load ``x``, ``y`` (1-D) and ``z`` ((nx, ny), "ij") arrays from an ``.npz`` file."""
        file = Path(file)
        try:
            with np.load(file, allow_pickle=False) as d:
                missing = {"x", "y", "z"} - set(d.files)
                if missing:
                    raise TerrainError(f"{file}: missing array(s) {sorted(missing)} (need x, y, z)")
                x, y, z = d["x"], d["y"], d["z"]
        except TerrainError:
            raise
        except (OSError, ValueError) as e:
            raise TerrainError(f"{file}: cannot read as .npz ({e})") from None
        try:
            return cls(x, y, z, name or file.stem, {"file": str(file)})
        except TerrainError as e:
            raise TerrainError(f"{file}: {e}") from None

    def save_npz(self, file: str | Path) -> Path:
        file = Path(file)
        np.savez_compressed(file, x=self.x, y=self.y, z=self.z)
        return file

    @classmethod
    def load_csv(cls, file: str | Path, name: str = "") -> Terrain:
        """Load ``x,y,z`` rows (optional header) that cover every node of a regular grid exactly once."""
        file = Path(file)
        try:
            with open(file, newline="") as fh:
                rows = [r for r in csv.reader(fh) if r and not r[0].lstrip().startswith("#")]
        except OSError as e:
            raise TerrainError(f"{file}: cannot read ({e.strerror})") from None
        if rows and not _is_number(rows[0][0]):
            rows = rows[1:]
        try:
            data = np.array([[float(v) for v in r] for r in rows])
        except ValueError as e:
            raise TerrainError(f"{file}: non-numeric value ({e})") from None
        if data.ndim != 2 or data.shape[1] != 3:
            raise TerrainError(f"{file}: expected rows of three values x,y,z")
        xs, ix = np.unique(data[:, 0], return_inverse=True)
        ys, iy = np.unique(data[:, 1], return_inverse=True)
        z = np.full((xs.size, ys.size), np.nan)
        count = np.zeros_like(z, dtype=int)
        np.add.at(count, (ix, iy), 1)
        if count.max() > 1:
            i, j = np.argwhere(count > 1)[0]
            raise TerrainError(f"{file}: node x = {xs[i]}, y = {ys[j]} appears {count[i, j]} times")
        z[ix, iy] = data[:, 2]
        try:
            return cls(xs, ys, z, name or file.stem, {"file": str(file)})
        except TerrainError as e:
            raise TerrainError(f"{file}: {e} (rows must cover a full x-y grid)") from None


def _is_number(s: str) -> bool:
    try:
        float(s)
        return True
    except ValueError:
        return False


# ---------------------------------------------------------------------------------- synthetic canyon
@dataclass
class SyntheticCanyon:
    """A generated canyon: the terrain, its centreline and where the one-mile path starts and ends."""

    terrain: Terrain
    centreline_xy: np.ndarray      #: (m, 2) valley axis incl. extensions [m]
    start_xy: np.ndarray           #: start of the core valley (path start) [m]
    end_xy: np.ndarray             #: end of the core valley (path end) [m]
    core_length_m: float
    params: dict[str, Any] = field(default_factory=dict)


def load_canyon_parameters(file: str | Path | None = None) -> dict[str, Any]:
    """The canyon parameter document (default ``data/terrain/synthetic_canyon.yaml``)."""
    file = Path(file) if file is not None else DATA_DIR / "synthetic_canyon.yaml"
    try:
        return load_yaml(file.read_text())
    except OSError as e:
        raise TerrainError(f"{file}: cannot read ({e.strerror})") from None


def _centreline(cl: dict[str, Any], step: float = 1.0) -> tuple[np.ndarray, float, float]:
    """Dense valley axis (1 m steps): extension, straight, arc, straight, extension (+ meander)."""
    ext = float(cl["extension_m"])
    a1, r, turn = float(cl["straight_before_m"]), float(cl["turn_radius_m"]), np.radians(cl["turn_angle_deg"])
    a2 = float(cl["straight_after_m"])
    arc = r * abs(turn)
    core = a1 + arc + a2
    s = np.arange(-ext, core + ext + 0.5 * step, step)
    # heading as a function of s: piecewise linear (zero curvature, then 1/r, then zero)
    psi0 = np.radians(cl["initial_heading_deg"])
    heading = psi0 + turn * np.clip((s - a1) / arc, 0.0, 1.0)
    dxy = np.c_[np.cos(heading), np.sin(heading)]
    xy = np.vstack([np.zeros(2), np.cumsum(0.5 * (dxy[1:] + dxy[:-1]) * step, axis=0)])
    xy -= xy[np.argmin(np.abs(s))]
    xy += np.asarray(cl["start_xy_m"], dtype=float)
    # lateral meander, tapered to zero at the core ends so the ends stay on the designed axis
    amp, lam = float(cl["sinuosity_amplitude_m"]), float(cl["sinuosity_wavelength_m"])
    normal = np.c_[-np.sin(heading), np.cos(heading)]
    xy += (amp * np.sin(2 * np.pi * np.clip(s, 0, core) / lam) * np.sin(np.pi * np.clip(s / core, 0, 1)))[:, None] \
        * normal
    return np.c_[s, xy], 0.0, core


def synthetic_canyon(params: dict[str, Any] | str | Path | None = None) -> SyntheticCanyon:
    """Generate the synthetic canyon (deterministic for a given parameter document and seed).

    Elevation at a horizontal point at distance ``n`` from the valley axis, nearest axis station ``s``::

        u = floor(s) + rise * min(n / half_width, 1)^2                  (U-shaped floor)
    z = min(shelf, u + tan(slope) * max(0, n - half_width)) + noise

    with ``floor(s)`` linear from ``elevation_start_m`` to ``elevation_end_m`` along the core and a
    smooth Gaussian-filtered noise field of standard deviation ``amplitude_m`` (numpy seed ``seed``).
    """
    from scipy import ndimage, spatial

    p = params if isinstance(params, dict) else load_canyon_parameters(params)
    cl, fl, wl, nz, gr = p["centreline"], p["floor"], p["walls"], p["noise"], p["grid"]
    line, s_start, s_end = _centreline(cl)
    s, axis_xy = line[:, 0], line[:, 1:]
    h, margin = float(gr["spacing_m"]), float(gr["margin_m"])
    lo, hi = axis_xy.min(axis=0) - margin, axis_xy.max(axis=0) + margin
    x = np.arange(np.floor(lo[0] / h) * h, hi[0] + h, h)
    y = np.arange(np.floor(lo[1] / h) * h, hi[1] + h, h)
    X, Y = np.meshgrid(x, y, indexing="ij")
    dist, k = spatial.cKDTree(axis_xy).query(np.c_[X.ravel(), Y.ravel()])
    s_near = s[k].reshape(X.shape)
    n = dist.reshape(X.shape)
    frac = np.clip((s_near - s_start) / (s_end - s_start), 0.0, 1.0)
    floor = fl["elevation_start_m"] + frac * (fl["elevation_end_m"] - fl["elevation_start_m"])
    half = float(fl["half_width_m"])
    u = floor + float(fl["cross_rise_m"]) * np.minimum(n / half, 1.0) ** 2
    z = np.minimum(wl["shelf_elevation_m"], u + np.tan(np.radians(wl["slope_deg"])) * np.maximum(0.0, n - half))
    rng = np.random.default_rng(int(nz["seed"]))
    noise = ndimage.gaussian_filter(rng.standard_normal(X.shape), sigma=float(nz["correlation_length_m"]) / h,
                                    mode="reflect")
    z = z + float(nz["amplitude_m"]) * noise / noise.std()
    terrain = Terrain(x, y, z, p.get("name", "synthetic_canyon"), p.get("provenance", {}))
    i0, i1 = np.argmin(np.abs(s - s_start)), np.argmin(np.abs(s - s_end))
    return SyntheticCanyon(terrain, axis_xy, axis_xy[i0].copy(), axis_xy[i1].copy(), s_end - s_start, p)


# --------------------------------------------------------------------------------------- thalweg
@dataclass
class Thalweg:
    """The lowest line along a valley: horizontal points, floor elevation there, arc length."""

    xy: np.ndarray        #: (m, 2) [m]
    floor_z: np.ndarray   #: (m,) terrain elevation under xy [m]
    s: np.ndarray         #: (m,) cumulative horizontal arc length [m]


def _grid_index(terrain: Terrain, xy: np.ndarray) -> tuple[int, int]:
    if not terrain.contains(xy):
        raise TerrainOutOfBoundsError(f"point {tuple(np.round(xy, 3))} m is outside the terrain grid")
    return int(np.argmin(np.abs(terrain.x - xy[0]))), int(np.argmin(np.abs(terrain.y - xy[1])))


def _least_cost_route(terrain: Terrain, a: np.ndarray, b: np.ndarray, steepness: float) -> np.ndarray:
    """Dijkstra route over the 8-connected grid; edge cost = length * (1 + steepness * rel. height)^2."""
    from scipy import sparse
    from scipy.sparse import csgraph

    nx, ny = terrain.z.shape
    zr = (terrain.z - terrain.z.min()) / max(np.ptp(terrain.z), 1e-9)
    w = (1.0 + steepness * zr) ** 2
    idx = np.arange(nx * ny).reshape(nx, ny)
    rows, cols, vals = [], [], []
    for di, dj in ((1, 0), (0, 1), (1, 1), (1, -1)):
        i0, i1 = max(0, -di), nx - max(0, di)
        j0, j1 = max(0, -dj), ny - max(0, dj)
        src = idx[i0:i1, j0:j1]
        dst = idx[i0 + di:i1 + di, j0 + dj:j1 + dj]
        length = np.hypot(di * np.diff(terrain.x).mean(), dj * np.diff(terrain.y).mean())
        cost = length * 0.5 * (w[i0:i1, j0:j1] + w[i0 + di:i1 + di, j0 + dj:j1 + dj])
        rows.append(src.ravel())
        cols.append(dst.ravel())
        vals.append(cost.ravel())
    g = sparse.coo_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                          shape=(nx * ny, nx * ny)).tocsr()
    ia, ib = _grid_index(terrain, a), _grid_index(terrain, b)
    _, pred = csgraph.dijkstra(g, directed=False, indices=idx[ia], return_predecessors=True)
    node, route = idx[ib], []
    while node != idx[ia]:
        if node < 0:
            raise TerrainError("no route between the thalweg end points")
        route.append(node)
        node = pred[node]
    route.append(idx[ia])
    route = np.array(route[::-1])
    return np.c_[terrain.x[route // ny], terrain.y[route % ny]]


def _resample(xy: np.ndarray, step: float) -> tuple[np.ndarray, np.ndarray]:
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(xy, axis=0), axis=1))])
    keep = np.concatenate([[True], np.diff(s) > 0])
    s, xy = s[keep], xy[keep]
    m = max(int(np.ceil(s[-1] / step)), 2)
    si = np.linspace(0.0, s[-1], m + 1)
    return np.c_[np.interp(si, s, xy[:, 0]), np.interp(si, s, xy[:, 1])], si


def _smooth(xy: np.ndarray, sigma_pts: float) -> np.ndarray:
    """Gaussian smoothing along the line with the ends held (reflect about the end points)."""
    from scipy import ndimage

    if sigma_pts <= 0:
        return xy
    pad = int(np.ceil(4 * sigma_pts))
    pad = min(pad, xy.shape[0] - 1)
    head = 2 * xy[0] - xy[pad:0:-1]
    tail = 2 * xy[-1] - xy[-2:-pad - 2:-1]
    ext = np.vstack([head, xy, tail])
    out = ndimage.gaussian_filter1d(ext, sigma_pts, axis=0, mode="nearest")
    out = out[pad:pad + xy.shape[0]]
    out[0], out[-1] = xy[0], xy[-1]
    return out


def extract_thalweg(terrain: Terrain, start_xy: np.ndarray, end_xy: np.ndarray, *, step_m: float = 10.0,
                    search_half_width_m: float = 120.0, smoothing_m: float = 100.0,
                    steepness: float = 30.0) -> Thalweg:
    """Lowest line along the valley from ``start_xy`` to ``end_xy`` (native horizontal coordinates).

    1. guide: least-cost grid route (Dijkstra) whose cost grows with elevation, smoothed;
    2. at stations every ``step_m`` along the guide, the lowest point of the cross-section
       (perpendicular, +- ``search_half_width_m``, sampled every ``step_m / 2``);
    3. Gaussian smoothing of the minima over ``smoothing_m`` (ends held at the given points).
    """
    a, b = np.asarray(start_xy, dtype=float), np.asarray(end_xy, dtype=float)
    route = _least_cost_route(terrain, a, b, steepness)
    route[0], route[-1] = a, b
    guide, _ = _resample(route, step_m)
    guide = _smooth(guide, 2 * smoothing_m / step_m)
    tangent = np.gradient(guide, axis=0)
    tangent /= np.linalg.norm(tangent, axis=1, keepdims=True)
    normal = np.c_[-tangent[:, 1], tangent[:, 0]]
    offs = np.arange(-search_half_width_m, search_half_width_m + 1e-9, step_m / 2)
    cand = guide[:, None, :] + offs[None, :, None] * normal[:, None, :]
    ok = terrain.contains(cand)
    zc = np.full(ok.shape, np.inf)
    zc[ok] = terrain.elevation(cand[ok][:, 0], cand[ok][:, 1])
    lowest = cand[np.arange(cand.shape[0]), np.argmin(zc, axis=1)]
    lowest[0], lowest[-1] = a, b
    xy, _ = _resample(_smooth(lowest, smoothing_m / step_m), step_m)
    xy = _smooth(xy, 0.5 * smoothing_m / step_m)
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(xy, axis=0), axis=1))])
    return Thalweg(xy, terrain.elevation(xy[:, 0], xy[:, 1]), s)


def thalweg_path(terrain: Terrain, start_xy: np.ndarray, end_xy: np.ndarray, *, clearance_m: float,
                 min_clearance_m: float, degree: int, tf_s: float, t0_s: float = 0.0,
                 max_elevation_m: float | None = None, floor_smoothing_m: float = 150.0,
                 name: str = "thalweg", thalweg: Thalweg | None = None) -> BernsteinPath:
    """Bernstein path (native frame) following the thalweg ``clearance_m`` above the floor.

    The thalweg is sampled, the target height is the smoothed floor elevation + ``clearance_m``, and the
    control points are a least-squares fit (ends interpolated) with the parameter proportional to arc
    length, so the path speed is nearly constant (length / (tf - t0)).  Raises
    :class:`PathBelowTerrainError` if the path comes within ``min_clearance_m`` of the terrain, and
    :class:`TerrainError` if it rises above ``max_elevation_m`` (e.g. the ROM's validity limit).
    """
    from scipy import ndimage

    th = thalweg if thalweg is not None else extract_thalweg(terrain, start_xy, end_xy)
    step = th.s[-1] / (len(th.s) - 1)
    # lower envelope of the floor over a window, then smooth it: never above the local floor minimum
    win = max(int(round(floor_smoothing_m / step)), 1)
    floor = ndimage.minimum_filter1d(th.floor_z, win, mode="nearest")
    floor = ndimage.gaussian_filter1d(floor, win / 2, mode="nearest")
    pts = np.c_[th.xy, floor + clearance_m]
    c = fit_control_points(th.s / th.s[-1], pts, degree)
    path = BernsteinPath(c, t0_s, tf_s, "native", name)
    terrain.check_path(path, min_clearance_m)
    if max_elevation_m is not None:
        zmax = float(path.sample(2001)[1][:, 2].max())
        if zmax > max_elevation_m:
            raise TerrainError(f"path {name!r} rises to z = {zmax:.1f} m, above the limit {max_elevation_m} m")
    return path


def canyon_path(canyon: SyntheticCanyon | None = None) -> BernsteinPath:
    """The terrain-following path of a synthetic canyon, set up by the ``path`` section of its parameters.

    Stand-in for the paper's canyon scenario (thalweg, CG 50 m above the bottom, ~1 mile, Tf = 500 s).
    """
    cy = canyon if canyon is not None else synthetic_canyon()
    pp = cy.params["path"]
    th = extract_thalweg(cy.terrain, cy.start_xy, cy.end_xy, smoothing_m=float(pp["thalweg_smoothing_m"]))
    return thalweg_path(cy.terrain, cy.start_xy, cy.end_xy, clearance_m=float(pp["clearance_m"]),
                        min_clearance_m=float(pp["min_clearance_m"]), degree=int(pp["degree"]),
                        tf_s=float(pp["tf_s"]), max_elevation_m=pp.get("max_elevation_m"),
                        floor_smoothing_m=float(pp["floor_smoothing_m"]), name=cy.terrain.name, thalweg=th)
