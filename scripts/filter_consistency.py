"""Consistency of the navigation filter in the real environment: NEES of ``(eta, nu)`` and RMSE, per level.

    python -m scripts.filter_consistency [--episodes 20] [--steps 250] [--levels 1 2 3] [--seed S]
                                         [--policy random|campc-privileged]

Each episode is ``gym.make("uvdms/CircleTrack-v1", case="random", hydro_randomization=0.3, realism=L)`` (random
circles, hydrodynamics off by up to 30 %, the level's action delay, thrusters with rotor lag and dead zone, drive
limits and sensors) driven by

* ``random`` (default): smooth random velocity commands, sums of sinusoids from a seeded generator (the episode
  never ends early: no termination on contact or tracking error; the filter is checked, not the task);
* ``campc-privileged``: CAMPC on the true state with delay compensation (the task's own motion).

The :class:`~uvdms_gym.realism.navigation.NavigationFilter` is fed exactly what a controller gets:
``info["measurements"]`` at reset, then ``info["measurements"]`` and ``info["tau_cmd"]`` after every step; its
error is taken against ``env.unwrapped.true_state()``.

Per step ``k`` the average NEES over the ``N`` episodes, ``mean_i e_i' P_i^-1 e_i`` (12 dof), is compared with the
two-sided 95 % bounds ``chi2.ppf([0.025, 0.975], 12 N) / N``; the script prints (JSON) the fraction of steps inside
them, the mean NEES per component (``e_j^2 / P_jj``, 1 when consistent) and the RMSE of each of the 12 components,
per level.
"""

from __future__ import annotations

import argparse
import json
from collections.abc import Callable
from typing import Any

import gymnasium as gym
import numpy as np
from scipy import stats

import uvdms_gym  # noqa: F401  (registers the ids)
from uvdms_gym.realism.navigation import NavigationFilter
from uvdms_gym.seeds import split_seeds

ENV_ID = "uvdms/CircleTrack-v1"
"""The task the filter is checked on."""
ENV_KWARGS: dict[str, Any] = {"case": "random", "hydro_randomization": 0.3}
"""Random circles with the hydrodynamics off by up to 30 % (the nominal model does not know)."""
NO_TERMINATION: dict[str, Any] = {"terminate_on_contact": False, "max_tracking_error": 1.0e9}
"""With random commands the episode runs its whole length (the filter is judged, not the tracking)."""
COMMAND_AMPLITUDE = 0.4
"""Largest normalised velocity command of each component (a fraction of ``zeta_max``), summed over its sinusoids."""
COMMAND_FREQUENCIES = (0.05, 0.5)
"""Range of the command sinusoids' frequencies, Hz."""
N_SINES = 3
"""Sinusoids summed per command component."""
COMPONENTS = ("x", "y", "z", "phi", "theta", "psi", "u", "v", "w", "p", "q", "r")
"""Names of the 12 estimated components."""
CONFIDENCE = 0.95
"""Two-sided probability of the NEES bounds."""
FIRST_SEED = split_seeds("validation", 1)[0]
"""First episode seed: the first validation draw (``uvdms_gym.seeds``); the test splits are never used here."""
POLICIES = ("random", "campc-privileged")
"""The motions an episode can follow (module docstring)."""


def make_env(level: int | dict[str, Any], policy: str = "random") -> gym.Env:
    """The consistency task at a realism level (a level number or a ``realism`` mapping)."""
    extra = NO_TERMINATION if policy == "random" else {}
    return gym.make(ENV_ID, **ENV_KWARGS, **extra, realism=level)


def random_commands(seed: int, n_steps: int, control_dt: float) -> np.ndarray:
    """Smooth random velocity commands (n_steps, 18) in ``[-1, 1]``: sums of sinusoids, seeded by ``seed``."""
    rng = np.random.default_rng([seed, 1])
    t = np.arange(n_steps)[:, None, None] * control_dt
    freq = rng.uniform(*COMMAND_FREQUENCIES, (1, 18, N_SINES))
    phase = rng.uniform(0.0, 2 * np.pi, (1, 18, N_SINES))
    amp = rng.uniform(0.0, COMMAND_AMPLITUDE / N_SINES, (1, 18, N_SINES))
    return np.clip((amp * np.sin(2 * np.pi * freq * t + phase)).sum(axis=2), -1.0, 1.0)


def _policy(env: gym.Env, policy: str, seed: int, n_steps: int) -> Callable[[int, Any, dict], np.ndarray]:
    if policy == "random":
        commands = random_commands(seed, n_steps, env.unwrapped.control_dt).astype(np.float32)
        return lambda k, obs, info: commands[k]
    if policy == "campc-privileged":
        from baselines.controllers import make_baseline

        ctrl = make_baseline("campc-privileged", env)
        ctrl.reset(seed)
        return lambda k, obs, info: ctrl.predict(obs, info)
    raise ValueError(f"policy must be one of {POLICIES}, got {policy!r}")


def error(nav: NavigationFilter, truth: dict[str, Any]) -> np.ndarray:
    """The estimate's error ``(eta, nu)`` against the true state (angle errors wrapped)."""
    eta, nu, _, _ = nav.state()
    e = np.concatenate((eta - truth["eta"], nu - truth["nu"]))
    e[3:6] = (e[3:6] + np.pi) % (2 * np.pi) - np.pi
    return e


def run_episode(
    level: int | dict[str, Any], seed: int, n_steps: int, policy: str = "random"
) -> tuple[np.ndarray, np.ndarray]:
    """The filter on one episode: errors (K + 1, 12) and covariances (K + 1, 12, 12).

    Row 0 is the estimate after :meth:`~NavigationFilter.reset`, row ``k`` after the ``k``-th update; an episode
    that ends early has fewer rows.
    """
    env = make_env(level, policy)
    try:
        base = env.unwrapped
        obs, info = env.reset(seed=seed)
        act = _policy(env, policy, seed, n_steps)
        nav = NavigationFilter(base.realism, base.params, control_dt=base.control_dt, physics_dt=base.physics_dt)
        nav.reset(info["t"], info["measurements"])
        errors, covs = [error(nav, base.true_state())], [nav.covariance()]
        for k in range(n_steps):
            obs, _, terminated, truncated, info = env.step(act(k, obs, info))
            nav.update(info["t"], info["measurements"], info["tau_cmd"])
            errors.append(error(nav, base.true_state()))
            covs.append(nav.covariance())
            if terminated or truncated:
                break
        return np.array(errors), np.array(covs)
    finally:
        env.close()


def nees(errors: np.ndarray, covs: np.ndarray) -> np.ndarray:
    """``e' P^-1 e`` per row."""
    return np.einsum("ki,ki->k", errors, np.linalg.solve(covs, errors[..., None])[..., 0])


def nees_bounds(n_episodes: int, dof: int = 12) -> tuple[float, float]:
    """Two-sided :data:`CONFIDENCE` bounds of the NEES averaged over ``n_episodes`` (chi-square, ``dof * N``)."""
    lo, hi = stats.chi2.ppf([(1 - CONFIDENCE) / 2, (1 + CONFIDENCE) / 2], dof * n_episodes) / n_episodes
    return float(lo), float(hi)


def summarize(runs: list[tuple[np.ndarray, np.ndarray]], level: Any) -> dict[str, object]:
    """Fraction of steps whose episode-averaged NEES lies in the bounds, per-component NEES, RMSE."""
    n_rows = min(e.shape[0] for e, _ in runs)
    runs = [(e[:n_rows], c[:n_rows]) for e, c in runs]
    n_ep = len(runs)
    avg = np.mean([nees(e, c) for e, c in runs], axis=0)[1:]  # the steps after updates
    lo, hi = nees_bounds(n_ep)
    errors = np.concatenate([e[1:] for e, _ in runs])
    variances = np.concatenate([np.diagonal(c[1:], axis1=1, axis2=2) for _, c in runs])
    rmse = np.sqrt(np.mean(errors**2, axis=0))
    per_component = np.mean(errors**2 / variances, axis=0)
    return {
        "level": level,
        "episodes": n_ep,
        "steps": int(avg.size),
        "fraction_in_bounds": round(float(np.mean((avg >= lo) & (avg <= hi))), 4),
        "fraction_below": round(float(np.mean(avg < lo)), 4),
        "fraction_above": round(float(np.mean(avg > hi)), 4),
        "bounds": [round(lo, 3), round(hi, 3)],
        "mean_nees": round(float(avg.mean()), 3),
        "nees_per_component": dict(zip(COMPONENTS, per_component.round(3).tolist(), strict=True)),
        "rmse": dict(zip(COMPONENTS, rmse.round(5).tolist(), strict=True)),
    }


def consistency(level: int, seeds: list[int], n_steps: int, policy: str = "random") -> dict[str, object]:
    """:func:`summarize` of the filter on one episode per seed at ``level``."""
    return summarize([run_episode(level, seed, n_steps, policy) for seed in seeds], level)


def main() -> None:
    """Print the consistency report (JSON) for the levels asked."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--episodes", type=int, default=20)
    ap.add_argument("--steps", type=int, default=250)
    ap.add_argument("--levels", type=int, nargs="+", default=[1, 2, 3])
    ap.add_argument("--seed", type=int, default=FIRST_SEED, help="first episode seed")
    ap.add_argument("--policy", choices=POLICIES, default="random")
    args = ap.parse_args()
    seeds = [args.seed + i for i in range(args.episodes)]
    out = [{**consistency(level, seeds, args.steps, args.policy), "policy": args.policy} for level in args.levels]
    print(json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
