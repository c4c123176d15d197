"""Consistency of the navigation filter: NEES of ``(eta, nu)`` against the chi-square bounds, and RMSE, per level.

    python -m scripts.filter_consistency [--episodes 20] [--steps 250] [--levels 1 2 3] [--seed 0]

A standalone harness until the environment reports measurements itself: each episode is a random circle
(``uvdms/CircleTrack-v1``, ``case="random"``, ``hydro_randomization=0.3``) driven in velocity mode by smooth random
commands (sums of sinusoids from a seeded generator), stepped one physics substep at a time through the
environment's own velocity loop; the true state of every substep and the mean commanded force of every control step
are recorded once and reused at every level. Per level a :class:`~uvdms_gym.realism.sensors.SensorBank` samples the
truth at its due substeps, releases the samples each control step, and the
:class:`~uvdms_gym.realism.navigation.NavigationFilter` fuses them.

Per step ``k`` the average NEES over the ``N`` episodes, ``mean_i e_i' P_i^-1 e_i`` (12 dof), is compared with the
two-sided 95 % bounds ``chi2.ppf([0.025, 0.975], 12 N) / N``; the script prints (JSON) the fraction of steps inside
them and the RMSE of each of the 12 components, per level.
"""

from __future__ import annotations

import argparse
import json
from dataclasses import dataclass

import gymnasium as gym
import numpy as np
from scipy import stats

import uvdms_gym  # noqa: F401  (registers the ids)
from uvdms_gym.physics.params import UVDMSParams
from uvdms_gym.realism.config import LEVELS
from uvdms_gym.realism.navigation import NavigationFilter
from uvdms_gym.realism.sensors import SensorBank

ENV_ID = "uvdms/CircleTrack-v1"
"""The task the filter is checked on."""
ENV_KWARGS = {"case": "random", "hydro_randomization": 0.3}
"""Random circles with the hydrodynamics off by up to 30 % (the nominal model does not know)."""
COMMAND_AMPLITUDE = 0.4
"""Largest normalised velocity command of each sinusoid (of ``zeta_max``)."""
COMMAND_FREQUENCIES = (0.05, 0.5)
"""Range of the command sinusoids' frequencies, Hz."""
N_SINES = 3
"""Sinusoids summed per command component."""
SENSORS = ("ahrs", "gyro", "dvl", "depth", "fix", "encoders")
"""The sensors simulated (no obstacles: no sonar)."""
COMPONENTS = ("x", "y", "z", "phi", "theta", "psi", "u", "v", "w", "p", "q", "r")
"""Names of the 12 estimated components."""
CONFIDENCE = 0.95
"""Two-sided probability of the NEES bounds."""


@dataclass
class Truth:
    """One recorded episode: the state at every substep and the mean commanded force of every control step."""

    seed: int
    eta: np.ndarray  # (S + 1, 6)
    nu: np.ndarray  # (S + 1, 6)
    q: np.ndarray  # (S + 1, 12)
    qdot: np.ndarray  # (S + 1, 12)
    tau: np.ndarray  # (K, 18)
    n_substeps: int
    physics_dt: float
    control_dt: float


def _commands(rng: np.random.Generator, n_steps: int, control_dt: float) -> np.ndarray:
    """Smooth random velocity commands (n_steps, 18) in ``[-1, 1]``: sums of sinusoids."""
    t = np.arange(n_steps)[:, None, None] * control_dt
    freq = rng.uniform(*COMMAND_FREQUENCIES, (1, 18, N_SINES))
    phase = rng.uniform(0.0, 2 * np.pi, (1, 18, N_SINES))
    amp = rng.uniform(0.0, COMMAND_AMPLITUDE / N_SINES, (1, 18, N_SINES))
    return np.clip((amp * np.sin(2 * np.pi * freq * t + phase)).sum(axis=2), -1.0, 1.0)


def simulate(seed: int, n_steps: int) -> Truth:
    """Record one episode of ``n_steps`` control steps (module docstring)."""
    env = gym.make(ENV_ID, **ENV_KWARGS)
    try:
        base = env.unwrapped
        env.reset(seed=seed)
        sim, loop, kin = base._sim, base._loop, base._kin
        n_sub, dt, tau_max = base.n_substeps, base.physics_dt, base.tau_max
        commands = _commands(np.random.default_rng([seed, 1]), n_steps, base.control_dt)
        states = [sim.state()]
        taus = []
        applied: list[np.ndarray] = []

        def feedback(z: np.ndarray) -> np.ndarray:
            tau = loop.torque(z, dt)
            applied.append(np.clip(tau, -tau_max, tau_max))
            return tau

        for k in range(n_steps):
            st = states[-1]
            kin.set_state(st.eta, st.q, st.zeta)
            loop.begin(commands[k] * base.zeta_max)
            applied.clear()
            for _ in range(n_sub):
                sim.step(np.zeros(18), 1, feedback=feedback)
                states.append(sim.state())
            taus.append(np.mean(applied, axis=0))
        return Truth(
            seed=seed,
            eta=np.array([s.eta for s in states]),
            nu=np.array([s.nu for s in states]),
            q=np.array([s.q for s in states]),
            qdot=np.array([s.qdot for s in states]),
            tau=np.array(taus),
            n_substeps=n_sub,
            physics_dt=base.physics_dt,
            control_dt=base.control_dt,
        )
    finally:
        env.close()


def _sensor_values(truth: Truth, s: int) -> dict[str, np.ndarray]:
    eta, nu = truth.eta[s], truth.nu[s]
    return {
        "ahrs": eta[3:6],
        "gyro": nu[3:6],
        "dvl": nu[0:3],
        "depth": eta[2:3],
        "fix": eta[[0, 1, 2, 5]],
        "encoders": truth.q[s],
    }


def run_filter(truth: Truth, level: int, episode: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """The filter on one recorded episode at ``level``: errors (K + 1, 12) and covariances (K + 1, 12, 12).

    Row 0 is the estimate after :meth:`~NavigationFilter.reset`, row ``k`` after the ``k``-th update.
    """
    cfg = LEVELS[level]
    n_sub, dt = truth.n_substeps, truth.physics_dt
    bank = SensorBank(cfg, physics_dt=dt, control_substeps=n_sub, names=SENSORS)
    nav = NavigationFilter(cfg, UVDMSParams(), control_dt=truth.control_dt, physics_dt=dt)
    bank.reset(truth.seed, episode, _sensor_values(truth, 0))
    nav.reset(0.0, bank.initial())
    errors, covs = [_error(nav, truth, 0)], [nav.covariance()]
    for k in range(truth.tau.shape[0]):
        for s in range(k * n_sub + 1, (k + 1) * n_sub + 1):
            due = bank.due(s)
            if due:
                values = _sensor_values(truth, s)
                bank.sample(s, {n: values[n] for n in due})
        s_now = (k + 1) * n_sub
        nav.update(s_now * dt, bank.release(s_now), truth.tau[k])
        errors.append(_error(nav, truth, s_now))
        covs.append(nav.covariance())
    return np.array(errors), np.array(covs)


def _error(nav: NavigationFilter, truth: Truth, s: int) -> np.ndarray:
    eta, nu, _, _ = nav.state()
    e = np.concatenate((eta - truth.eta[s], nu - truth.nu[s]))
    e[3:6] = (e[3:6] + np.pi) % (2 * np.pi) - np.pi
    return e


def nees(errors: np.ndarray, covs: np.ndarray) -> np.ndarray:
    """``e' P^-1 e`` per row."""
    return np.einsum("ki,ki->k", errors, np.linalg.solve(covs, errors[..., None])[..., 0])


def consistency(truths: list[Truth], level: int) -> dict[str, object]:
    """Fraction of steps whose episode-averaged NEES lies in the 95 % bounds, and the RMSE per component."""
    runs = [run_filter(tr, level) for tr in truths]
    n_ep = len(runs)
    avg = np.mean([nees(e, c) for e, c in runs], axis=0)[1:]  # the steps after updates
    lo, hi = stats.chi2.ppf([(1 - CONFIDENCE) / 2, (1 + CONFIDENCE) / 2], 12 * n_ep) / n_ep
    errors = np.concatenate([e[1:] for e, _ in runs])
    rmse = np.sqrt(np.mean(errors**2, axis=0))
    return {
        "level": level,
        "episodes": n_ep,
        "steps": int(avg.size),
        "fraction_in_bounds": float(np.mean((avg >= lo) & (avg <= hi))),
        "fraction_below": float(np.mean(avg < lo)),
        "fraction_above": float(np.mean(avg > hi)),
        "bounds": [float(lo), float(hi)],
        "mean_nees": float(avg.mean()),
        "rmse": dict(zip(COMPONENTS, rmse.round(6).tolist(), strict=True)),
    }


def main() -> None:
    """Print the consistency report (JSON) for the levels asked."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--episodes", type=int, default=20)
    ap.add_argument("--steps", type=int, default=250)
    ap.add_argument("--levels", type=int, nargs="+", default=[1, 2, 3])
    ap.add_argument("--seed", type=int, default=0, help="first episode seed")
    args = ap.parse_args()
    truths = [simulate(args.seed + i, args.steps) for i in range(args.episodes)]
    print(json.dumps([consistency(truths, level) for level in args.levels], indent=2))


if __name__ == "__main__":
    main()
