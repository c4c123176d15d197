"""The named baselines built from an environment, as controllers of the benchmark's protocol.

Every baseline follows :class:`uvdms_gym.evaluation.Controller` (``reset(seed)``, ``predict(obs, info) -> action``,
the action in the environment's normalised space ``[-1, 1]^18``; re-exported here); the MPC baselines expose
``last_record`` (a dict with ``status``, ``iterations``, ``max_slack``, ``wall_us`` and more) after each
``predict`` (``hold``, with no QP, an empty one). Trained agents follow the same protocol
(:class:`agents.export.AgentController`); resolving a name *or* an agent path
to a controller is the composition layer's job (:mod:`leaderboard.suite.registry`).

Named baselines (:data:`BASELINES`; :func:`make_baseline`):

==============  ============  ===========================================================================
name            action_mode   what
==============  ============  ===========================================================================
``mpc``         velocity      kinematic MPC without collision rows (MODEL.md section 6): ``a = zeta_cmd / zeta_max``
``campc``       velocity      collision-avoidance MPC (the 18 velocity-damper rows), same action
``campc-di``    torque        CAMPC + dynamic inversion without the RBF network (``a = tau / tau_max``)
``campc-nndi``  torque        CAMPC + dynamic inversion with the RBF network: the paper's full stack
``campc-inner`` velocity      CAMPC without outer-obstacle rows (the ablation on ``TransportObstacles-v1``)
``hold``        velocity      the zero command: vehicle and arms hold still (the floor a controller must beat)
``campc-coop``  velocity      cooperative CAMPC for the friction grasp (:mod:`baselines.cooperative`): internal-force
                              admittance, grip law, integral action; 20 values (18 velocities, 2 grip commands)
==============  ============  ===========================================================================

On an environment with the friction grasp (``env.unwrapped.grasp_config`` set, e.g.
``uvdms/CooperativeTransport-v1``) every other baseline runs unchanged and is wrapped by
:class:`baselines.cooperative.ConstantGrip`, which appends a constant grip command of the grasp's ``grip_initial``
(40 N by default) to its 18 values: the ablation of ``campc-coop``. ``campc-coop`` refuses a rigid-grasp
environment (a one-line ``ValueError``).

In an environment with outer obstacles (``uvdms/TransportObstacles-v1``) the CAMPC baselines add
:data:`OUTER_ROWS` velocity-damper rows for them, built from ``info["obstacles"]`` (the measured obstacle
centres, velocities and shapes) and predicted over the horizon from the measured velocities.

Timing. The MPC runs once per environment step with ``T_c = env.control_dt`` (0.04 s by default), on a
reference window ``env.unwrapped.reference(t + j T_c)``, ``j = 1..N_p``. [D] In torque mode the dynamic
inversion also runs once per environment step (``dt = control_dt``): the torque is held over the
environment's physics substeps, exactly as an RL agent's torque action is, so the two compete on equal
terms and the registered episode lengths (in steps) stay valid. The defaults of
:class:`~baselines.inner_loop.di.DIConfig` were chosen for that 25 Hz rate on the simulator; ``dt`` is set to the
environment's ``control_dt``.

Information used. A controller sees ``obs``/``info`` (``t``, ``eta``, ``nu``, ``q``, ``qdot``), the task's
reference through ``env.unwrapped.reference``, and public attributes of the environment (``params``,
``zeta_max``, ``tau_max``, ``control_dt``, ``kinematic_model``, ``with_object``) — never the simulator.
The MPC's outputs (end-effector positions, or the object pose through the right arm) are computed on the
kinematic model from ``eta`` and ``q``.
"""

from __future__ import annotations

from typing import Any

from baselines.cooperative import ConstantGrip, CooperativeCAMPC
from baselines.mpc_baselines import CascadeTorqueController, HoldStill, MPCVelocityController
from uvdms_gym.evaluation import Controller, check_action_mode

__all__ = [  # the controllers are re-exported from baselines.mpc_baselines, where they live
    "BASELINES",
    "CascadeTorqueController",
    "Controller",
    "HoldStill",
    "MPCVelocityController",
    "baseline_action_mode",
    "make_baseline",
]

_REALISM_ROW: dict[str, Any] = {"action_mode": "velocity", "collision": True, "realism_only": True, "default": False}

BASELINES: dict[str, dict[str, Any]] = {
    "mpc": {"action_mode": "velocity", "collision": False},
    "campc": {"action_mode": "velocity", "collision": True},
    "campc-di": {"action_mode": "torque", "collision": True, "use_nn": False},
    "campc-nndi": {"action_mode": "torque", "collision": True, "use_nn": True},
    "campc-inner": {
        "action_mode": "velocity",
        "collision": True,
        "outer": False,
        "env_id": "uvdms/TransportObstacles-v1",
    },
    "hold": {"action_mode": "velocity", "collision": False, "hold": True, "default": False},
    "campc-coop": {
        "action_mode": "velocity",
        "collision": True,
        "cooperative": True,
        "grasp": "friction",
        "default": False,
    },
    "campc-raw": {**_REALISM_ROW, "state": "raw"},
    "campc-privileged": {**_REALISM_ROW, "state": "truth"},
}
"""The named baselines: required action mode, collision rows, RBF network, outer-obstacle rows (default: with
the collision rows, when the environment has obstacles; ``campc-inner`` is CAMPC without them, the ablation), and
``env_id``, the one environment a baseline is meant for (``campc-inner`` is ``campc`` wherever there are no
obstacles, so the leaderboard runs it on the obstacle task only; it works on any). ``hold`` is no MPC
(:class:`HoldStill`); ``default: False`` keeps it out of the leaderboard's ``baselines`` token (name it).

``state`` (default ``"filter"``) is where an MPC baseline reads the state at ``realism > 0``
(:data:`STATE_SOURCES`); ``realism_only`` marks the baselines that exist for the realism track only:
``campc-raw`` (CAMPC on the raw measurements without delay compensation, the ablation) and ``campc-privileged``
(CAMPC on the true state with delay compensation: a privileged reference row, not a competitor). At ``realism=0``
both are ``campc``."""


def make_baseline(name: str, env: Any, **kwargs: Any) -> Controller:
    """A named baseline for ``env``.

    Args:
        name: one of :data:`BASELINES`.
        env: the environment.
        **kwargs: ``mpc_overrides`` / ``di_overrides`` dictionaries (``campc-coop``: also ``integral``).

    Returns:
        The controller (on a friction-grasp environment, a baseline other than ``campc-coop`` wrapped in
        :class:`baselines.cooperative.ConstantGrip`).

    Raises:
        ValueError: unknown name, or the environment's action mode is not the one the baseline needs.
    """
    if name not in BASELINES:
        raise ValueError(f"unknown baseline {name!r}; choose one of {sorted(BASELINES)} or give a path to an agent")
    spec = BASELINES[name]
    check_action_mode(name, env, spec["action_mode"])

    outer = spec.get("outer", True)
    state = spec.get("state", "filter")
    if spec.get("cooperative", False):
        return CooperativeCAMPC(env, outer=outer, state=state, **kwargs)
    grasp = getattr(env.unwrapped, "grasp_config", None)
    if spec.get("hold", False):
        ctrl: Controller = HoldStill(env)
    elif spec["action_mode"] == "velocity":
        ctrl = MPCVelocityController(env, collision=spec["collision"], outer=outer, state=state, **kwargs)
    else:
        ctrl = CascadeTorqueController(
            env, use_nn=spec["use_nn"], collision=spec["collision"], outer=outer, state=state, **kwargs
        )
    return ctrl if grasp is None else ConstantGrip(ctrl, grasp)


def baseline_action_mode(name: str) -> str | None:
    """The action mode a baseline needs (``None`` for a name that is not a baseline, such as an agent path)."""
    return BASELINES[name]["action_mode"] if name in BASELINES else None
