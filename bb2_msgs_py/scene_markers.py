"""The scene as ``visualization_msgs/MarkerArray`` (RViz, Foxglove): the hull, the terrain, the sea surface.

The builders import the message packages inside the functions (this module imports without rclpy).

=====================  ==========================  =====================================================
marker (``ns``)        frame                       content
=====================  ==========================  =====================================================
``bb2/hull``           ``base_link`` (FLU, CG)     TRIANGLE_LIST of the ROM's own hull surfaces (hull,
                                                   sail, hub, plane roots and the five planes undeflected)
``bb2/terrain``        ``map`` (ENU)               TRIANGLE_LIST of the mission's terrain grid, at most
                                                   ``max_cells`` cells a side (subsampled)
``bb2/sea_surface``    ``map`` (ENU)               TRIANGLE_LIST of the free-surface elevation on a square
                                                   grid around a point (calm: the plane z = 0), at time t
=====================  ==========================  =====================================================

Points are the native coordinates turned to REP-103 (``D = diag(-1, -1, 1)`` for the body and the earth alike,
:mod:`bb2_sim.frames`), metres.  Markers are ``ADD`` with ``frame_locked`` false and no lifetime (they stay until
replaced by the same ``ns``/``id``).
"""
from __future__ import annotations

from typing import Any, Callable

import numpy as np

from bb2_sim.frames import D_FLIP

from .contract import FRAME_BASE_LINK, FRAME_MAP
from .conversions import _header

__all__ = ["HULL_NS", "TERRAIN_NS", "SEA_NS", "hull_triangles_flu", "terrain_triangles_enu", "sea_triangles_enu",
           "triangle_marker", "hull_marker", "terrain_marker", "sea_surface_marker", "marker_array",
           "marker_triangles"]

HULL_NS, TERRAIN_NS, SEA_NS = "bb2/hull", "bb2/terrain", "bb2/sea_surface"
_D = np.diag(D_FLIP)


def hull_triangles_flu(surfaces: Any) -> np.ndarray:
    """(N, 3, 3) triangles of every hull surface (planes undeflected) in base_link (FLU, origin the CG), m."""
    return surfaces.all_triangles() * _D


def _grid_triangles(X: np.ndarray, Y: np.ndarray, Z: np.ndarray) -> np.ndarray:
    """(2 (n-1)(m-1), 3, 3) triangles of a surface z = Z over the grid X, Y (each (n, m)), counter-clockwise
    seen from above in the frame of the points."""
    P = np.stack([X, Y, Z], axis=-1)
    a, b, c, d = P[:-1, :-1], P[1:, :-1], P[1:, 1:], P[:-1, 1:]
    t1 = np.stack([a, b, c], axis=-2).reshape(-1, 3, 3)
    t2 = np.stack([a, c, d], axis=-2).reshape(-1, 3, 3)
    tris = np.concatenate([t1, t2])
    n = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
    flip = n[:, 2] < 0
    tris[flip] = tris[flip][:, ::-1]
    return tris


def terrain_triangles_enu(terrain: Any, max_cells: int = 120) -> np.ndarray:
    """Triangles of the terrain's grid (native ``z[i, j]`` at ``(x[i], y[j])``) in map (ENU), every
    ``ceil(n / max_cells)``-th grid line (the last one kept)."""
    x, y, z = np.asarray(terrain.x, float), np.asarray(terrain.y, float), np.asarray(terrain.z, float)

    def lines(n: int) -> np.ndarray:
        step = max(1, -(-(n - 1) // max_cells))
        return np.unique(np.r_[np.arange(0, n, step), n - 1])

    i, j = lines(x.size), lines(y.size)
    X, Y = np.meshgrid(x[i], y[j], indexing="ij")
    return _grid_triangles(-X, -Y, z[np.ix_(i, j)])


def sea_triangles_enu(elevation: Callable[[np.ndarray, np.ndarray, float], np.ndarray] | None,
                      center_native_xy, t: float, half_size_m: float = 80.0, cells: int = 24) -> np.ndarray:
    """Triangles of the free surface over the square of side ``2 half_size_m`` centred at the native earth point
    ``center_native_xy``, ``cells`` cells a side, in map (ENU): ``elevation(x_native, y_native, t)`` (a
    :class:`bb2_sim.sea.sea.Sea`'s, vectorised), or the calm plane z = 0 with None."""
    c = np.asarray(center_native_xy, float).reshape(2)
    u = np.linspace(-half_size_m, half_size_m, int(cells) + 1)
    X, Y = np.meshgrid(c[0] + u, c[1] + u, indexing="ij")
    Z = np.zeros(X.shape) if elevation is None else np.asarray(elevation(X, Y, t), float).reshape(X.shape)
    return _grid_triangles(-X, -Y, Z)


def triangle_marker(tris: np.ndarray, *, ns: str, frame_id: str, t: float = 0.0, rgba=(0.6, 0.6, 0.65, 1.0),
                    marker_id: int = 0):
    """A TRIANGLE_LIST marker of ``tris`` ((N, 3, 3), m) in ``frame_id``, one colour."""
    from geometry_msgs.msg import Point
    from std_msgs.msg import ColorRGBA
    from visualization_msgs.msg import Marker

    m = Marker(header=_header(t, frame_id), ns=ns, id=int(marker_id), type=Marker.TRIANGLE_LIST,
               action=Marker.ADD)
    m.pose.orientation.w = 1.0
    m.scale.x = m.scale.y = m.scale.z = 1.0
    m.color = ColorRGBA(r=float(rgba[0]), g=float(rgba[1]), b=float(rgba[2]), a=float(rgba[3]))
    m.points = [Point(x=x, y=y, z=z) for x, y, z in np.asarray(tris, float).reshape(-1, 3).tolist()]
    return m


def marker_triangles(marker) -> np.ndarray:
    """(N, 3, 3) triangles of a TRIANGLE_LIST marker (the inverse of :func:`triangle_marker`'s points)."""
    return np.array([[p.x, p.y, p.z] for p in marker.points], dtype=float).reshape(-1, 3, 3)


def hull_marker(surfaces: Any, t: float = 0.0, *, frame_id: str = FRAME_BASE_LINK):
    """The hull in the vehicle's base_link ``frame_id`` (``boat1/base_link`` for a boat in ``/boat1``)."""
    return triangle_marker(hull_triangles_flu(surfaces), ns=HULL_NS, frame_id=frame_id, t=t,
                           rgba=(0.55, 0.57, 0.6, 1.0))


def terrain_marker(terrain: Any, t: float = 0.0, max_cells: int = 120):
    return triangle_marker(terrain_triangles_enu(terrain, max_cells), ns=TERRAIN_NS, frame_id=FRAME_MAP, t=t,
                           rgba=(0.62, 0.52, 0.38, 1.0))


def sea_surface_marker(elevation, center_native_xy, t: float, half_size_m: float = 80.0, cells: int = 24):
    return triangle_marker(sea_triangles_enu(elevation, center_native_xy, t, half_size_m, cells), ns=SEA_NS,
                           frame_id=FRAME_MAP, t=t, rgba=(0.2, 0.45, 0.75, 0.45))


def marker_array(markers):
    from visualization_msgs.msg import MarkerArray

    return MarkerArray(markers=list(markers))
