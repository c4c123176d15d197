"""Training sweeps: one ordinary ``uvdms train`` run per seed and grid point, run locally or as Ray tasks.

:func:`sweep` (command line: ``uvdms sweep``) plans one run per seed (``--seeds``) and per point of the
hyperparameter grid (``--grid``, :func:`parse_grid`), checks every run's configuration before anything starts, runs
them, and writes a summary. Every seed is a ``training`` seed of the seed protocol (:mod:`uvdms_gym.seeds`) with all
the seeds its run derives from it (:func:`check_seeds`): no run sees a validation or test seed. Each run is a normal
run directory of :func:`agents.training.train.train` (``uvdms evaluate``, ``uvdms export-agent`` and
``uvdms train --resume`` take it), under ``--out``::

    <out>/<env id, '/' and ':' replaced by '_'>/<algo>_<seed>/              (no --grid)
    <out>/grid_<k>/<env id ...>/<algo>_<seed>/                             (grid point k)
    <out>/configs/<config file name>       the configuration the runs used (their config.yml names it)
    <out>/sweep.json, <out>/sweep.csv      the summary (:mod:`agents.distributed.report`; per run: seed, grid point,
                                           evaluation returns, episode length, steps, wall time, retries, status)

Backends: ``local`` trains the runs one after another in this process; ``ray`` submits each run as a Ray task
(through :func:`uvdms_gym.utils.cluster.ray_session`: a local instance, or the cluster at ``--address``). Both run
:func:`agents.distributed.worker.run_job` and produce the same files; with the same seed a run gives the same
evaluations either way (training is deterministic on the CPU with one torch thread). No shared filesystem is
needed: runs train in a temporary directory on their worker and come back to the driver as archives, and
checkpoints are shipped to a store on the driver's node as they are written, so that a run whose worker dies is
retried from its newest checkpoint (:mod:`agents.distributed.worker`; ``max_retries`` retries per run).

CPU accounting: a run declares the CPUs it keeps busy (:func:`run_cpus`): 1 with ``--vec-env dummy`` (the envs
step in the trainer's process), ``n_envs`` with ``subproc`` (one worker process per env; the trainer runs while
they wait) and with ``hybrid`` (env 0 in the trainer, the others in spinning workers, all at once). Ray never
starts more runs on a node than its CPUs allow, and a run that needs more CPUs
than any node has is an error before the sweep starts. The trainer uses one torch thread
(:func:`agents.training.train.train` sets it; Ray also sets ``OMP_NUM_THREADS`` to the task's CPUs), so a run never
uses more cores than it declared.
"""

from __future__ import annotations

import contextlib
import dataclasses
import itertools
import json
import logging
import time
import uuid
from collections.abc import Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any

import yaml

from agents.common.envs import ActionComponents, check_env_id, check_training_seed
from agents.common.threads import run_cpus
from agents.config import ConfigError
from agents.distributed.report import evaluation_summary, write_summary
from agents.distributed.worker import CheckpointStore, RunJob, StoreClient, relocate_records, run_job, unpack_run_dir
from agents.training.args import DEFAULT_GYM_PACKAGES
from agents.training.rundir import RunDirError, latest_checkpoint, run_dir_for, utc_now
from agents.training.spec import RunSpec
from uvdms_gym.seeds import SeedProtocolError
from uvdms_gym.utils.cluster import ray_session
from uvdms_gym.utils.kwargs import check_make_kwargs, parse_kv

log = logging.getLogger("agents.sweep")

BACKENDS: tuple[str, ...] = ("local", "ray")
"""Values of ``--backend``."""
STORE_PREFIX = "uvdms-sweep-store-"
"""Name prefix of the checkpoint-store actor of a Ray sweep (namespace :data:`STORE_NAMESPACE`)."""
STORE_NAMESPACE = "uvdms"
"""Ray namespace of the checkpoint-store actors."""


@dataclasses.dataclass(frozen=True)
class SweepResult:
    """A finished sweep.

    Attributes:
        out_dir: The sweep's ``--out``.
        rows: One summary row per run (:data:`SUMMARY_COLUMNS`), in plan order.
    """

    out_dir: Path
    rows: list[dict[str, Any]]

    @property
    def failed(self) -> list[dict[str, Any]]:
        """The rows of runs that did not complete."""
        return [row for row in self.rows if row["status"] != "completed"]


# ------------------------------------------------------------------------------------------------------
# Planning
# ------------------------------------------------------------------------------------------------------
def parse_grid(items: Sequence[str] | None) -> dict[str, list[Any]]:
    """Parse ``--grid`` items ``key=v1,v2,...`` into axes (values are YAML literals, as in ``--hyperparams``).

    ``learning_rate=1.0e-3,3.0e-4`` is an axis of two values; a bracketed YAML list (``'net_arch=[[64], [256]]'``)
    works as well, for values that contain commas themselves; a single value is an axis of one.

    Raises:
        ValueError: A malformed item (:func:`uvdms_gym.utils.kwargs.parse_kv`), a key given twice, an empty axis, or a
            value repeated within an axis.
    """
    items = list(items or ())
    keys = [item.partition("=")[0] for item in items]
    for key in keys:
        if keys.count(key) > 1:
            raise ValueError(f"--grid: key {key!r} is given twice (list its values once: {key}=v1,v2)")
    axes: dict[str, list[Any]] = {}
    for key, value in parse_kv(items, "--grid").items():
        if isinstance(value, str) and "," in value:
            try:
                value = yaml.safe_load(f"[{value}]")
            except yaml.YAMLError as exc:
                raise ValueError(f"--grid: the values of {key!r} ({value!r}) are not YAML literals") from exc
        values = value if isinstance(value, list) else [value]
        if not values or any(v == "" or v is None for v in values):
            raise ValueError(f"--grid: {key!r} needs at least one value (key=v1,v2,...), got {value!r}")
        for i, v in enumerate(values):
            if v in values[:i]:
                raise ValueError(f"--grid: {key!r} lists the value {v!r} twice")
        axes[key] = values
    return axes


def grid_points(axes: Mapping[str, Sequence[Any]]) -> list[dict[str, Any]]:
    """The Cartesian product of the axes, the last axis varying fastest (``[{}]`` without axes)."""
    keys = list(axes)
    return [dict(zip(keys, values)) for values in itertools.product(*(axes[k] for k in keys))]


def check_seeds(seeds: Sequence[int], n_envs: int = 1, n_eval_envs: int = 1) -> list[int]:
    """The seeds as a list, or a :class:`ValueError`: none, a repeated one, or one that is not a training seed.

    A training seed of the seed protocol (:mod:`uvdms_gym.seeds`) with all the seeds a run with ``n_envs`` training
    and ``n_eval_envs`` evaluation envs derives from it (:func:`agents.common.envs.check_training_seed`: a
    ``SeedProtocolError``, itself a ``ValueError``, naming the seed and its derivation).
    """
    seeds = [int(s) for s in seeds]
    if not seeds:
        raise ValueError("--seeds: give at least one seed")
    for i, seed in enumerate(seeds):
        if seed in seeds[:i]:
            raise ValueError(f"--seeds: seed {seed} is given twice (each seed is one run directory)")
        check_training_seed(seed, n_envs, n_eval_envs, "--seeds: training seed")
    return seeds


def plan_sweep(
    base: RunSpec,
    seeds: Sequence[int],
    *,
    grid: Mapping[str, Sequence[Any]] | None = None,
    components: ActionComponents | None = None,
) -> list[RunJob]:
    """Check the arguments and every run's configuration, and return the runs (seeds vary fastest).

    Every run is ``base`` with one of ``seeds`` and one grid point merged into its ``hyperparams``. ``components``
    are the base and filter factories a residual or filtered configuration needs (``uvdms sweep`` passes the
    composition layer's); without them such a configuration is refused here, before any run starts.

    Raises:
        ConfigError: Bad budget or configuration, a key in both ``hyperparams`` and ``grid``, ...
        EnvironmentNotFoundError: The env id is not registered.
        ValueError: Bad seeds (``uvdms_gym.seeds.SeedProtocolError``: one that is not a training seed with all its
            derived seeds, for the configuration of any grid point) or ``env_kwargs`` keys the environment does not
            take.
    """
    from agents.training.composition import composition_factories

    seeds = check_seeds(seeds)
    if base.total_timesteps is not None and base.total_timesteps < 1:
        raise ConfigError(f"--total-timesteps must be >= 1, got {base.total_timesteps}")
    check_env_id(base.env_id, base.gym_packages)
    check_make_kwargs(base.env_id, base.env_kwargs)
    axes = dict(grid or {})
    both = sorted(set(axes) & set(base.hyperparams))
    if both:
        raise ConfigError(f"--grid and --hyperparams both set {', '.join(map(repr, both))}")
    config_path = base.config_file
    config_text = config_path.read_text(encoding="utf-8") if config_path.is_file() else None
    jobs = []
    for index, point in enumerate(grid_points(axes)):
        where = f"grid point {index} ({_point_label(point)})" if axes else "the configuration"
        spec = base.replace(config_path=config_path, hyperparams={**base.hyperparams, **point})
        try:
            cfg = spec.resolve()
            composition_factories(cfg, components)  # a residual or the filter needs the components
        except ConfigError as exc:
            raise ConfigError(f"{where}: {exc}") from None
        try:
            check_seeds(seeds, cfg.n_envs, cfg.n_eval_envs)  # with this grid point's envs
        except SeedProtocolError as exc:
            raise SeedProtocolError(f"{where}: {exc}") from None
        assert config_text is not None  # resolve_config read the file
        out_subdir = f"grid_{index}" if axes else ""
        for seed in seeds:
            key = run_dir_for(out_subdir or ".", spec.env_id, spec.algo, seed).as_posix().removeprefix("./")
            jobs.append(
                RunJob(
                    key=key,
                    out_subdir=out_subdir,
                    spec=spec.replace(seed=seed),
                    config_name=config_path.name,
                    config_text=config_text,
                    num_cpus=run_cpus(cfg.n_envs, spec.vec_env),
                    grid_index=index if axes else None,
                    grid_point=point,
                    components=None if cfg.composition.is_plain else components,
                )
            )
    return jobs


def _point_label(point: Mapping[str, Any]) -> str:
    return " ".join(f"{k}={json.dumps(v)}" for k, v in point.items())


# ------------------------------------------------------------------------------------------------------
# Running
# ------------------------------------------------------------------------------------------------------
def sweep(
    algo: str,
    env_id: str,
    seeds: Sequence[int],
    *,
    env_kwargs: Mapping[str, Any] | None = None,
    config_path: str | Path | None = None,
    hyperparams: Mapping[str, Any] | None = None,
    grid: Mapping[str, Sequence[Any]] | None = None,
    total_timesteps: int | None = None,
    n_envs: int | None = None,
    vec_env: str = "dummy",
    gym_packages: Sequence[str] = DEFAULT_GYM_PACKAGES,
    backend: str = "local",
    address: str | None = None,
    num_cpus: int | None = None,
    max_retries: int = 3,
    out_dir: str | Path = "sweeps",
    components: ActionComponents | None = None,
) -> SweepResult:
    """Train one run per seed and grid point and write the summary (see the module docstring).

    Args:
        algo: Algorithm name.
        env_id: Environment id.
        seeds: Base seeds, one run each (distinct ``training`` seeds of :mod:`uvdms_gym.seeds`, with their derived
            seeds: :func:`check_seeds`).
        env_kwargs: ``gymnasium.make`` keyword arguments of every run.
        config_path: Configuration file (default ``train_configs/<algo>.yml``).
        hyperparams: Config overrides of every run.
        grid: Axes ``{key: [values]}`` (:func:`parse_grid`); every combination is run with every seed.
        total_timesteps: Steps per run (default: the configuration's ``n_timesteps``).
        n_envs: Training envs per run (default: the configuration's).
        vec_env: ``dummy`` or ``subproc``.
        gym_packages: Packages imported to register the env id.
        backend: ``local`` (one run after another in this process) or ``ray`` (one Ray task per run).
        address: Ray cluster address (``ray`` backend; ``None`` starts a local instance).
        num_cpus: CPUs of the local Ray instance (``ray`` backend without ``address``).
        max_retries: Retries of a run whose worker dies (``ray`` backend).
        out_dir: Where the run directories and the summary go.
        components: Base and filter factories of residual or filtered configurations (:func:`plan_sweep`).

    Returns:
        The summary rows.

    Raises:
        ConfigError, ValueError: Bad arguments (before any run starts).
        RunDirError: ``out_dir`` already holds a sweep.
        ConnectionError: The Ray cluster at ``address`` cannot be reached.
    """
    if backend not in BACKENDS:
        raise ConfigError(f"--backend must be one of {BACKENDS}, got {backend!r}")
    if max_retries < 0:
        raise ConfigError(f"--max-retries must be >= 0, got {max_retries}")
    if backend == "local" and (address is not None or num_cpus is not None):
        raise ConfigError("--address and --num-cpus are options of --backend ray")
    base = RunSpec(
        algo=algo,
        env_id=env_id,
        env_kwargs=env_kwargs or {},
        config_path=Path(config_path) if config_path is not None else None,
        total_timesteps=total_timesteps,
        n_envs=n_envs,
        hyperparams=hyperparams or {},
        vec_env=vec_env,
        gym_packages=tuple(gym_packages),
    )
    jobs = plan_sweep(base, seeds, grid=grid, components=components)
    out_dir = Path(out_dir)
    if (out_dir / "sweep.json").exists():
        raise RunDirError(f"{out_dir} already holds a sweep (sweep.json); choose another --out")
    for job in jobs:
        if (out_dir / job.key).exists():
            raise RunDirError(f"run directory {out_dir / job.key} exists; choose another --out")
    with contextlib.ExitStack() as stack:
        ray = stack.enter_context(ray_session(address=address, num_cpus=num_cpus)) if backend == "ray" else None
        if ray is not None:
            check_fits(ray, max(job.num_cpus for job in jobs))
        out_dir.mkdir(parents=True, exist_ok=True)
        config_copy = out_dir / "configs" / jobs[0].config_name
        config_copy.parent.mkdir(exist_ok=True)
        config_copy.write_text(jobs[0].config_text, encoding="utf-8")
        header = {
            "algo": algo,
            "env_id": env_id,
            "env_kwargs": dict(env_kwargs or {}),
            "seeds": [int(s) for s in seeds],
            "config": str(config_copy),
            "hyperparams": dict(hyperparams or {}),
            "grid": {k: list(v) for k, v in (grid or {}).items()},
            "total_timesteps": total_timesteps,
            "n_envs": n_envs,
            "vec_env": vec_env,
            "backend": backend,
            "address": address,
            "max_retries": max_retries,
            "started_utc": utc_now(),
        }
        rows: dict[str, dict[str, Any]] = {}
        runs = _run_ray(ray, jobs, out_dir, max_retries) if ray is not None else _run_local(jobs, out_dir)
        for job, row in runs:
            rows[job.key] = row
            write_summary(out_dir, header, [rows[j.key] for j in jobs if j.key in rows])
    header["finished_utc"] = utc_now()
    ordered = [rows[job.key] for job in jobs]
    write_summary(out_dir, header, ordered)
    return SweepResult(out_dir, ordered)


def _finish(job: RunJob, outcome: Any, out_dir: Path, first_start: float | None, attempts: int) -> dict[str, Any]:
    """Unpack a finished run under ``out_dir`` and return its summary row (or a failed row for an exception)."""
    row: dict[str, Any] = {
        "run": job.key,
        "seed": job.spec.seed,
        "grid": job.grid_index,
        "grid_point": dict(job.grid_point),
        "wall_time_s": round(time.time() - first_start, 3) if first_start is not None else None,
        "retries": max(attempts - 1, 0),
    }
    if isinstance(outcome, BaseException):
        return {**row, "status": "failed", "error": " ".join(str(outcome).split())[:2000]}
    run_dir = out_dir / job.key
    unpack_run_dir(outcome.archive, run_dir)
    relocate_records(run_dir, outcome.worker_root, str(out_dir))
    checkpoint = latest_checkpoint(run_dir)
    return {
        **row,
        "status": "completed",
        "node": outcome.node_id,
        "num_timesteps": checkpoint.num_timesteps if checkpoint else None,
        **evaluation_summary(run_dir),
    }


def _run_local(jobs: Sequence[RunJob], out_dir: Path) -> Iterator[tuple[RunJob, dict[str, Any]]]:
    """The runs one after another in this process (a crash ends the sweep: no retry)."""
    store = CheckpointStore()
    client = StoreClient(store, remote=False)
    for job in jobs:
        try:
            outcome: Any = run_job(job, client)
        except Exception as exc:  # one run's error is recorded in its row; the sweep goes on
            log.error("run %s failed: %s: %s", job.key, type(exc).__name__, exc)
            outcome = exc
        record = store.status().get(job.key, {})
        store.forget(job.key)
        yield job, _finish(job, outcome, out_dir, record.get("first_start"), record.get("attempts", 1))


def check_fits(ray: Any, need: int) -> None:
    """Raise :class:`ConfigError` if a run declaring ``need`` CPUs fits on no node (it would wait forever)."""
    largest = max((node.get("Resources", {}).get("CPU", 0) for node in ray.nodes() if node.get("Alive")), default=0)
    if need > largest:
        raise ConfigError(
            f"a run needs {need} CPUs (n_envs {need} with --vec-env subproc/hybrid) but the largest Ray node has "
            f"{largest:g}; "
            "lower --n-envs or use --vec-env dummy"
        )


def _run_ray(
    ray: Any, jobs: Sequence[RunJob], out_dir: Path, max_retries: int
) -> Iterator[tuple[RunJob, dict[str, Any]]]:
    """The runs as Ray tasks (``ray``: the connected module), yielded as they finish."""
    from ray.util.scheduling_strategies import NodeAffinitySchedulingStrategy

    here = ray.get_runtime_context().get_node_id()
    actor = (
        ray.remote(num_cpus=0, max_restarts=0)(CheckpointStore)
        .options(
            name=f"{STORE_PREFIX}{uuid.uuid4().hex[:12]}",
            namespace=STORE_NAMESPACE,
            scheduling_strategy=NodeAffinitySchedulingStrategy(node_id=here, soft=False),
        )
        .remote()
    )
    try:
        client = StoreClient(actor, remote=True)
        task = ray.remote(run_job)
        refs = {
            task.options(
                num_cpus=job.num_cpus, max_retries=max_retries, retry_exceptions=False, name=f"sweep {job.key}"
            ).remote(job, client): job
            for job in jobs
        }
        pending = list(refs)
        while pending:
            done, pending = ray.wait(pending, num_returns=1)
            for ref in done:
                job = refs[ref]
                try:
                    outcome: Any = ray.get(ref)
                except ray.exceptions.RayError as exc:  # a run's error or its last worker's death
                    cause = getattr(exc, "cause", None)
                    outcome = cause if isinstance(cause, Exception) else exc
                    log.error("run %s failed: %s: %s", job.key, type(outcome).__name__, outcome)
                record = ray.get(actor.status.remote()).get(job.key, {})
                ray.get(actor.forget.remote(job.key))
                yield job, _finish(job, outcome, out_dir, record.get("first_start"), record.get("attempts", 1))
    finally:
        ray.kill(actor)
