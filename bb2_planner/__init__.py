"""bb2_planner: ROS-free motion planning for BB2 (Bernstein paths, path files, terrain, optimisation).

Modules: ``bernstein`` (polynomials and :class:`~bb2_planner.bernstein.BernsteinPath`), ``paths``
(JSON/YAML files and the shipped paths), ``terrain`` (gridded bathymetry, synthetic canyon, thalweg
paths), ``optimal`` (constrained optimal Bernstein trajectories).
"""
