"""``HybridVecEnv``: env 0 in the trainer's process, the others in worker processes, stepped at the same time.

Why: with ``SubprocVecEnv`` every env lives in a worker, and the trainer sleeps while they step. On a small VM
the round trip to a sleeping worker (wake-up, pickling, pipe) costs about half an env step, and the trainer's
core idles during the physics. ``HybridVecEnv`` sends the actions to the workers first, steps env 0 itself
meanwhile, then collects the workers' results: with 2 envs on 2 cores both cores step physics and the
worker's wake-up latency is hidden behind the trainer's own step. With ``n`` envs it uses ``n`` processes (the
trainer and ``n - 1`` workers), one core each.

The results are those of :class:`~stable_baselines3.common.vec_env.DummyVecEnv` over the same factories: env
``i`` gets seed ``seed + i`` and options ``options[i]`` on its next reset, exactly as there (a test compares
the two bit for bit).
"""

from __future__ import annotations

import multiprocessing as mp
import os
import time
from collections.abc import Callable, Sequence
from multiprocessing.connection import Connection
from typing import Any

import gymnasium as gym
import numpy as np
from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv, VecEnv
from stable_baselines3.common.vec_env.base_vec_env import (
    CloudpickleWrapper,
    VecEnvIndices,
    VecEnvObs,
    VecEnvStepReturn,
)
from stable_baselines3.common.vec_env.subproc_vec_env import _worker

_yield_core: Callable[[], None] = getattr(os, "sched_yield", lambda: time.sleep(0))  # no sched_yield on Windows

DEFAULT_SPIN_S = 0.002
"""How long each side polls its pipe before falling back to a blocking read (seconds; see the module)."""


def _spin_until_readable(conn: Connection, spin_s: float) -> None:
    """Poll ``conn`` for up to ``spin_s`` seconds (returns early as soon as a message is there).

    Each unsuccessful poll yields the core (``os.sched_yield``): on an idle core that returns at once, so the
    wait stays a spin, while on a busy machine the other runnable processes go first instead of competing with
    a spinning one.
    """
    if spin_s <= 0.0 or conn.poll():
        return
    deadline = time.perf_counter() + spin_s
    while time.perf_counter() < deadline:
        if conn.poll():
            return
        _yield_core()


class _SpinningConnection:
    """The worker's end of the pipe, whose ``recv`` polls for ``spin_s`` before blocking."""

    def __init__(self, conn: Connection, spin_s: float) -> None:
        self._conn = conn
        self._spin_s = spin_s

    def recv(self) -> Any:
        _spin_until_readable(self._conn, self._spin_s)
        return self._conn.recv()

    def send(self, obj: Any) -> None:
        self._conn.send(obj)

    def close(self) -> None:
        self._conn.close()


def _spinning_worker(
    remote: Connection, parent_remote: Connection, env_fn_wrapper: CloudpickleWrapper, spin_s: float
) -> None:
    """Stable-Baselines3's ``SubprocVecEnv`` worker loop, reading its commands through a spinning pipe end."""
    _worker(_SpinningConnection(remote, spin_s), parent_remote, env_fn_wrapper)  # type: ignore[arg-type]


class _SpinningSubprocVecEnv(SubprocVecEnv):
    """``SubprocVecEnv`` whose workers and trainer poll their pipes for ``spin_s`` before blocking."""

    def __init__(self, env_fns: list[Callable[[], gym.Env]], spin_s: float, start_method: str | None = None) -> None:
        self.waiting = False
        self.closed = False
        self.spin_s = spin_s
        if start_method is None:
            start_method = "forkserver" if "forkserver" in mp.get_all_start_methods() else "spawn"
        ctx = mp.get_context(start_method)
        self.remotes, self.work_remotes = zip(*[ctx.Pipe() for _ in env_fns], strict=True)
        self.processes = []
        for work_remote, remote, env_fn in zip(self.work_remotes, self.remotes, env_fns, strict=True):
            args = (work_remote, remote, CloudpickleWrapper(env_fn), spin_s)
            process = ctx.Process(target=_spinning_worker, args=args, daemon=True)  # type: ignore[attr-defined]
            process.start()
            self.processes.append(process)
            work_remote.close()
        self.remotes[0].send(("get_spaces", None))
        observation_space, action_space = self.remotes[0].recv()
        VecEnv.__init__(self, len(env_fns), observation_space, action_space)

    def step_wait(self) -> VecEnvStepReturn:
        for remote in self.remotes:
            _spin_until_readable(remote, self.spin_s)
        return super().step_wait()


def _concat_obs(local: VecEnvObs, remote: VecEnvObs) -> VecEnvObs:
    """Observations of env 0 followed by those of the workers (arrays, dicts or tuples of arrays)."""
    if isinstance(local, dict):
        return {key: np.concatenate([local[key], remote[key]]) for key in local}  # type: ignore[index]
    if isinstance(local, tuple):
        return tuple(np.concatenate([a, b]) for a, b in zip(local, remote, strict=True))  # type: ignore[arg-type]
    return np.concatenate([local, remote])  # type: ignore[list-item]


class HybridVecEnv(VecEnv):
    """Env 0 stepped in this process while envs ``1 .. n-1`` step in ``SubprocVecEnv`` workers (see the module).

    Args:
        env_fns: At least 2 picklable env constructors.
        spin_s: Seconds each side polls its pipe before a blocking read (0: block at once, as
            ``SubprocVecEnv`` does).
        start_method: ``multiprocessing`` start method of the workers (``SubprocVecEnv``'s default if ``None``).
    """

    def __init__(
        self,
        env_fns: Sequence[Callable[[], gym.Env]],
        spin_s: float = DEFAULT_SPIN_S,
        start_method: str | None = None,
    ) -> None:
        if len(env_fns) < 2:
            raise ValueError(f"HybridVecEnv needs at least 2 envs, got {len(env_fns)} (use DummyVecEnv for one)")
        if not spin_s >= 0.0:
            raise ValueError(f"spin_s must be >= 0, got {spin_s}")
        self.remote = _SpinningSubprocVecEnv(list(env_fns[1:]), spin_s, start_method=start_method)
        self.local = DummyVecEnv([env_fns[0]])
        super().__init__(len(env_fns), self.local.observation_space, self.local.action_space)
        self.metadata = self.local.metadata
        self.closed = False

    def _route(self, method: str, indices: VecEnvIndices, *args: Any, **kwargs: Any) -> list[Any]:
        """Call ``method(*args, indices=[j], **kwargs)`` on the part holding each chosen env, in ``indices`` order."""
        out: list[Any] = []
        for i in self._get_indices(indices):
            part, j = (self.local, 0) if i == 0 else (self.remote, i - 1)
            result = getattr(part, method)(*args, indices=[j], **kwargs)
            if result is not None:  # set_attr returns nothing
                out += result
        return out

    def reset(self) -> VecEnvObs:
        """Reset every env with its pending seed and options (then forget them, as ``DummyVecEnv`` does)."""
        self.local._seeds, self.remote._seeds = self._seeds[:1], self._seeds[1:]
        self.local._options, self.remote._options = self._options[:1], self._options[1:]
        remote_obs = self.remote.reset()
        local_obs = self.local.reset()
        self.reset_infos = list(self.local.reset_infos) + list(self.remote.reset_infos)
        self._reset_seeds()
        self._reset_options()
        return _concat_obs(local_obs, remote_obs)

    def step_async(self, actions: np.ndarray) -> None:
        """Send the workers their actions first, so that they step while env 0 does."""
        self.remote.step_async(actions[1:])
        self.local.step_async(actions[:1])

    def step_wait(self) -> VecEnvStepReturn:
        """Step env 0 here, then collect the workers' results."""
        local_obs, local_rew, local_done, local_info = self.local.step_wait()
        remote_obs, remote_rew, remote_done, remote_info = self.remote.step_wait()
        self.reset_infos = list(self.local.reset_infos) + list(self.remote.reset_infos)
        return (
            _concat_obs(local_obs, remote_obs),
            np.concatenate([local_rew, remote_rew]).astype(np.float32),  # DummyVecEnv's reward dtype
            np.concatenate([local_done, remote_done]),
            list(local_info) + list(remote_info),
        )

    def close(self) -> None:
        """Close env 0 and the workers (idempotent)."""
        if self.closed:
            return
        self.local.close()
        self.remote.close()
        self.closed = True

    def get_images(self) -> Sequence[np.ndarray | None]:
        """Frames of every env, in env order."""
        return list(self.local.get_images()) + list(self.remote.get_images())

    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        """Attribute ``attr_name`` of the chosen envs."""
        return self._route("get_attr", indices, attr_name)

    def set_attr(self, attr_name: str, value: Any, indices: VecEnvIndices = None) -> None:
        """Set attribute ``attr_name`` of the chosen envs."""
        self._route("set_attr", indices, attr_name, value)

    def env_method(
        self, method_name: str, *method_args: Any, indices: VecEnvIndices = None, **method_kwargs: Any
    ) -> list[Any]:
        """Call ``method_name`` on the chosen envs."""
        return self._route("env_method", indices, method_name, *method_args, **method_kwargs)

    def env_is_wrapped(self, wrapper_class: type[gym.Wrapper], indices: VecEnvIndices = None) -> list[bool]:
        """Whether each chosen env is wrapped in ``wrapper_class``."""
        return self._route("env_is_wrapped", indices, wrapper_class)
