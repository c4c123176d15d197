"""``uvdms/CooperativeTransport-v1`` and ``uvdms/CooperativeTransportObstacles-v1``: transport with a friction grasp.

The paper's future work, in its words: "the proposed control scheme deals with objects that are fixed with the end
effectors which reduces the degrees of freedom and ability of collaboration". These two tasks are
``uvdms/Transport-v1`` and ``uvdms/TransportObstacles-v1`` with ``grasp="friction"`` by default: each hand holds the
cylinder by friction (:mod:`uvdms_gym.physics.friction_grasp`), so a disagreement between the two hands' motions
becomes an internal force along the object and, beyond the friction limit, slip; the controller commands each
gripper's force, and squeezing is bounded by the object's crush limit. ``docs/cooperative.md`` has the model, its
validation and the reference controller.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from uvdms_gym.envs.obstacles import TransportObstaclesV1Env
from uvdms_gym.envs.transport import TransportV1Env


class CooperativeTransportV1Env(TransportV1Env):
    """``uvdms/CooperativeTransport-v1``: the v1 transport with the object held by friction.

    ## Description
    The UVDMS carries the cylinder of ``uvdms/Transport-v1`` (0.6 m x 0.05 m, 1100 kg/m^3) along the same reference,
    but each hand holds it by friction instead of a weld (:mod:`uvdms_gym.physics.friction_grasp`): the jaws hold it
    against every motion but sliding along its axis and turning about it, which friction resists within the ellipse
    ``(f / mu F)^2 + (m / mu r_t F)^2 <= 1`` of the hand's grip force ``F``. The two hands must cooperate: what their
    motions disagree on becomes an internal force along the object, and beyond the friction limit, slip.

    ## Action Space
    ``Box(-1, 1, (20,), float32)``: the 18 values of ``uvdms/Transport-v1`` (velocity or torque mode), then the grip
    command of the left and the right hand, ``F = (a + 1) / 2 * grip_max`` (default ``grip_max`` 300 N).

    ## Observation Space
    ``Box(-10, 10, (84,), float32)``: the 80 values of ``uvdms/Transport-v1``, then each gripper's force over
    ``grip_max`` and the axial force of each wrist on the object over 20 N.

    ## Costs
    ``cost_contact``, ``cost_zone`` as in the transport, plus ``cost_slip``, ``cost_drop`` and ``cost_crush``
    (:mod:`uvdms_gym.envs.grip_channel`), all summed in ``info["cost"]``.

    ## Episode End
    As the transport, and terminated when a hand's axial slip reaches ``drop_slip`` (the object is dropped) or a grip
    force exceeds ``crush_force`` (the object is crushed): both are failures.

    ## Arguments
    ``grasp`` (default ``"friction"``; a mapping ``{"mu": 0.4, "crush_force": 120, ...}`` sets the knobs of
    :class:`~uvdms_gym.physics.grip.FrictionGraspConfig`) and every argument of ``uvdms/Transport-v1``.

    ## Version History
    * v1: initial release (0.7.0).
    """

    def __init__(self, *, grasp: str | Mapping[str, Any] = "friction", **kwargs: Any) -> None:
        super().__init__(grasp=grasp, **kwargs)


class CooperativeTransportObstaclesV1Env(TransportObstaclesV1Env):
    """``uvdms/CooperativeTransportObstacles-v1``: the obstacle task with the object held by friction.

    ## Description
    The transport among moving outer obstacles in a current of ``uvdms/TransportObstacles-v1``, with the friction
    grasp of :class:`CooperativeTransportV1Env`.

    As :class:`CooperativeTransportV1Env` over ``uvdms/TransportObstacles-v1``: the action gains the two grip
    commands, the observation the four gripper readings after the obstacle slots, ``info`` the grasp's keys and
    costs, and the episode ends at a drop or a crush.

    ## Version History
    * v1: initial release (0.7.0).
    """

    def __init__(self, *, grasp: str | Mapping[str, Any] = "friction", **kwargs: Any) -> None:
        super().__init__(grasp=grasp, **kwargs)
