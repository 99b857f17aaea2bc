"""A batch ROM: N boats of the same hull evaluated and integrated together (arrays over boats).

Each boat has its own state, actuators, Derivative memory, sea (the authors' regular wave or a spectrum's
components), current and commands; the batch equals N single :class:`bb2_sim.integrator.Simulator` runs to
round-off (``exact=True``: bit for bit). Modules: ``model`` (:class:`BatchModel`, one evaluation), ``simulator``
(:class:`BatchSimulator`, ode3), ``maneuvers`` (the v12 autopilot maneuvers per boat: ``BatchManeuverCommander``,
``batch_for_maneuvers``, ``run_maneuvers_batch``: the twin of ``run_maneuver``), ``autopilot`` (v12 PID/PD, speed
PI), and the twins of the scalar force modules: ``lookup``, ``hull``, ``planes``, ``propeller``, ``pressure``,
``rigid_body``, ``actuators``, ``memory``, ``waves``, and ``environment`` (each boat's spectrum sea and current: the
scalar code's flow, boat by boat).
"""
from .model import BatchEvaluation, BatchModel
from .simulator import BatchSimulator, BatchStepRecord

__all__ = ["BatchEvaluation", "BatchModel", "BatchSimulator", "BatchStepRecord"]
