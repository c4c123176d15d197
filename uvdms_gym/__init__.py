"""uvdms-gym: a Gymnasium benchmark for an underwater vehicle-dual-manipulator system (UVDMS).

Importing the package registers the environments (entry points are strings, so nothing heavy is imported):

* ``uvdms/CircleTrack-v0``: collision-risk circle tracking (paper Cases 1 and 2, or random circles);
* ``uvdms/Transport-v0``: transport of a gripped cylinder;
* ``uvdms/CircleTrack-v1``, ``uvdms/Transport-v1``: the same tasks with a bounded, non-negative per-step reward
  and a contact penalty, under which ending an episode early never pays (:mod:`uvdms_gym.envs.bounded_reward`);
* ``uvdms/TransportObstacles-v1``: the v1 transport among moving outer obstacles (:mod:`uvdms_gym.envs.obstacles`);
* ``uvdms/CooperativeTransport-v1``, ``uvdms/CooperativeTransportObstacles-v1``: the two v1 transports with the
  object held by friction instead of welded (:mod:`uvdms_gym.envs.cooperative`).

``gymnasium.make("uvdms_gym:uvdms/CircleTrack-v0")`` also works without importing the package first
(RL Zoo's ``--gym-packages uvdms_gym``).
"""

import warnings

from gymnasium.envs.registration import register, registry

from uvdms_gym.physics.params import UVDMSParams
from uvdms_gym.utils.legacy import MOVED, REGROUPED, install_moved_finder, regrouped_message

__version__ = "0.9.4"
__all__ = ["ENV_IDS", "UVDMSParams", "__version__"]

_REGISTRATIONS: tuple[tuple[str, str, int], ...] = (
    ("uvdms/CircleTrack-v0", "uvdms_gym.envs.circle:CircleTrackEnv", 500),
    ("uvdms/Transport-v0", "uvdms_gym.envs.transport:TransportEnv", 600),
    ("uvdms/CircleTrack-v1", "uvdms_gym.envs.circle:CircleTrackV1Env", 500),
    ("uvdms/Transport-v1", "uvdms_gym.envs.transport:TransportV1Env", 600),
    ("uvdms/TransportObstacles-v1", "uvdms_gym.envs.obstacles:TransportObstaclesV1Env", 600),
    ("uvdms/CooperativeTransport-v1", "uvdms_gym.envs.cooperative:CooperativeTransportV1Env", 600),
    ("uvdms/CooperativeTransportObstacles-v1", "uvdms_gym.envs.cooperative:CooperativeTransportObstaclesV1Env", 600),
)
"""(id, entry point, max_episode_steps) of every registered environment."""
ENV_IDS: tuple[str, ...] = tuple(env_id for env_id, _, _ in _REGISTRATIONS)

for _env_id, _entry_point, _max_steps in _REGISTRATIONS:
    if _env_id not in registry:
        register(id=_env_id, entry_point=_entry_point, max_episode_steps=_max_steps)

# v0 is not deprecated: it is the version of the published results and stays supported beside v1. Gymnasium's
# make() warns that any version but the newest is "out of date"; silence that for the uvdms ids only.
warnings.filterwarnings("ignore", message=r".*The environment uvdms/\S+ is out of date", category=DeprecationWarning)

# The module paths before the package was grouped into subpackages (uvdms_gym.sim, uvdms_gym.params, ...) fail in
# one line naming their new home (uvdms_gym/utils/legacy.py; the aliases of 0.3.0 were removed in 0.4.0).
install_moved_finder(MOVED)
install_moved_finder(REGROUPED, regrouped_message)
