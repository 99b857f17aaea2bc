"""bb2_control: ROS-free guidance and control for the BB2 ROM (SPEC of shared/bb2_control).

Modules: ``path_following`` (3-D SO(3) law), ``los`` (2-D LOS + depth), ``l1_adaptive`` (sampled-data
SISO L1), ``autopilots`` (rate P, depth/heading PD), ``mixer`` (X-plane mixer), ``stacks`` (named
compositions: ``build_stack("rate_2022" | "los_2023" | file, path, overrides)``), ``config`` and
``errors``.  Gains and tunings live in ``bb2_control/data/*.yaml``.
"""
