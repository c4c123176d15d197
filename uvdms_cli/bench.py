"""Benchmarks behind ``uvdms bench {sim,env} --json``: medians (µs) and ratios measured in one run.

``uvdms bench mpc`` runs :func:`baselines.bench.benchmark_all` and ``uvdms bench train``
:func:`agents.training.bench.bench_train`; the command layer (:mod:`uvdms_cli.main`) dispatches them, so this package
imports
neither. Timings are medians of repeated blocks (each block averages many calls, so timer overhead is
negligible). They are measurements, never test assertions.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import numpy as np

from uvdms_gym.physics.params import CIRCLE_Q0_LEFT_DEG, CIRCLE_Q0_RIGHT_DEG, UVDMSParams

BENCH_ENV_IDS: tuple[str, ...] = ("uvdms/CircleTrack-v0", "uvdms/Transport-v0")
"""Environments of ``uvdms bench env`` (the v1 environments step the same physics; only their reward differs)."""


def _median_us(fn: Callable[[], object], calls: int, blocks: int) -> float:
    """Median over ``blocks`` of the mean time per call of ``calls`` calls, in µs."""
    fn()  # warm-up
    per_call = []
    for _ in range(blocks):
        t0 = time.perf_counter()
        for _ in range(calls):
            fn()
        per_call.append((time.perf_counter() - t0) / calls)
    return float(np.median(per_call) * 1e6)


def bench_sim(quick: bool = False) -> dict:
    """Bare ``stepSimulation`` vs one substep with hydrodynamics, the three distance methods and ``J_dis``.

    ``physics_step_us`` is one physics substep of :meth:`UVDMSSim.step` (state read, vehicle and link
    hydrodynamics, external forces, joint torques, ``stepSimulation``), timed over 10-substep calls;
    ``bare_step_us`` is ``stepSimulation`` alone on the same body and time step. The two alternate in short
    blocks; ``overhead_ratio`` is the median over blocks of ``physics_step / bare_step`` within each block.

    ``distances_us["exact"]`` and ``jdis_us`` are the default (compiled) paths,
    ``distances_us["exact_numpy_reference"]`` and ``jdis_reference_us`` the numpy reference of the same
    computation, ``exact_speedup`` / ``jdis_speedup`` their ratios; ``link_segments_us`` is the Pinocchio
    read-out inside ``"exact"`` (``KinematicModel.link_segments``). ``numba_first_call_ms`` times the first
    exact-distance and ``J_dis`` call of a fresh process: ``"compile"`` with an empty numba cache,
    ``"cached"`` with the cache that run wrote.
    """
    from uvdms_gym.distances import (
        compute_distances,
        compute_distances_reference,
        distance_jacobian,
        distance_jacobian_reference,
    )
    from uvdms_gym.distances.pybullet_queries import pybullet_distances
    from uvdms_gym.physics.kinematics import KinematicModel
    from uvdms_gym.physics.sim import UVDMSSim

    calls, blocks = (200, 5) if quick else (1000, 15)
    params = UVDMSParams()
    q0 = np.radians(np.array(CIRCLE_Q0_LEFT_DEG + CIRCLE_Q0_RIGHT_DEG))
    eta0 = np.array([2.0, 0.0, 3.0, 0.0, 0.0, 0.0])
    rng = np.random.default_rng(0)
    out: dict = {"physics_dt": None}
    with UVDMSSim(params) as sim:
        sim.reset(eta0, q=q0)
        out["physics_dt"] = sim.physics_dt
        tau = np.zeros(18)
        tau[6:] = rng.uniform(-1.0, 1.0, 12)

        def reset_if_far() -> None:
            if sim.t > 5.0:
                sim.reset(eta0, q=q0)

        # interleave the two measurements in short blocks so machine load affects both alike; the ratio is
        # the median of the per-block ratios (a load change between blocks cancels within each pair)
        bare, full = [], []
        for _ in range(3 * blocks):
            reset_if_far()
            bare.append(_median_us(sim.bare_step, calls // 3, 1))
            reset_if_far()
            # one call runs 10 substeps (input validation and the state check amortised, as in an env step)
            full.append(_median_us(lambda: sim.step(tau, n_substeps=10), calls // 30, 1) / 10.0)
        out["bare_step_us"] = float(np.median(bare))
        out["physics_step_us"] = float(np.median(full))
        out["overhead_ratio"] = float(np.median(np.array(full) / np.array(bare)))
        sim.reset(eta0, q=q0)
        pb = _median_us(lambda: pybullet_distances(sim.client, sim.body_id, sim.link_index, params), calls // 4, blocks)
    kin = KinematicModel(params)
    kin.set_state(eta0, q0)
    exact = _median_us(lambda: compute_distances(kin, "exact"), calls, blocks)
    sampled = _median_us(lambda: compute_distances(kin, "sampled", n=20), calls, blocks)
    reference = _median_us(lambda: compute_distances_reference(kin), calls // 4, blocks)
    res = compute_distances(kin, "exact")
    jdis = _median_us(lambda: distance_jacobian(kin, res), calls, blocks)
    jdis_ref = _median_us(lambda: distance_jacobian_reference(kin, res), calls, blocks)
    both = _median_us(lambda: distance_jacobian(kin, compute_distances(kin, "exact")), calls, blocks)
    out["distances_us"] = {"exact": exact, "sampled_n20": sampled, "pybullet": pb, "exact_numpy_reference": reference}
    out["jdis_us"] = jdis
    out["exact_plus_jdis_us"] = both
    out["jdis_reference_us"] = jdis_ref
    out["exact_speedup"] = reference / exact
    out["jdis_speedup"] = jdis_ref / jdis
    out["link_segments_us"] = _median_us(kin.link_segments, calls, blocks)
    out["numba_first_call_ms"] = _numba_first_call_ms()
    return out


_FIRST_CALL_SCRIPT = """
import json, time
import numpy as np
from uvdms_gym.distances import compute_distances, distance_jacobian
from uvdms_gym.physics.kinematics import KinematicModel
kin = KinematicModel()
kin.set_state(np.zeros(6), np.full(12, 0.3))
t0 = time.perf_counter()
distance_jacobian(kin, compute_distances(kin, "exact"))
print(json.dumps(1e3 * (time.perf_counter() - t0)))
"""


def _numba_first_call_ms() -> dict:
    """First ``compute_distances(kin, "exact")`` + ``distance_jacobian`` in fresh processes (ms).

    Run twice with a new ``NUMBA_CACHE_DIR``: the first run compiles the kernels and writes the cache,
    the second loads it (what every process pays once the cache exists).
    """
    import json
    import os
    import subprocess
    import sys
    import tempfile

    out = {}
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, NUMBA_CACHE_DIR=cache)
        for key in ("compile", "cached"):
            run = subprocess.run(
                [sys.executable, "-c", _FIRST_CALL_SCRIPT], env=env, capture_output=True, text=True, check=True
            )
            out[key] = float(json.loads(run.stdout.strip().splitlines()[-1]))
    return out


OBSTACLE_ENV_ID = "uvdms/TransportObstacles-v1"
OBSTACLE_REFERENCE_ID = "uvdms/Transport-v1"


def _first_seed_with(env, n_obstacles: int) -> int:
    """The smallest seed whose random scenario has ``n_obstacles`` obstacles."""
    for seed in range(1000):
        env.reset(seed=seed)
        if len(env.unwrapped.obstacles) == n_obstacles:
            return seed
    raise RuntimeError(f"no seed below 1000 draws {n_obstacles} obstacles")


def _bench_obstacles(n_blocks: int, block_steps: int, warmup: int) -> dict:
    """``uvdms/TransportObstacles-v1`` with 3 obstacles against ``uvdms/Transport-v1``, in alternating blocks.

    Both environments (velocity mode, no termination on contact) start from the same seed, one whose random
    scenario has 3 obstacles, and take the same random actions (uniform in ``[-0.3, 0.3]``); blocks alternate
    between them, so each block pair runs under the same machine load. Reported: both medians and
    ``ratio_to_transport_v1``, the median of the per-pair ratios (the issue's target: at most 1.3). Only
    ``step()`` is timed; an episode's reset (which draws the random scenario against the planned transport) is
    reported apart as ``reset_ms``, the median over seeds 0-19.
    """
    import gymnasium as gym

    envs = {
        OBSTACLE_ENV_ID: gym.make(OBSTACLE_ENV_ID, action_mode="velocity", terminate_on_contact=False),
        OBSTACLE_REFERENCE_ID: gym.make(OBSTACLE_REFERENCE_ID, action_mode="velocity", terminate_on_contact=False),
    }
    seed = _first_seed_with(envs[OBSTACLE_ENV_ID], 3)
    blocks = _alternating_blocks(envs, seed, n_blocks, block_steps, warmup)
    ratios = np.array(blocks[OBSTACLE_ENV_ID]) / np.array(blocks[OBSTACLE_REFERENCE_ID])
    result = {
        "seed": seed,
        "n_obstacles": 3,
        "step_us": float(np.median(blocks[OBSTACLE_ENV_ID])),
        "reference_step_us": float(np.median(blocks[OBSTACLE_REFERENCE_ID])),
        "ratio_to_transport_v1": float(np.median(ratios)),
        "ratio_blocks": ratios.tolist(),
        "reset_ms": 1e3 * float(np.median([_time_reset(envs[OBSTACLE_ENV_ID], k) for k in range(20)])),
    }
    for env in envs.values():
        env.close()
    return result


REALISM_BENCH_LEVEL = 3
"""The realism level whose environment step ``uvdms bench env`` compares with level 0 (the issue's bound: 1.3x)."""


def _bench_realism(env_id: str, n_blocks: int, block_steps: int, warmup: int) -> dict:
    """``env_id`` at realism level 3 against level 0, in alternating blocks of the same actions from the same seed.

    Both run velocity mode without termination on contact; the ratio is the median of the per-pair ratios, so each
    pair runs under the same machine load. Only ``step()`` is timed (the navigation filter is the controller's
    cost, not the environment's: ``benchmarks/bench_navigation.py``).
    """
    import gymnasium as gym

    levels = (REALISM_BENCH_LEVEL, 0)
    envs = {
        level: gym.make(env_id, action_mode="velocity", terminate_on_contact=False, realism=level) for level in levels
    }
    blocks = _alternating_blocks(envs, 0, n_blocks, block_steps, warmup)
    for env in envs.values():
        env.close()
    ratios = np.array(blocks[REALISM_BENCH_LEVEL]) / np.array(blocks[0])
    return {
        "level": REALISM_BENCH_LEVEL,
        "step_us": float(np.median(blocks[REALISM_BENCH_LEVEL])),
        "level0_step_us": float(np.median(blocks[0])),
        "ratio_to_level0": float(np.median(ratios)),
        "ratio_blocks": ratios.tolist(),
    }


GRASP_BENCH_ENV_ID = "uvdms/Transport-v1"
"""The transport ``uvdms bench env`` times with the friction grasp against the rigid grasp (the issue's bound: 1.3x)."""
GRASP_BENCH_GRIP = 0.0
"""The grip command of both hands in the grasp benchmark: half of ``grip_max`` (150 N), which holds the object under
the random actions without crushing it (above ``crush_force``, 200 N, an episode ends at once)."""


def _bench_grasp(n_blocks: int, block_steps: int, warmup: int) -> dict:
    """The transport with ``grasp="friction"`` against ``grasp="rigid"``, in alternating blocks from the same seed.

    Both run velocity mode without termination on contact and take the same random velocity actions; the friction
    environment's two grip commands stay at :data:`GRASP_BENCH_GRIP`. Its episodes may still end on a drop (then it
    resets, untimed, as on any episode end: ``resets`` counts them). The ratio is the median of the per-pair
    ratios, so each pair runs under the same machine load; only ``step()`` is timed.
    """
    import gymnasium as gym

    envs = {
        grasp: gym.make(GRASP_BENCH_ENV_ID, action_mode="velocity", terminate_on_contact=False, grasp=grasp)
        for grasp in ("friction", "rigid")
    }
    resets = _ResetCounter(envs["friction"])
    blocks = _alternating_blocks(envs, 0, n_blocks, block_steps, warmup, extra_action=GRASP_BENCH_GRIP)
    for env in envs.values():
        env.close()
    ratios = np.array(blocks["friction"]) / np.array(blocks["rigid"])
    return {
        "env_id": GRASP_BENCH_ENV_ID,
        "grip_command": GRASP_BENCH_GRIP,
        "step_us": float(np.median(blocks["friction"])),
        "rigid_step_us": float(np.median(blocks["rigid"])),
        "ratio_to_rigid": float(np.median(ratios)),
        "ratio_blocks": ratios.tolist(),
        "resets": resets.count,
    }


class _ResetCounter:
    """Counts an environment's ``reset`` calls (wraps the method of the instance)."""

    def __init__(self, env: Any) -> None:
        self.count = -1  # (the first reset starts the run, not after an episode's end)
        self._reset = env.reset
        env.reset = self

    def __call__(self, *args: Any, **kwargs: Any) -> Any:
        self.count += 1
        return self._reset(*args, **kwargs)


def _alternating_blocks(
    envs: dict, seed: int, n_blocks: int, block_steps: int, warmup: int, extra_action: float = 0.0
) -> dict[Any, list[float]]:
    """Per environment, the mean µs of ``step()`` in each of ``n_blocks`` blocks, the environments taking turns.

    Every environment starts from ``seed`` and takes the same random actions (uniform in ``[-0.3, 0.3]``), after
    ``warmup`` untimed steps; an episode's end resets it to ``seed`` (untimed). Taking turns block by block keeps
    each block pair under the same machine load, so their ratio is the figure to report. An environment with more
    than 18 action values (the friction grasp's grip commands) gets ``extra_action`` in each of the others.
    """
    base = np.random.default_rng(0).uniform(-0.3, 0.3, (warmup + n_blocks * block_steps, 18)).astype(np.float32)
    per_env = {}
    for key, env in envs.items():
        extra = np.full((len(base), env.action_space.shape[0] - 18), extra_action, np.float32)
        per_env[key] = np.concatenate([base, extra], axis=1)
    blocks: dict[Any, list[float]] = {key: [] for key in envs}
    for key, env in envs.items():
        env.reset(seed=seed)
        for a in per_env[key][:warmup]:
            env.step(a)
    for b in range(n_blocks):
        for key, env in envs.items():
            elapsed = 0.0
            for a in per_env[key][warmup + b * block_steps : warmup + (b + 1) * block_steps]:
                t0 = time.perf_counter()
                _, _, term, trunc, _ = env.step(a)
                elapsed += time.perf_counter() - t0
                if term or trunc:  # resets are timed apart (a random scenario is drawn at each)
                    env.reset(seed=seed)
            blocks[key].append(elapsed / block_steps * 1e6)
    return blocks


def _time_reset(env, seed: int) -> float:
    """Seconds of one ``reset(seed=seed)`` (which draws the random scenario)."""
    t0 = time.perf_counter()
    env.reset(seed=seed)
    return time.perf_counter() - t0


def bench_env(quick: bool = False) -> dict:
    """Environment steps per second (velocity mode, random actions) and the ratio to bare physics.

    Per environment: ``n_blocks`` blocks of ``block_steps`` steps of ``gym.make(env_id)`` (resets on episode
    end included), after ``warmup_steps`` untimed steps (numba kernels are compiled or loaded from their disk
    cache at construction; the warm-up keeps first-touch effects out of the medians). Before each block, 300
    ``stepSimulation`` calls of the free robot from rest are timed (``bare_step_us``, per call: the figure the
    project's targets use), so that each block's ratio ``step_us / (substeps * bare_step_us)`` divides two
    figures measured seconds apart under the same machine load. Reported: ``step_us`` (median over blocks),
    ``steps_per_s = 1e6 / step_us``, ``ratio_to_bare_physics`` (median of the block ratios) and the per-block
    figures (``step_us_blocks``, ``ratio_blocks``). ``env_bare_step_us`` is one ``stepSimulation`` of the
    environment's own multibody at its reset state (for the transport task: with the gripped object and its
    two grasp constraints, solved by the direct LCP solver) and ``ratio_to_env_physics`` the step against
    that, i.e. the cost on top of the physics engine. ``uvdms/TransportObstacles-v1`` is measured against
    ``uvdms/Transport-v1`` in alternating blocks (:func:`_bench_obstacles`), and each v1 environment at realism
    level 3 against level 0 (``realism``, :func:`_bench_realism`; the bound is 1.3x), and the transport with the
    friction grasp against the rigid grasp (``grasp``, :func:`_bench_grasp`; the bound is 1.3x).
    """
    import gymnasium as gym

    from uvdms_gym.physics.sim import UVDMSSim

    n_blocks, block_steps, warmup = (3, 100, 10) if quick else (7, 400, 20)
    eta0 = np.array([2.0, 0.0, 3.0, 0.0, 0.0, 0.0])
    result: dict = {}
    bare_all: list[float] = []
    with UVDMSSim(UVDMSParams()) as sim:

        def bare_step_us() -> float:
            sim.reset(eta0)
            return _median_us(sim.bare_step, 300, 1)

        for env_id in BENCH_ENV_IDS:
            env = gym.make(env_id, action_mode="velocity", terminate_on_contact=False)
            rng = np.random.default_rng(0)
            env.reset(seed=0)
            n_sub = env.unwrapped.n_substeps
            actions = rng.uniform(-0.3, 0.3, (warmup + n_blocks * block_steps, 18)).astype(np.float32)
            for a in actions[:warmup]:
                env.step(a)
            step_blocks, ratio_blocks = [], []
            for b in range(n_blocks):
                bare_us = bare_step_us()
                bare_all.append(bare_us)
                t0 = time.perf_counter()
                for a in actions[warmup + b * block_steps : warmup + (b + 1) * block_steps]:
                    _, _, term, trunc, _ = env.step(a)
                    if term or trunc:
                        env.reset()
                step_us = (time.perf_counter() - t0) / block_steps * 1e6
                step_blocks.append(step_us)
                ratio_blocks.append(step_us / (n_sub * bare_us))
            env_bare = []
            for _ in range(5):  # bare physics of this environment's body from its reset state (1 s of free fall)
                env.reset(seed=0)
                env_bare.append(_median_us(env.unwrapped._sim.bare_step, 100, 1))
            env.close()
            step_us = float(np.median(step_blocks))
            env_bare_us = float(np.median(env_bare))
            result[env_id] = {
                "steps_per_s": 1e6 / step_us,
                "step_us": step_us,
                "ratio_to_bare_physics": float(np.median(ratio_blocks)),
                "env_bare_step_us": env_bare_us,
                "ratio_to_env_physics": step_us / (n_sub * env_bare_us),
                "substeps": n_sub,
                "step_us_blocks": step_blocks,
                "ratio_blocks": ratio_blocks,
            }
    result[OBSTACLE_ENV_ID] = _bench_obstacles(n_blocks, block_steps, warmup)
    result["realism"] = {
        env_id: _bench_realism(env_id, n_blocks, block_steps, warmup)
        for env_id in ("uvdms/CircleTrack-v1", "uvdms/Transport-v1", OBSTACLE_ENV_ID)
    }
    result["grasp"] = _bench_grasp(n_blocks, block_steps, warmup)
    result["bare_step_us"] = float(np.median(bare_all))
    result["warmup_steps"] = warmup
    result["blocks"] = {"n_blocks": n_blocks, "block_steps": block_steps}
    return result
