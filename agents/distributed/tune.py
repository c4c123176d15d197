"""Hyperparameter search (``uvdms tune``): Ray Tune drives Optuna's TPE sampler over an RL-Zoo-style search space.

:func:`tune` samples ``n_trials`` configurations from ``train_configs/search_spaces/<algo>.yml``
(:mod:`agents.distributed.search_space`) with Optuna's ``TPESampler`` (seeded; through
``ray.tune.search.optuna.OptunaSearch``), trains each as an ordinary :func:`agents.training.train.train` run of
``--total-timesteps`` steps in a temporary directory of its Ray worker, and reports every evaluation's mean
return (``eval_return``, at ``timesteps``) to Tune. An ``ASHAScheduler`` on that report stops the trials that
fall behind at its rungs (``grace_period``, ``grace_period * reduction_factor``, ... steps); Optuna is told
those trials were pruned (as RL Zoo's pruner does). A trial that trains to the end reports a last time with
``completed`` set; the best configuration is the completed trial with the highest last evaluation return.

Every trial trains with the same ``--seed`` (common random numbers: trials differ only in their hyperparameters), a
training seed of the seed protocol (:mod:`uvdms_gym.seeds`): it and every seed a trial derives from it
(:func:`agents.common.envs.check_training_seed`, the evaluations included) are in the ``training`` split, never a
test split, or the search is refused before Ray starts. The sampler is seeded with ``--seed`` too, but with more
than one trial at a time the order in which results arrive (and so what TPE sees when it samples) depends on timing;
``--max-concurrent 1`` makes a search repeatable. CPUs: a trial declares :func:`agents.common.threads.run_cpus` (as
a sweep run).

Output under ``--out``: ``<algo>.yml`` (the best configuration as an entry of an RL Zoo hyperparameter file, in
the format of ``train_configs/<algo>.yml``, so ``uvdms train --algo A --env ID --config <out>/<algo>.yml``
trains it), ``tune.json`` / ``tune.csv`` (every trial: its sample, last evaluation return, steps, status) and
``ray_results/`` (Ray Tune's experiment records on the driver; no trial checkpoints are kept).
"""

from __future__ import annotations

import csv
import dataclasses
import functools
import json
import shutil
import tempfile
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from stable_baselines3.common.callbacks import BaseCallback

from agents.algos import ALGOS
from agents.common.envs import check_env_id, check_training_seed
from agents.common.threads import run_cpus
from agents.config import ConfigError, default_config_path
from agents.config.zoo import TRAIN_OPTIONS, zoo_entry
from agents.distributed.search_space import SearchSpace, default_search_space_path, load_search_space
from agents.distributed.sweep import check_fits
from agents.training.args import DEFAULT_GYM_PACKAGES, VEC_ENV_TYPES
from agents.training.rundir import RunDirError, latest_checkpoint, utc_now
from agents.training.spec import RunSpec
from uvdms_gym.utils.cluster import ray_session
from uvdms_gym.utils.io import to_jsonable, write_json_atomic
from uvdms_gym.utils.kwargs import check_make_kwargs

METRIC = "eval_return"
"""The reported metric: mean return of an evaluation (evaluation callback, ``alive_bonus`` included)."""
TIME_ATTR = "timesteps"
"""The reported time: the model's ``num_timesteps`` at the evaluation (ASHA's rungs are in these units)."""
TRIAL_COLUMNS: tuple[str, ...] = ("trial", "status", METRIC, TIME_ATTR, "eval_episode_length", "params", "error")
"""Columns of ``tune.csv``."""


@dataclasses.dataclass(frozen=True)
class TrialSetup:
    """What every trial trains (plain data, shipped to the Ray workers).

    Attributes:
        spec: What every trial trains: its ``hyperparams`` are the fixed keys (``--hyperparams``), its
            ``total_timesteps`` the steps per trial, its ``seed`` the training seed of every trial; the sampled keys
            are merged in per trial and ``config_path`` is replaced by the worker's copy of ``config_text``.
        config_name: File name of the configuration.
        config_text: Its text (no shared filesystem).
        policy_kwargs: The configuration's ``policy_kwargs`` (sampled ``policy_kwargs.*`` keys are merged in).
        space: The search space (without the fixed keys).
        components: Base and filter factories of a residual or filtered configuration
            (:class:`agents.common.envs.ActionComponents`; ``None``: none).
    """

    spec: RunSpec
    config_name: str
    config_text: str
    policy_kwargs: Mapping[str, Any]
    space: SearchSpace
    components: Any = None

    def hyperparams(self, sample: Mapping[str, Any]) -> dict[str, Any]:
        """The config overrides of a trial: the fixed keys and the sample's."""
        return {**self.spec.hyperparams, **self.space.hyperparams(sample, self.policy_kwargs)}


@dataclasses.dataclass(frozen=True)
class TuneResult:
    """A finished search.

    Attributes:
        out_dir: ``--out``.
        best_config: The best configuration file (``<out>/<algo>.yml``).
        best: The best trial's row (``params``, ``hyperparams``, ``eval_return``, ...).
        trials: One row per trial.
    """

    out_dir: Path
    best_config: Path
    best: dict[str, Any]
    trials: list[dict[str, Any]]


class NoTrialCompletedError(RuntimeError):
    """Every trial of a search was pruned or failed (``tune.json`` records them)."""


class ReportEvaluations(BaseCallback):
    """``after_eval`` callback of :func:`agents.training.train.train`: reports each evaluation to Ray Tune.

    Args:
        report: Called with the metrics (``ray.tune.report``).
    """

    def __init__(self, report: Any) -> None:
        super().__init__()
        self.report = report
        self.last: dict[str, Any] | None = None

    def _on_step(self) -> bool:
        evaluation = self.parent
        lengths = getattr(evaluation, "evaluations_length", None)
        self.last = {
            METRIC: float(evaluation.last_mean_reward),
            TIME_ATTR: int(self.num_timesteps),
            "eval_episode_length": float(np.mean(lengths[-1])) if lengths else None,
            "completed": 0,
        }
        self.report(dict(self.last))
        return True


def run_trial(config: dict[str, Any], setup: TrialSetup) -> None:
    """The Ray Tune trainable: train one sampled configuration, reporting every evaluation, then ``completed``."""
    import os

    from ray import tune as ray_tune

    from agents.training.train import train_run

    root = Path(tempfile.mkdtemp(prefix="uvdms-trial-", dir=os.getcwd()))  # Tune's trial directory on the worker
    try:
        config_path = root / setup.config_name
        config_path.write_text(setup.config_text, encoding="utf-8")
        reporter = ReportEvaluations(ray_tune.report)
        spec = setup.spec.replace(config_path=config_path, hyperparams=setup.hyperparams(config))
        run_dir = train_run(
            spec, out_dir=root / "runs", progress=False, after_eval=[reporter], components=setup.components
        )
        if reporter.last is None:
            raise ConfigError("the trial never evaluated (eval_freq larger than --total-timesteps)")
        checkpoint = latest_checkpoint(run_dir)
        final = {**reporter.last, "completed": 1}
        if checkpoint is not None:
            final[TIME_ATTR] = checkpoint.num_timesteps
        ray_tune.report(final)
    finally:
        shutil.rmtree(root, ignore_errors=True)


def _check_search_options(
    algo: str, vec_env: str, n_trials: int, n_startup_trials: int, reduction_factor: float, max_concurrent: int | None
) -> None:
    """The search's own arguments (before any configuration is read)."""
    if algo not in ALGOS:
        raise ConfigError(f"unknown algorithm {algo!r}; choose one of {sorted(ALGOS)}")
    if vec_env not in VEC_ENV_TYPES:
        raise ConfigError(f"vec_env must be one of {VEC_ENV_TYPES}, got {vec_env!r}")
    for name, value, low in (("--n-trials", n_trials, 1), ("--n-startup-trials", n_startup_trials, 0)):
        if value < low:
            raise ConfigError(f"{name} must be >= {low}, got {value}")
    if not reduction_factor > 1:
        raise ConfigError(f"--reduction-factor must be > 1, got {reduction_factor}")
    if max_concurrent is not None and max_concurrent < 1:
        raise ConfigError(f"--max-concurrent must be >= 1, got {max_concurrent}")


def _trial_budget(cfg: Any, grace_period: int | None) -> tuple[int, int]:
    """``(steps per trial, ASHA's grace period)``: trials evaluate within their budget, and ASHA waits a while."""
    budget = cfg.n_timesteps
    if not 0 < cfg.eval_freq <= budget:
        raise ConfigError(
            f"eval_freq ({cfg.eval_freq}) must be in 1 .. --total-timesteps ({budget}): trials report evaluations"
        )
    grace = cfg.eval_freq if grace_period is None else grace_period
    if not 0 < grace <= budget:
        raise ConfigError(f"--grace-period must be in 1 .. --total-timesteps ({budget}), got {grace}")
    return budget, grace


def _searcher(space: SearchSpace, seed: int, n_startup_trials: int) -> Any:
    """``OptunaSearch`` with a seeded TPE sampler; a trial stopped by the scheduler is told to Optuna as pruned."""
    import optuna
    from ray.tune.search.optuna import OptunaSearch

    class _PruningAwareOptunaSearch(OptunaSearch):
        def on_trial_complete(self, trial_id: str, result: dict | None = None, error: bool = False) -> None:
            if result is not None and not error and not result.get("completed"):
                result = None  # no final value: Optuna records the trial as pruned (its intermediate values stay)
            super().on_trial_complete(trial_id, result, error)

    sampler = optuna.samplers.TPESampler(seed=seed, n_startup_trials=n_startup_trials)
    return _PruningAwareOptunaSearch(space=space.define_by_run, metric=METRIC, mode="max", sampler=sampler)


def _check_space(space: SearchSpace, check: Any) -> None:
    """Validate the config keys of every choice and bound of the space (``check(sample)`` raises ConfigError)."""
    base = space.example()
    check(base)
    for p in space.params:
        options = p.choices if p.type == "categorical" else [p.low, p.high]
        for value in options or ():
            if p.type == "int":
                value = int(value)
            check({**base, p.name: value})


def tune(
    algo: str,
    env_id: str,
    n_trials: int,
    *,
    env_kwargs: Mapping[str, Any] | None = None,
    config_path: str | Path | None = None,
    search_space_path: str | Path | None = None,
    hyperparams: Mapping[str, Any] | None = None,
    total_timesteps: int | None = None,
    n_envs: int | None = None,
    vec_env: str = "dummy",
    gym_packages: Sequence[str] = DEFAULT_GYM_PACKAGES,
    seed: int = 0,
    n_startup_trials: int = 10,
    grace_period: int | None = None,
    reduction_factor: float = 3.0,
    max_concurrent: int | None = None,
    address: str | None = None,
    num_cpus: int | None = None,
    out_dir: str | Path = "tune",
    components: Any = None,
) -> TuneResult:
    """Search hyperparameters and write the best configuration (see the module docstring).

    Args:
        algo: Algorithm name.
        env_id: Environment id.
        n_trials: Number of sampled configurations.
        env_kwargs: ``gymnasium.make`` keyword arguments.
        config_path: Base configuration (default ``train_configs/<algo>.yml``).
        search_space_path: Search space (default ``train_configs/search_spaces/<algo>.yml``).
        hyperparams: Fixed config keys (their parameters leave the search).
        total_timesteps: Steps per trial (default: the configuration's ``n_timesteps``).
        n_envs: Training envs per trial.
        vec_env: ``dummy`` or ``subproc``.
        gym_packages: Packages imported to register the env id.
        seed: Training seed of every trial (a ``training`` seed of :mod:`uvdms_gym.seeds`, with its derived seeds)
            and seed of the TPE sampler.
        n_startup_trials: Trials sampled at random before TPE models the results (Optuna's default 10).
        grace_period: Steps before ASHA may stop a trial (default: the configuration's ``eval_freq``).
        reduction_factor: ASHA keeps the best ``1 / reduction_factor`` of the trials at each rung.
        max_concurrent: Trials at a time (default: as many as the CPUs allow).
        address: Ray cluster address (``None``: a local instance).
        num_cpus: CPUs of the local Ray instance.
        out_dir: Output folder.
        components: Base and filter factories (:class:`agents.common.envs.ActionComponents`) of a residual or filtered
            configuration (``uvdms tune`` passes the composition layer's); without them such a configuration is
            refused before Ray starts.

    Raises:
        ConfigError, ValueError: Bad arguments, configuration or search space (before Ray starts); a seed that is
            not a training seed is a ``uvdms_gym.seeds.SeedProtocolError``.
        RunDirError: ``out_dir`` already holds a search.
        NoTrialCompletedError: No trial completed.
    """
    from agents.training.composition import composition_factories

    _check_search_options(algo, vec_env, n_trials, n_startup_trials, reduction_factor, max_concurrent)
    spec = _run_spec(
        algo,
        env_id,
        env_kwargs=dict(env_kwargs or {}),
        config_path=Path(config_path) if config_path is not None else default_config_path(algo),
        seed=seed,
        total_timesteps=total_timesteps,
        n_envs=n_envs,
        hyperparams=dict(hyperparams or {}),
        vec_env=vec_env,
        gym_packages=tuple(gym_packages),
    )
    cfg = spec.resolve()
    check_training_seed(seed, cfg.n_envs, cfg.n_eval_envs, "--seed")  # the seed of every trial
    composition_factories(cfg, components)  # a residual or the filter needs the components
    budget, grace = _trial_budget(cfg, grace_period)
    space_path = Path(search_space_path) if search_space_path is not None else default_search_space_path(algo)
    setup = _trial_setup(spec.replace(total_timesteps=budget), cfg, space_path, components)
    out_dir = _new_out_dir(Path(out_dir))
    started = utc_now()
    scheduler_options = {"max_t": budget, "grace_period": grace, "reduction_factor": reduction_factor}
    trials = _run_trials(
        setup,
        functools.partial(_searcher, setup.space, seed, n_startup_trials),
        scheduler_options,
        run_cpus(cfg.n_envs, vec_env),
        n_trials=n_trials,
        max_concurrent=max_concurrent,
        address=address,
        num_cpus=num_cpus,
        out_dir=out_dir,
    )
    header = {
        "algo": algo,
        "env_id": env_id,
        "env_kwargs": spec.env_kwargs,
        "config": str(spec.config_path),
        "search_space": str(space_path),
        "hyperparams": spec.hyperparams,
        "n_trials": n_trials,
        "total_timesteps": budget,
        "seed": seed,
        "n_startup_trials": n_startup_trials,
        "grace_period": grace,
        "reduction_factor": reduction_factor,
        "address": address,
        "started_utc": started,
        "finished_utc": utc_now(),
    }
    return _write_results(out_dir, spec, header, trials)


def _new_out_dir(out_dir: Path) -> Path:
    """``out_dir``, made; refused if it already holds a search."""
    if (out_dir / "tune.json").exists():
        raise RunDirError(f"{out_dir} already holds a search (tune.json); choose another --out")
    out_dir.mkdir(parents=True, exist_ok=True)
    return out_dir


def _write_results(out_dir: Path, spec: RunSpec, header: Mapping[str, Any], trials: list[dict]) -> TuneResult:
    """Write ``tune.json``, ``tune.csv`` and the best completed trial's configuration (``<algo>.yml``).

    Raises:
        NoTrialCompletedError: No trial completed (``tune.json`` and ``tune.csv`` are written first).
    """
    completed = [t for t in trials if t["status"] == "completed" and t[METRIC] is not None]
    if not completed:
        _write_trials(out_dir, header, trials, None)
        raise NoTrialCompletedError(f"no trial completed (see {out_dir / 'tune.json'})")
    best = max(completed, key=lambda t: t[METRIC])
    best_cfg = spec.replace(hyperparams=best["hyperparams"], total_timesteps=None).resolve()
    best_file = write_best_config(out_dir / f"{spec.algo}.yml", best_cfg.to_entry(), spec.env_id, header, best)
    _write_trials(out_dir, header, trials, best)
    return TuneResult(out_dir, best_file, best, trials)


def _run_spec(algo: str, env_id: str, **options: Any) -> RunSpec:
    """The run every trial starts from (the env id and its ``gymnasium.make`` keywords checked first)."""
    check_env_id(env_id, options["gym_packages"])
    check_make_kwargs(env_id, options["env_kwargs"])
    return RunSpec(algo=algo, env_id=env_id, **options)


def _trial_setup(spec: RunSpec, cfg: Any, space_path: Path, components: Any) -> TrialSetup:
    """What every trial needs; every choice and bound of the search space checked to give a valid configuration."""
    space = load_search_space(space_path).without(spec.hyperparams)
    if not space.params:
        raise ConfigError(f"{space_path}: --hyperparams fix every parameter of the search space; nothing to search")
    setup = TrialSetup(
        spec=spec,
        config_name=spec.config_path.name,
        config_text=spec.config_path.read_text(encoding="utf-8"),
        policy_kwargs=dict(cfg.policy_kwargs),
        space=space,
        components=None if cfg.composition.is_plain else components,
    )

    def check(sample: Mapping[str, Any]) -> None:
        try:
            setup.spec.replace(hyperparams=setup.hyperparams(sample)).resolve()
        except ConfigError as exc:
            raise ConfigError(f"{space_path}: a sample does not give a valid configuration: {exc}") from None

    _check_space(space, check)
    return setup


def _run_trials(
    setup: TrialSetup,
    searcher: Callable[[], Any],
    scheduler_options: Mapping[str, Any],
    cpus: int,
    *,
    n_trials: int,
    max_concurrent: int | None,
    address: str | None,
    num_cpus: int | None,
    out_dir: Path,
) -> list[dict[str, Any]]:
    """Run the trials on Ray Tune (``searcher()``'s samples, ASHA with ``scheduler_options``, ``cpus`` per trial).

    Returns:
        One row per trial (:func:`_trial_row`).
    """
    with ray_session(address=address, num_cpus=num_cpus) as ray:
        from ray import tune as ray_tune
        from ray.tune.schedulers import ASHAScheduler

        check_fits(ray, cpus)
        scheduler = ASHAScheduler(
            time_attr=TIME_ATTR,
            stop_last_trials=False,  # a trial ends by itself (its last report says completed)
            **scheduler_options,
        )
        tuner = ray_tune.Tuner(
            ray_tune.with_resources(ray_tune.with_parameters(run_trial, setup=setup), {"cpu": cpus}),
            tune_config=ray_tune.TuneConfig(
                metric=METRIC,
                mode="max",
                search_alg=searcher(),
                scheduler=scheduler,
                num_samples=n_trials,
                max_concurrent_trials=max_concurrent,
            ),
            run_config=ray_tune.RunConfig(
                name="tune", storage_path=str((out_dir / "ray_results").resolve()), verbose=0
            ),
        )
        grid = tuner.fit()
        return [_trial_row(grid[i], setup) for i in range(len(grid))]


def _trial_row(result: Any, setup: TrialSetup) -> dict[str, Any]:
    metrics = result.metrics or {}
    params = {p.name: result.config.get(p.name) for p in setup.space.params}
    if result.error is not None:
        status = "error"
    elif metrics.get("completed"):
        status = "completed"
    else:
        status = "pruned"
    return {
        "trial": metrics.get("trial_id") or Path(result.path).name,
        "status": status,
        METRIC: metrics.get(METRIC),
        TIME_ATTR: metrics.get(TIME_ATTR),
        "eval_episode_length": metrics.get("eval_episode_length"),
        "params": params,
        "hyperparams": setup.hyperparams(params),
        "error": " ".join(str(result.error).split())[:2000] if result.error is not None else None,
    }


def _write_trials(out_dir: Path, header: Mapping[str, Any], trials: list[dict], best: dict | None) -> None:
    write_json_atomic(out_dir / "tune.json", to_jsonable({"tune": dict(header), "best": best, "trials": trials}))
    with (out_dir / "tune.csv").open("w", encoding="utf-8", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=TRIAL_COLUMNS)
        writer.writeheader()
        for trial in trials:
            row = {k: trial.get(k) for k in TRIAL_COLUMNS}
            row["params"] = json.dumps(to_jsonable(trial["params"]), sort_keys=True)
            writer.writerow({k: "" if v is None else v for k, v in row.items()})


def write_best_config(
    path: Path, flat: Mapping[str, Any], env_id: str, header: Mapping[str, Any], best: Mapping[str, Any]
) -> Path:
    """Write a configuration as the entry of ``env_id`` in an RL Zoo hyperparameter file (``train_configs`` format).

    Args:
        path: The file.
        flat: The flat entry (``TrainConfig.to_entry()``).
        env_id: Its key.
        header: The search's arguments (written as comments).
        best: The best trial's row (comments).
    """
    entry, options = zoo_entry(flat)
    data: dict[str, Any] = {env_id: entry}
    if options:
        data[TRAIN_OPTIONS] = {env_id: options}
    comments = [
        f"Best of {header['n_trials']} trials of `uvdms tune --algo {header['algo']} --env {env_id}` "
        f"({header['finished_utc']}): trial {best['trial']}, last evaluation return {best[METRIC]:.4g} after "
        f"{best[TIME_ATTR]} steps.",
        f"Base configuration {header['config']}, search space {header['search_space']}, fixed "
        f"{json.dumps(to_jsonable(header['hyperparams']))}, seed {header['seed']}.",
        f"Sampled: {json.dumps(to_jsonable(best['params']), sort_keys=True)}.",
        f"Train with: uvdms train --algo {header['algo']} --env {env_id} --config {path}",
    ]
    text = "".join(f"# {line}\n" for line in comments)
    text += yaml.safe_dump(to_jsonable(data), sort_keys=False, default_flow_style=None, width=120)
    path.write_text(text, encoding="utf-8")
    return path
