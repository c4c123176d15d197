"""Parallel PPO rollouts (``--vec-env rollout``): each env collects its part of the rollout with its own policy copy.

Why: with ``dummy``, ``subproc`` or ``hybrid`` vector envs the trainer picks every env's action, so the policy's
forward pass (about 300-460 µs for PPO's 256 x 256 networks) and the round trip to the workers (about 200 µs)
are serial work on every vector step, and PPO's 2-env throughput stays at 1.3-1.6x that of 1 env on 2 cores.
Here env 0 stays in the trainer's process and envs ``1 .. n-1`` in worker processes, as with
:class:`agents.common.vecenv.HybridVecEnv`; at the start of each rollout every worker receives the policy's weights, the
frozen observation-normalisation statistics and a torch seed, and collects its whole part of the rollout
(``n_steps`` transitions: observation, sampled action, value, log-probability, raw reward, episode ends, the
value of a truncated episode's terminal observation) with its own copy of the policy, while the trainer collects
env 0's part with the policy itself. The parts are then merged into SB3's ``RolloutBuffer`` in step order, and
PPO's ``train()`` runs unchanged. Per vector step that leaves one env step and one batch-1 forward pass per
process, and one pipe round trip per rollout instead of per step.

What differs from SB3's ``collect_rollouts`` (and so from the other ``--vec-env`` types, which agree bit for bit
with each other):

* Sampling. Each worker's actions come from its own torch generator, seeded at every rollout from the trainer's
  (``torch.randint`` on the global generator), so a run is reproducible from its seed, but its action noise is
  not ``DummyVecEnv``'s.
* Observation normalisation (``VecNormalize``). Within a rollout every env normalises with the statistics of the
  rollout's start; the running statistics are then updated with the rollout's raw observations in step order,
  exactly the sequence of updates ``VecNormalize`` makes (the RLlib-style "filter synced per rollout"). Reward
  normalisation replays ``VecNormalize``'s per-step return statistics exactly, in the trainer.
* Callbacks. ``on_step`` is called once per vector step, with ``num_timesteps`` advanced by ``n_envs`` as SB3
  does; its ``locals`` (``infos``, ``dones``) describe env 0 only. The other envs' episode records reach
  ``ep_info_buffer`` when the rollout ends. A callback that stops training stops env 0's collection; the workers'
  parts of that rollout are received and discarded.

PPO (:class:`RolloutPPO`, SB3's PPO subclassed and registered as ``ppo``) and PPO-Lagrangian (its subclass, which reads
each merged step's ``info["cost"]`` through :meth:`RolloutPPO._on_merged_step`) collect this way, without gSDE; with any
other vector env they are unchanged. The off-policy learners refuse ``--vec-env rollout``
(:func:`check_rollout_vec_env`).
"""

from __future__ import annotations

import traceback
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any, ClassVar

import cloudpickle
import gymnasium as gym
import numpy as np
import torch as th
from gymnasium import spaces
from stable_baselines3 import PPO as SB3PPO
from stable_baselines3.common.buffers import RolloutBuffer
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.policies import ActorCriticPolicy
from stable_baselines3.common.utils import obs_as_tensor
from stable_baselines3.common.vec_env import VecEnv, VecNormalize

from agents.common.vecenv import DEFAULT_SPIN_S, HybridVecEnv, _spin_until_readable

COLLECT_METHOD = "collect_rollout_part"
"""Name of :class:`RolloutCollector`'s method that the workers run (through SB3's ``env_method`` command)."""
ROLLOUT_ALGOS: tuple[str, ...] = ("ppo", "ppo_lagrangian")
"""Algorithms that can train with ``--vec-env rollout``."""
_SEED_HIGH = 2**31 - 1


def check_rollout_vec_env(algo: str, use_sde: bool = False) -> None:
    """Raise ``ValueError`` unless ``algo`` (and ``use_sde``) can train with ``--vec-env rollout``."""
    if algo not in ROLLOUT_ALGOS:
        raise ValueError(
            f"--vec-env rollout (parallel rollouts, agents.common.rollouts) is for {', '.join(ROLLOUT_ALGOS)} only, "
            f"not {algo}: use hybrid"
        )
    if use_sde:
        raise ValueError("--vec-env rollout does not support gSDE (use_sde: true): use hybrid")


@dataclass(frozen=True)
class ObsNormalization:
    """``VecNormalize``'s observation normalisation with frozen statistics (``mean is None``: none)."""

    mean: np.ndarray | None = None
    var: np.ndarray | None = None
    epsilon: float = 1e-8
    clip_obs: float = 10.0

    @classmethod
    def of(cls, vec_normalize: VecNormalize | None) -> ObsNormalization:
        """The current statistics of ``vec_normalize`` (none if it is ``None`` or does not normalise observations)."""
        if vec_normalize is None or not vec_normalize.norm_obs:
            return cls()
        rms = vec_normalize.obs_rms
        if isinstance(rms, dict):
            raise ValueError("--vec-env rollout needs a Box observation space (VecNormalize of a dict space)")
        return cls(rms.mean.copy(), rms.var.copy(), float(vec_normalize.epsilon), float(vec_normalize.clip_obs))

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        """The normalised observation (``VecNormalize.normalize_obs``'s formula and float32 cast)."""
        if self.mean is None:
            return obs
        return np.clip((obs - self.mean) / np.sqrt(self.var + self.epsilon), -self.clip_obs, self.clip_obs).astype(
            np.float32
        )


@dataclass
class RolloutPart:
    """One env's part of a rollout (``n`` steps; arrays indexed by step)."""

    obs: np.ndarray
    """(n, *obs_shape) the observations the policy acted on (normalised with the rollout's frozen statistics)."""
    actions: np.ndarray
    """(n, *action_shape) the sampled actions (before clipping to the action space)."""
    values: np.ndarray
    """(n,) the value estimates of ``obs``."""
    log_probs: np.ndarray
    """(n,) the log-probabilities of ``actions``."""
    episode_starts: np.ndarray
    """(n,) whether ``obs`` began an episode."""
    rewards: np.ndarray
    """(n,) the environment's (raw) rewards."""
    dones: np.ndarray
    """(n,) whether the step ended an episode."""
    new_raw_obs: np.ndarray
    """(n, *obs_shape) the raw observation after each step (the reset observation after an episode end)."""
    terminal_values: np.ndarray
    """(n,) the value of the terminal observation of a truncated episode, else 0."""
    terminal_obs: dict[int, np.ndarray]
    """Step -> the terminal observation of the episode the step ended (normalised as ``obs``)."""
    infos: list[dict[str, Any]]
    """(n) the step infos (``DummyVecEnv``'s ``TimeLimit.truncated``; the merge adds ``terminal_observation``)."""
    last_value: float = 0.0
    """The value of the observation after the last step."""
    last_raw_obs: np.ndarray = field(default_factory=lambda: np.zeros(0))
    """The raw observation after the last step."""


@dataclass(frozen=True)
class _WorkerError:
    message: str


def collect_part(
    collector: RolloutCollector,
    policy: ActorCriticPolicy,
    n_steps: int,
    normalization: ObsNormalization,
    on_step: Callable[[dict[str, Any], bool], bool] | None = None,
) -> RolloutPart | None:
    """Collect ``n_steps`` transitions of ``collector``'s env with ``policy`` (SB3's per-step logic for one env).

    Args:
        collector: The env (its last observation is where the part starts).
        policy: The acting policy (in evaluation mode; sampling draws from torch's current generator).
        n_steps: Steps to collect.
        normalization: Observation normalisation (frozen for the part).
        on_step: Called after every step with its ``info`` and ``done``; returning ``False`` stops the part.

    Returns:
        The part, or ``None`` if ``on_step`` stopped it.
    """
    space = policy.action_space
    obs_shape = collector.last_obs.shape
    part = RolloutPart(
        obs=np.empty((n_steps, *obs_shape), np.float32),
        actions=np.empty((n_steps, *space.shape), np.float32),
        values=np.empty(n_steps, np.float32),
        log_probs=np.empty(n_steps, np.float32),
        episode_starts=np.empty(n_steps, np.float32),
        rewards=np.empty(n_steps, np.float32),
        dones=np.empty(n_steps, bool),
        new_raw_obs=np.empty((n_steps, *obs_shape), collector.last_obs.dtype),
        terminal_values=np.zeros(n_steps, np.float32),
        terminal_obs={},
        infos=[],
    )
    for t in range(n_steps):
        obs = normalization(collector.last_obs)
        with th.no_grad():
            actions, values, log_probs = policy(obs_as_tensor(obs[None], policy.device))
        action = actions.cpu().numpy()[0]
        if isinstance(space, spaces.Box):
            sent = policy.unscale_action(action) if policy.squash_output else np.clip(action, space.low, space.high)
        else:
            sent = action
        part.obs[t] = obs
        part.actions[t] = action
        part.values[t] = float(values[0, 0])
        part.log_probs[t] = float(log_probs[0])
        part.episode_starts[t] = collector.episode_start
        reward, done, info, terminal = collector.step_auto_reset(sent)
        part.rewards[t] = reward
        part.dones[t] = done
        part.new_raw_obs[t] = collector.last_obs
        if terminal is not None:
            part.terminal_obs[t] = normalization(terminal)
            if info.get("TimeLimit.truncated", False):
                with th.no_grad():
                    tv = policy.predict_values(obs_as_tensor(part.terminal_obs[t][None], policy.device))
                part.terminal_values[t] = float(tv[0, 0])
        part.infos.append(info)
        if on_step is not None and not on_step(info, done):
            return None
    with th.no_grad():
        last = policy.predict_values(obs_as_tensor(normalization(collector.last_obs)[None], policy.device))
    part.last_value = float(last[0, 0])
    part.last_raw_obs = collector.last_obs.copy()
    return part


class RolloutCollector(gym.Wrapper):
    """The outermost wrapper of every env of a :class:`RolloutVecEnv`: it collects rollout parts.

    In the worker processes :meth:`collect_rollout_part` runs through SB3's ``env_method`` command. ``reset`` and
    ``step`` pass through and remember the observation they return (and whether it began an episode), so the env
    can be driven by its vector env (``reset`` at the start of training) and by :func:`collect_part` alike.
    """

    def __init__(self, env: gym.Env) -> None:
        super().__init__(env)
        self.last_obs: np.ndarray = np.zeros(0)
        self.episode_start = True
        self._policy: ActorCriticPolicy | None = None

    def reset(self, **kwargs: Any) -> tuple[Any, dict[str, Any]]:
        """Reset the env (and remember the observation)."""
        obs, info = self.env.reset(**kwargs)
        self.last_obs, self.episode_start = np.asarray(obs), True
        return obs, info

    def step(self, action: Any) -> tuple[Any, Any, bool, bool, dict[str, Any]]:
        """Step the env (and remember the observation)."""
        obs, reward, terminated, truncated, info = self.env.step(action)
        self.last_obs, self.episode_start = np.asarray(obs), bool(terminated or truncated)
        return obs, reward, terminated, truncated, info

    def step_auto_reset(self, action: np.ndarray) -> tuple[float, bool, dict[str, Any], np.ndarray | None]:
        """One step as ``DummyVecEnv`` makes it: ``(reward, done, info, terminal observation or None)``.

        After an episode end the env is reset (without a seed, as ``DummyVecEnv`` does) and ``last_obs`` is
        the reset observation; ``info["TimeLimit.truncated"]`` is ``truncated and not terminated``.
        """
        obs, reward, terminated, truncated, info = self.env.step(action)
        done = bool(terminated or truncated)
        info = dict(info)
        info["TimeLimit.truncated"] = bool(truncated and not terminated)
        terminal = None
        if done:
            terminal = np.asarray(obs)
            obs, _ = self.env.reset()
        self.last_obs, self.episode_start = np.asarray(obs), done
        return float(reward), done, info, terminal

    def collect_rollout_part(self, payload: dict[str, Any]) -> RolloutPart | _WorkerError:
        """Worker side: load the weights, seed torch and collect a part (errors come back as a message)."""
        try:
            if payload.get("policy") is not None:
                self._policy = cloudpickle.loads(payload["policy"])
            if self._policy is None:
                raise RuntimeError("no policy received")
            self._policy.load_state_dict({k: th.as_tensor(v) for k, v in payload["state"].items()})
            self._policy.set_training_mode(False)
            th.manual_seed(int(payload["seed"]))
            part = collect_part(self, self._policy, int(payload["n_steps"]), payload["normalization"])
            assert part is not None
            return part
        except Exception:
            return _WorkerError(traceback.format_exc())


class _WithCollector:
    """A picklable env constructor: the given one's env wrapped in :class:`RolloutCollector`."""

    def __init__(self, env_fn: Callable[[], gym.Env]) -> None:
        self.env_fn = env_fn

    def __call__(self) -> gym.Env:
        return RolloutCollector(self.env_fn())


class RolloutVecEnv(HybridVecEnv):
    """:class:`agents.common.vecenv.HybridVecEnv` whose envs also collect whole rollout parts (module docstring).

    As a vector env it behaves as ``HybridVecEnv`` (env 0 here, the others in workers, the same results as
    ``DummyVecEnv``); :class:`RolloutPPO` drives it through :meth:`start_parts` / :meth:`finish_parts`.

    Args:
        env_fns: At least 2 picklable env constructors.
        spin_s: Seconds each side polls its pipe before a blocking read.
        start_method: ``multiprocessing`` start method of the workers.
    """

    def __init__(
        self,
        env_fns: Sequence[Callable[[], gym.Env]],
        spin_s: float = DEFAULT_SPIN_S,
        start_method: str | None = None,
    ) -> None:
        super().__init__([_WithCollector(fn) for fn in env_fns], spin_s, start_method)
        self._policy_sent = False
        self._collecting = False

    @property
    def local_collector(self) -> RolloutCollector:
        """Env 0 (in this process)."""
        return self.local.envs[0]  # type: ignore[return-value]

    def start_parts(
        self, policy: ActorCriticPolicy, n_steps: int, normalization: ObsNormalization, seeds: Sequence[int]
    ) -> None:
        """Send every worker the policy's weights (the policy itself the first time) and start its part."""
        if self._collecting:
            raise RuntimeError("RolloutVecEnv: the previous rollout's parts were not received")
        state = {k: v.detach().cpu().numpy() for k, v in policy.state_dict().items()}
        policy_bytes = None if self._policy_sent else cloudpickle.dumps(policy)
        for remote, seed in zip(self.remote.remotes, seeds, strict=True):
            payload = {
                "policy": policy_bytes,
                "state": state,
                "seed": int(seed),
                "n_steps": int(n_steps),
                "normalization": normalization,
            }
            remote.send(("env_method", (COLLECT_METHOD, (payload,), {})))
        self._policy_sent = True
        self._collecting = True

    def finish_parts(self) -> list[RolloutPart]:
        """Receive every worker's part (in env order).

        Raises:
            RuntimeError: A worker failed (its traceback is in the message).
        """
        parts = []
        for remote in self.remote.remotes:
            _spin_until_readable(remote, self.spin_s)
            parts.append(remote.recv())
        self._collecting = False
        for i, part in enumerate(parts, start=1):
            if isinstance(part, _WorkerError):
                raise RuntimeError(f"rollout worker of env {i} failed:\n{part.message}")
        return parts

    @property
    def spin_s(self) -> float:
        """The pipes' spin time."""
        return self.remote.spin_s


def _rollout_envs(env: VecEnv) -> tuple[RolloutVecEnv, VecNormalize | None]:
    """The :class:`RolloutVecEnv` under ``env`` and the ``VecNormalize`` above it, if any."""
    if isinstance(env, RolloutVecEnv):
        return env, None
    if isinstance(env, VecNormalize) and isinstance(env.venv, RolloutVecEnv):
        return env.venv, env
    raise TypeError(f"parallel rollouts need a RolloutVecEnv, optionally inside VecNormalize, got {env!r}")


def is_rollout_env(env: VecEnv | None) -> bool:
    """Whether ``env`` is a :class:`RolloutVecEnv`, directly or inside ``VecNormalize``."""
    return isinstance(env, RolloutVecEnv) or (isinstance(env, VecNormalize) and isinstance(env.venv, RolloutVecEnv))


class RolloutPPO(SB3PPO):
    """SB3's PPO that collects its rollouts in parallel on a :class:`RolloutVecEnv` (module docstring).

    With any other vector env it is SB3's PPO, unchanged (it only overrides ``collect_rollouts``, and defers to
    SB3's there). Its name is its own (it no longer shadows SB3's ``PPO``); configuration errors show
    :attr:`display_name`, SB3's, whose arguments it takes.
    """

    display_name: ClassVar[str] = "PPO"
    """The name configuration errors show (:func:`agents.config.files.algo_display_name`); not inherited."""

    def collect_rollouts(
        self, env: VecEnv, callback: BaseCallback, rollout_buffer: RolloutBuffer, n_rollout_steps: int
    ) -> bool:
        """SB3's ``collect_rollouts``, or the parallel one on a :class:`RolloutVecEnv`."""
        if not is_rollout_env(env):
            return super().collect_rollouts(env, callback, rollout_buffer, n_rollout_steps)
        check_rollout_vec_env("ppo", self.use_sde)
        venv, vec_normalize = _rollout_envs(env)
        self.policy.set_training_mode(False)
        rollout_buffer.reset()
        callback.on_rollout_start()
        normalization = ObsNormalization.of(vec_normalize)
        seeds = th.randint(0, _SEED_HIGH, (venv.num_envs - 1,)).tolist()
        venv.start_parts(self.policy, n_rollout_steps, normalization, seeds)

        def on_step(info: dict[str, Any], done: bool) -> bool:
            self.num_timesteps += venv.num_envs
            callback.update_locals({"infos": [info], "dones": np.array([done]), "n_steps": n_rollout_steps})
            return callback.on_step()

        try:
            local = collect_part(venv.local_collector, self.policy, n_rollout_steps, normalization, on_step)
        finally:
            remote = venv.finish_parts()
        if local is None:
            return False
        self._merge(rollout_buffer, [local, *remote], vec_normalize, n_rollout_steps)
        callback.update_locals({"rollout_buffer": rollout_buffer})
        callback.on_rollout_end()
        return True

    def _on_merged_step(self, infos: list[dict[str, Any]], dones: np.ndarray) -> None:
        """Called for every vector step of a merged parallel rollout, in step order (subclasses read ``infos``)."""

    def _merge(
        self,
        rollout_buffer: RolloutBuffer,
        parts: list[RolloutPart],
        vec_normalize: VecNormalize | None,
        n_steps: int,
    ) -> None:
        """Fill the buffer in step order, replaying ``VecNormalize``'s statistics updates of those steps."""
        training = vec_normalize is not None and vec_normalize.training
        for t in range(n_steps):
            dones = np.array([p.dones[t] for p in parts])
            raw_rewards = np.array([p.rewards[t] for p in parts], np.float32)
            if vec_normalize is not None:
                if training and vec_normalize.norm_obs:
                    vec_normalize.obs_rms.update(np.stack([p.new_raw_obs[t] for p in parts]))
                if training:
                    vec_normalize._update_reward(raw_rewards)
                rewards = vec_normalize.normalize_reward(raw_rewards)
                vec_normalize.returns[dones] = 0
            else:
                rewards = raw_rewards.copy()
            rewards = rewards + self.gamma * np.array([p.terminal_values[t] for p in parts], np.float32)
            infos = [p.infos[t] for p in parts]
            for info, p in zip(infos, parts, strict=True):  # as VecNormalize hands them on
                if t in p.terminal_obs:
                    info["terminal_observation"] = p.terminal_obs[t]
            self._update_info_buffer(infos, dones)
            self._on_merged_step(infos, dones)
            rollout_buffer.add(
                np.stack([p.obs[t] for p in parts]),
                np.stack([p.actions[t] for p in parts]),
                rewards,
                np.array([p.episode_starts[t] for p in parts], np.float32),
                th.as_tensor(np.array([p.values[t] for p in parts])),
                th.as_tensor(np.array([p.log_probs[t] for p in parts])),
            )
        last_obs = np.stack([p.last_raw_obs for p in parts])
        last_dones = np.array([p.dones[-1] for p in parts])
        rollout_buffer.compute_returns_and_advantage(
            last_values=th.as_tensor(np.array([p.last_value for p in parts])), dones=last_dones
        )
        if vec_normalize is not None:
            vec_normalize.old_obs = last_obs
            self._last_obs = vec_normalize.normalize_obs(last_obs)
        else:
            self._last_obs = last_obs
        self._last_episode_starts = last_dones
