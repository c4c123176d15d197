"""Leaderboard: the baselines and trained agents ranked on collisions and tracking error, with bootstrap CIs.

:func:`run_leaderboard` evaluates a set of **entries** (the named baselines ``mpc``, ``campc``, ``campc-di``,
``campc-nndi``, every agent folder (one agent, or one per training seed) in the shipped-agents directory, and
any agent checkpoint given by path) on a **task suite** (:data:`TASKS`: the paper's Case 1, Case 2 and
transport, plus held-out randomised variants with ``hydro_randomization=0.3``) and writes ``leaderboard.md``,
``leaderboard.csv``, one JSON per entry, PNG plots (learning curves too, for the agents that recorded them) and
``index.html``, all of it as one self-contained web page (:mod:`~leaderboard.webpage`).
The ``uvdms leaderboard`` command (:mod:`leaderboard.cli`) wraps it. Modules: :mod:`~leaderboard.tasks` (task
suite, tracks, seeds), :mod:`~leaderboard.entries`, :mod:`~leaderboard.registry` (name or path -> controller),
:mod:`~leaderboard.stats` (bootstrap CIs, multi-seed IQMs, ranking), :mod:`~leaderboard.cache`,
:mod:`~leaderboard.jobs`, :mod:`~leaderboard.runner`, :mod:`~leaderboard.report` and :mod:`~leaderboard.plots`;
this package re-exports their public names.

Tracks
    Entries are ranked separately in two tracks, by the action mode they command: ``velocity`` (``mpc``,
    ``campc``, agents unless their ``env_kwargs`` say ``action_mode: torque``) and ``torque``
    (``campc-di``, ``campc-nndi``). An entry runs only on its own track's action mode. An agent runs only on
    the tasks of the environment id it was trained on (a CircleTrack agent on every circle task, including
    the case it was not trained on; a Transport agent on the transport tasks); baselines run on every task.
    Any version of the environment counts: the task suite names ``uvdms/CircleTrack-v0`` and
    ``uvdms/Transport-v0``, and an agent trained on ``-v1`` runs the same tasks on ``-v1``
    (:meth:`Entry.task_spec`). The versions share dynamics, tasks, observations and costs and differ only in the
    reward, so every metric but ``return`` (and so the ranking) is independent of the version.

Multi-seed entries
    A folder whose sub-folders are named ``seed_<k>`` (:data:`SEED_FOLDER_PREFIX`), each an agent folder of its
    own (a weights-only export, a shipped agent folder or a run directory) trained with ``--seed k``, is **one**
    entry (:func:`multi_seed_entry`): ``trained_agents/<entry>/seed_0/``, ``seed_1/``, ``seed_2/``. It needs at
    least :data:`MIN_TRAINING_SEEDS` (2) seed folders; shipped learned entries should have
    :data:`RECOMMENDED_TRAINING_SEEDS` (3), fewer are accepted with a warning. Other sub-folders and files (a
    README) are ignored. Refused with an error: a folder that is also an agent itself, a ``seed_*`` name that is
    not ``seed_<integer>`` or repeats a seed, a seed folder that is not an agent (or holds seeds itself), a run
    inside ``seed_<k>`` whose ``config.yml``/``meta.json`` records another seed, seeds trained on different
    environments (id, keyword arguments or action mode) and two seeds with identical model files. Every seed
    runs every evaluation seed of the entry's tasks; each (entry, training seed, task, evaluation seed) episode
    is cached on its own (the seed's member entry ``<entry>/seed_<k>``, keyed by its own checksum), and the
    leaderboard reports one row per task for the whole entry (``<entry> (3 seeds)``, ``n`` = seeds x episodes).
    A single agent folder keeps working unchanged.

Learning curves
    A run whose evaluation callback ran records the benchmark's metrics of its evaluation episodes against
    environment steps in ``learning_curve.json`` (:mod:`agents.common.learning_curve`, kept through ``--resume``,
    copied by exports and ``scripts.ship_agent``). For every agent entry with such files the leaderboard writes
    ``plots/learning_curves_<entry>.png``: success rate and position RMSE against environment steps, every
    seed's curve and, at the step counts every seed has, the mean over seeds with a 95 % bootstrap interval
    (:func:`bootstrap_ci` over the seeds' values, :func:`learning_curve_stats`).

Seeds
    Episode ``i`` of every task uses seed ``SEED_BASE + i`` (:data:`SEED_BASE` = 2,000,000,000), far above
    the training scheme of :mod:`agents.training.train` (training envs ``seed + 1000 k + i``, its evaluation envs
    ``seed + 1,000,000 + i``). Every integer stored under a key containing ``seed`` in an agent's
    ``meta.json``, ``config.yml`` or ``agent.json`` is collected (for a seed of a multi-seed entry also its
    ``k``) and :func:`check_seed_disjointness` refuses to run if an evaluation seed is among them (naming the
    seed folder for a multi-seed entry).

Statistics
    Per entry and task, every per-episode metric of :func:`uvdms_gym.evaluation.run_episode` is aggregated as
    its mean with a 95 % bootstrap confidence interval (:func:`bootstrap_ci`: ``scipy.stats.bootstrap``,
    BCa, 9,999 resamples, fixed seed; the percentile method if BCa is not finite; an all-equal sample gives
    the zero-width interval ``[x, x]``; fewer than two values give no interval). Two per-episode 0/1
    indicators are added, ``contact_free`` (no physical contact) and ``contact_free_success`` (the episode's
    ``success`` and no contact); their rates, like the success rate, are means of 0/1 values. The paper's
    tasks have a fixed start and no randomisation, so the episodes of a deterministic controller there are
    identical and their intervals have zero width; the randomised tasks carry the spread. Tables print an interval as
    ``mean ± h`` with ``h = max(mean - low, high - mean)`` (bootstrap intervals are asymmetric; the CSV and
    JSON hold the exact bounds).

    A multi-seed entry's cell (entry, task, metric) is the matrix of its scores, training seeds x evaluation
    episodes (every seed ran the same evaluation seeds), and is aggregated as Agarwal et al. (NeurIPS 2021,
    the ``rliable`` library) recommend (:func:`aggregate_runs`): the point estimate is the **interquartile mean**
    (IQM, :func:`iqm`: ``scipy.stats.trim_mean(values, 0.25)`` of the pooled matrix, robust to a diverged seed
    or episode), except for the three rates, which stay the fraction of all seeds x episodes (an IQM of 0/1
    values is ``clip(2 p - 1/2, 0, 1)`` of the rate ``p``: a 75 % rate would print as 1.00 and tie a perfect
    entry); the interval is a 95 % **stratified bootstrap** interval (:func:`stratified_bootstrap_ci`: 9,999
    resamples, fixed seed, percentile method): the strata are the evaluation episodes, and each resample draws,
    for every episode independently, as many training seeds as it has, with replacement (rliable's
    ``StratifiedBootstrap`` with the episodes as its tasks, ``task_bootstrap=False``). [D] Why this scheme:
    the evaluation seeds are fixed by the benchmark and the same for every entry (like rliable's fixed task
    set), so the question the interval answers is how the entry would score if trained again with other seeds,
    the variability that dominates RL results and that one seed cannot show. Resampling episodes within each
    seed instead would give zero-width intervals on the paper's deterministic tasks however much the seeds
    differ (all of a seed's episodes are identical there); resampling the episodes too (rliable's
    ``task_bootstrap=True``) would mix in the choice of evaluation seeds, which is not a property of the entry.
    Missing values (an episode without an RMSE) are left out of their stratum. The single-agent and baseline
    rows keep the statistics above. ``Stat.estimator`` says ``"iqm"`` where the point is an IQM (the JSON has
    ``estimator`` then); ``leaderboard.csv`` has ``training_seeds`` and ``aggregation``
    (``episodes-mean-bca`` or ``seeds-iqm-stratified``) per row.

Ranking (within each track and task, :func:`rank_rows`)
    1. Sort by contact-free success rate (higher first), then tracking RMSE ``rmse_pos`` (lower first; an
       entry without an RMSE sorts after those with one), then name.
    2. Walk the sorted list. An entry is **tied** with the first entry of the current tie group (its
       leader) if both their contact-free-success intervals and their RMSE intervals overlap (closed
       intervals, and two intervals less than :data:`TIE_TOLERANCE` apart (0.1 mm of RMSE) count as
       overlapping; a missing interval counts as the single point of its mean; two missing RMSEs overlap).
       Otherwise it starts a new group. Every member of a group gets the group's rank, which is one plus the
       number of entries ranked before the group (standard competition ranking: 1, 2=, 2=, 4); tied ranks
       print as ``2=``.

Cache
    Every (entry, task, seed) result is a JSON file under the cache directory, keyed by the SHA-256 of the
    entry identity (name and kind; for agents the SHA-256 of their model files), the task spec (env id,
    keyword arguments incl. the action mode, step limit, whether a trajectory is stored), the seed, the
    package version and, for baselines, the ProxSuite build (``baselines.mpc.solver.PROXSUITE_BUILD``). Files are
    written atomically (temporary file + ``os.replace``) and reused on re-runs; ``force=True`` recomputes. A
    file that cannot be parsed or does not match its key is reported with ``logging.warning`` (by path) and
    recomputed.

Timings
    ``controller_ms_median`` is wall-clock time, so every computed episode stores a ``timing`` record
    (:func:`uvdms_gym.utils.provenance.timing_record`: CPU model, core count, 1-minute load average at the start and
    end of the episode) in its cached result, and the run keeps one for itself. ``leaderboard.md`` states the
    machine(s) and loads, and marks with :data:`OVERLOAD_MARK` every timing cell of a row in which an episode
    ran with a load above the core count; ``leaderboard.csv`` has ``timing_episodes_overloaded``,
    ``timing_episodes_unknown_load``, ``timing_load_1min_max`` and ``timing_machine`` per row.

Safety
    Weights-only agent exports (:func:`agents.export.load_weights_only`) evaluate without trust. A full SB3
    zip contains pickles: it is refused (:class:`agents.export.UntrustedFileError`) unless it lies inside the
    repository's ``trained_agents/`` folder or ``trust=True``; the check runs before any evaluation.
"""

from __future__ import annotations

from leaderboard.agent_files import agent_checksum, agent_env, training_seeds
from leaderboard.cache import (
    CACHE_FORMAT,
    PACKAGE_VERSION,
    REQUIRED_KEYS,
    CorruptCacheError,
    cache_key,
    cache_material,
    cache_path,
    compact_result,
    read_cached,
)
from leaderboard.entries import (
    BASELINES,
    DEFAULT_ENTRIES,
    MIN_TRAINING_SEEDS,
    RECOMMENDED_TRAINING_SEEDS,
    SEED_FOLDER_PREFIX,
    Entry,
    agent_entry,
    check_seed_disjointness,
    find_agent_folders,
    is_multi_seed_folder,
    is_weights_only,
    multi_seed_entry,
    resolve_entries,
    slugify,
)
from leaderboard.jobs import DEFAULT_BACKEND, Backend, Job, compute_job, make_env, plan_jobs
from leaderboard.plots import PLOT_METRICS, write_learning_curves, write_plots
from leaderboard.report import OVERLOAD_MARK, TABLE_METRICS, TIMING_METRICS, markdown_tables, timing_text, write_outputs
from leaderboard.result import LeaderboardResult
from leaderboard.runner import row_for, run_leaderboard
from leaderboard.stats import (
    BOOTSTRAP_SEED,
    CONFIDENCE,
    IQM_PROPORTION,
    METRICS,
    N_RESAMPLES,
    RATE_METRICS,
    TIE_TOLERANCE,
    RankedRow,
    Stat,
    aggregate,
    aggregate_runs,
    bootstrap_ci,
    episode_indicators,
    intervals_overlap,
    iqm,
    learning_curve_stats,
    rank_rows,
    run_matrix,
    stratified_bootstrap_ci,
    timing_summary,
)
from leaderboard.tasks import (
    CIRCLE_ID,
    DEFAULT_EPISODES,
    HYDRO_RANDOMIZATION,
    QUICK_EPISODES,
    SEED_BASE,
    TASKS,
    TRACKS,
    TRANSPORT_ID,
    Task,
    evaluation_seeds,
    select_tasks,
)
from leaderboard.webpage import PAGE_NAME, PageError, write_index_html

__all__ = [
    "BASELINES",
    "BOOTSTRAP_SEED",
    "CACHE_FORMAT",
    "CIRCLE_ID",
    "CONFIDENCE",
    "DEFAULT_BACKEND",
    "DEFAULT_ENTRIES",
    "DEFAULT_EPISODES",
    "HYDRO_RANDOMIZATION",
    "IQM_PROPORTION",
    "METRICS",
    "MIN_TRAINING_SEEDS",
    "N_RESAMPLES",
    "OVERLOAD_MARK",
    "PACKAGE_VERSION",
    "PAGE_NAME",
    "PLOT_METRICS",
    "QUICK_EPISODES",
    "RATE_METRICS",
    "RECOMMENDED_TRAINING_SEEDS",
    "REQUIRED_KEYS",
    "SEED_BASE",
    "SEED_FOLDER_PREFIX",
    "TABLE_METRICS",
    "TASKS",
    "TIE_TOLERANCE",
    "TIMING_METRICS",
    "TRACKS",
    "TRANSPORT_ID",
    "Backend",
    "CorruptCacheError",
    "Entry",
    "Job",
    "LeaderboardResult",
    "PageError",
    "RankedRow",
    "Stat",
    "Task",
    "agent_checksum",
    "agent_entry",
    "agent_env",
    "aggregate",
    "aggregate_runs",
    "bootstrap_ci",
    "cache_key",
    "cache_material",
    "cache_path",
    "check_seed_disjointness",
    "compact_result",
    "compute_job",
    "episode_indicators",
    "evaluation_seeds",
    "find_agent_folders",
    "intervals_overlap",
    "iqm",
    "is_multi_seed_folder",
    "is_weights_only",
    "learning_curve_stats",
    "make_env",
    "markdown_tables",
    "multi_seed_entry",
    "plan_jobs",
    "rank_rows",
    "read_cached",
    "resolve_entries",
    "row_for",
    "run_leaderboard",
    "run_matrix",
    "select_tasks",
    "slugify",
    "stratified_bootstrap_ci",
    "timing_summary",
    "timing_text",
    "training_seeds",
    "write_index_html",
    "write_learning_curves",
    "write_outputs",
    "write_plots",
]
