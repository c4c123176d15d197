"""The benchmark's definition of a result: the controller protocol, one episode's metrics and the success rule.

Every competitor (a named baseline, a trained agent, a user's own controller) is evaluated through the same
:class:`Controller` protocol and :func:`run_episode`; :func:`summarize` averages episodes and
:func:`evaluate_controller` runs several seeded episodes of a controller factory and writes the JSON result.
Resolving a controller *name* (``campc``) or *path* (an agent folder) to a controller belongs to the command
layer (:mod:`leaderboard.suite.registry`, ``uvdms evaluate``), not here: this module imports no other package of the
project.
:func:`evaluate` runs several seeded episodes of a controller named by a string (a baseline name or an agent
path), averages them and writes the result to a JSON file atomically. ``uvdms evaluate`` is its command line.

Definitions (per episode):

* samples: the state after :meth:`reset` (``t = 0``) and after every step (``t = k control_dt``);
* ``return``: sum of the rewards; ``cost``: sum of ``info["cost"]``; ``contacts``: steps with a reported
  contact (``info["contacts"] > 0``); ``zone_steps``: steps with ``info["cost_zone"]`` (a distance below d1);
* ``min_distance`` / ``min_distance_by_pair``: minimum over all samples of the 18 distances (m, rows as in
  ``docs/ARCHITECTURE.md``) — the collision metrics cover the whole run;
* ``rmse_pos`` (m): over the samples with ``t >= env.unwrapped.tracking_transient`` (5 s for the circle tasks,
  0 for transport); circle tracking: ``sqrt(mean_k (|e_left|^2 + |e_right|^2) / 2)`` with ``e = y - y_ref`` of each
  end effector, i.e. the RMS of the two end effectors' position errors; transport: ``sqrt(mean_k |p - p_ref|^2)``
  of the object position;
* ``rmse_ori`` (rad, transport only, else ``None``): RMS over the same samples of the rotation angle between the
  object's orientation and the reference (``info["orientation_error"]``);
* ``final_pos_error`` (m): ``info["tracking_error"]`` at the last sample (circle: mean of the two end effectors'
  error norms; transport: object position error); ``final_ori_error`` (rad): transport only;
* ``success``: the episode was not cut short by a termination (contact, tracking error, physics) and had no
  contact; circle tracking also needs ``rmse_pos <= 0.03`` m (:data:`CIRCLE_SUCCESS_RMSE`); transport needs
  ``info["is_success"]`` at the last sample (object within 2 cm and 2 degrees of the goal after the move);
* ``controller_ms_median``: median wall time of ``controller.predict`` (ms);
* ``qp_slack_max``: largest collision slack of the MPC over the run (m/s; ``None`` for controllers without a QP,
  e.g. agents); ``qp_unsolved``: steps whose QP did not reach ``"solved"`` (``None`` likewise);
* ``steps``, ``terminated``, ``truncated``, ``physics_error`` (the message, or ``None``);
* the friction grasp's (:data:`GRASP_EPISODE_KEYS`; ``None`` on a rigid-grasp environment, where the object is
  welded to the hands): ``slip_max`` (m, the largest ``info["slip_max"]`` over the steps: how far either hand's
  contact moved over the object's surface), ``dropped`` / ``crushed`` (bool: the episode ended by a drop or a
  crush, ``info["dropped"]`` / ``info["crushed"]`` at the last step), ``internal_force_max`` (N, the largest
  ``|info["internal_force"]|`` over the samples, the one after reset included) and ``internal_force_rms`` (N, its
  RMS over the same samples). A drop or a crush terminates the episode, so such an episode is never a success.

With ``save_trajectory`` an episode also holds ``trajectory``: lists over the samples of ``t``, ``y``, ``y_ref``,
``distances``, ``eta``, ``nu``, ``q``, ``qdot``, ``action``, ``tau`` (the generalized force applied during the step
that ended at the sample; zeros at ``t = 0``), ``zeta_cmd`` (the MPC command, ``None`` without an MPC) and
``nn_output`` (the network's compensation ``Deltahat`` of the dynamic inversion; ``None`` unless the controller
has one).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping, Sequence
from typing import Any, Protocol, runtime_checkable

import numpy as np

from uvdms_gym.seeds import PROTOCOL, protocol_record, split_of
from uvdms_gym.utils.io import to_jsonable, write_json_atomic
from uvdms_gym.utils.provenance import git_info, package_versions, timing_record

EPISODE_KEYS: tuple[str, ...] = (
    "seed",
    "return",
    "cost",
    "contacts",
    "zone_steps",
    "min_distance",
    "min_distance_by_pair",
    "rmse_pos",
    "rmse_ori",
    "final_pos_error",
    "final_ori_error",
    "success",
    "controller_ms_median",
    "qp_slack_max",
    "qp_unsolved",
    "steps",
    "terminated",
    "truncated",
    "physics_error",
    "slip_max",
    "dropped",
    "crushed",
    "internal_force_max",
    "internal_force_rms",
)
"""Keys of every episode dict returned by :func:`run_episode` (plus ``trajectory`` with ``save_trajectory``)."""
GRASP_EPISODE_KEYS: tuple[str, ...] = EPISODE_KEYS[-5:]
"""The friction grasp's keys of :data:`EPISODE_KEYS` (``None`` on a rigid-grasp environment). Episodes computed
before they existed lack them: readers take a missing key as ``None`` (:func:`summarize`, the leaderboard)."""

CIRCLE_SUCCESS_RMSE = 0.03
"""Circle tracking succeeds with no contact and ``rmse_pos`` at most this (m)."""

TRAJECTORY_KEYS: tuple[str, ...] = (
    "t",
    "y",
    "y_ref",
    "distances",
    "eta",
    "nu",
    "q",
    "qdot",
    "action",
    "tau",
    "zeta_cmd",
    "nn_output",
)
"""Keys of an episode's ``trajectory``."""


@runtime_checkable
class Controller(Protocol):
    """What :func:`run_episode` drives: baselines and trained agents alike.

    The action is in the environment's normalised space ``[-1, 1]^18``. A controller may expose
    ``last_record`` (a dict with ``max_slack`` and ``status`` of its QP, and more) and ``last_di`` (its network
    output ``delta_hat``) after each ``predict``; :func:`run_episode` reads them when present.
    """

    def reset(self, seed: int | None = None) -> None:
        """Start an episode (called right after ``env.reset(seed=seed)``)."""
        ...

    def predict(self, obs: np.ndarray, info: dict[str, Any]) -> np.ndarray:
        """The action (18, in ``[-1, 1]``) for the current observation and ``info``."""
        ...


def judged_info(env: Any, info: Mapping[str, Any]) -> Mapping[str, Any]:
    """``info`` with the true state where a realism level put measurements: metrics are judged on the truth.

    At ``realism=0`` this is ``info`` itself; at ``realism > 0`` the state keys (``eta``, ``nu``, ``q``, ``qdot``,
    ``y``, the distances, ...) come from ``env.unwrapped.true_state()``. Controllers are never handed this.
    """
    u = env.unwrapped
    if getattr(u, "realism", None) is None:
        return info
    return {**info, **u.true_state()}


def is_transport(env: Any) -> bool:
    """Whether the environment tracks an object pose (transport) rather than end-effector positions."""
    return bool(getattr(env.unwrapped, "with_object", False))


def tracking_rmse(
    t: np.ndarray, y: np.ndarray, y_ref: np.ndarray, transport: bool, transient: float
) -> tuple[float, float | None]:
    """Position and orientation RMSE of a trajectory (definitions in the module docstring).

    Args:
        t: sample times (N).
        y: tracked outputs (N, 6): ``[p_left; p_right]`` or the object pose ``[x y z phi theta psi]``.
        y_ref: references (N, 6), same layout.
        transport: object pose (``True``) or two end-effector positions.
        transient: samples with ``t < transient`` are left out.

    Returns:
        ``(rmse_pos, rmse_ori)``; ``rmse_ori`` is ``None`` for end-effector tracking. ``nan`` if no sample is left.
    """
    t, y, y_ref = np.asarray(t, float), np.asarray(y, float), np.asarray(y_ref, float)
    keep = t >= transient - 1e-9
    if not keep.any():
        return math.nan, (math.nan if transport else None)
    y, y_ref = y[keep], y_ref[keep]
    if not transport:
        e = (y - y_ref).reshape(-1, 2, 3)
        return float(np.sqrt(np.mean(np.sum(e**2, axis=2)))), None
    from uvdms_gym.physics.frames import euler_to_rot_batch

    pos = float(np.sqrt(np.mean(np.sum((y[:, :3] - y_ref[:, :3]) ** 2, axis=1))))
    r_rel = np.einsum("nji,njk->nik", euler_to_rot_batch(y_ref[:, 3:]), euler_to_rot_batch(y[:, 3:]))
    cos_a = np.clip((np.trace(r_rel, axis1=1, axis2=2) - 1.0) / 2.0, -1.0, 1.0)
    return pos, float(np.sqrt(np.mean(np.arccos(cos_a) ** 2)))


class EpisodeTracker:
    """The samples and counts of one episode that its outcome metrics are computed from.

    The one home of the success rule and of what ``rmse_pos`` averages: :func:`run_episode` feeds it, and so does
    anything else that steps an environment itself (a trainer's evaluation episodes,
    ``agents.common.learning_curve.EpisodeMetrics``), so both report the same numbers for the same episode.

    At ``realism > 0`` it records the true state (:func:`judged_info`), not the measured one in ``info``.

    Args:
        env: The environment (wrapped or not; its ``unwrapped`` has ``tracking_transient``).
        reset_info: The ``info`` of ``env.reset`` (the sample at ``t = 0``).
    """

    def __init__(self, env: Any, reset_info: Mapping[str, Any]) -> None:
        self.env = env
        reset_info = judged_info(env, reset_info)
        self.first_info = reset_info
        self.transport = is_transport(env)
        self.transient = float(env.unwrapped.tracking_transient)
        self.ts: list[Any] = [reset_info["t"]]
        self.ys: list[Any] = [reset_info["y"]]
        self.refs: list[Any] = [reset_info["y_ref"]]
        self.contacts = 0
        self.steps = 0
        self.terminated = False
        self.physics_error: str | None = None
        self.last_info: Mapping[str, Any] = reset_info
        self.grasp = GraspRecord() if has_friction_grasp(env) else None
        if self.grasp is not None:
            self.grasp.add(reset_info)

    def step(self, info: Mapping[str, Any], terminated: bool) -> Mapping[str, Any]:
        """Record the sample and counts of one ``env.step`` (its ``info`` and ``terminated`` flag).

        Returns:
            The judged ``info`` (:func:`judged_info`): what the sample was recorded from.
        """
        info = judged_info(self.env, info)
        self.steps += 1
        self.contacts += int(info["contacts"] > 0)
        self.ts.append(info["t"])
        self.ys.append(info["y"])
        self.refs.append(info["y_ref"])
        if info.get("physics_error"):
            self.physics_error = str(info["physics_error"])
        self.terminated = bool(terminated)
        self.last_info = info
        if self.grasp is not None:
            self.grasp.add(info)
        return info

    def outcome(self) -> dict[str, Any]:
        """``rmse_pos``, ``rmse_ori``, ``success``, ``contacts``, ``steps``, ``terminated``, ``physics_error``, ...

        ... and the friction grasp's :data:`GRASP_EPISODE_KEYS` (``None`` each with the rigid grasp). Definitions
        in the module docstring (``rmse_pos`` is ``nan`` when no sample lies past the transient).
        """
        rmse_pos, rmse_ori = tracking_rmse(
            np.array(self.ts), np.array(self.ys), np.array(self.refs), self.transport, self.transient
        )
        if self.transport:
            success = bool(self.last_info["is_success"])
        else:
            success = math.isfinite(rmse_pos) and rmse_pos <= CIRCLE_SUCCESS_RMSE
        success = success and self.contacts == 0 and not self.terminated and self.physics_error is None
        return {
            "rmse_pos": rmse_pos,
            "rmse_ori": rmse_ori,
            "success": success,
            "contacts": self.contacts,
            "steps": self.steps,
            "terminated": self.terminated,
            "physics_error": self.physics_error,
            **(self.grasp.outcome() if self.grasp is not None else dict.fromkeys(GRASP_EPISODE_KEYS)),
        }


def has_friction_grasp(env: Any) -> bool:
    """Whether the environment holds its object by friction (``grasp="friction"``), not welded to the hands."""
    return getattr(env.unwrapped, "grasp_config", None) is not None


class GraspRecord:
    """The friction grasp's running episode figures (:data:`GRASP_EPISODE_KEYS`), fed one ``info`` per sample.

    A sample without the grasp's keys (a step that ended in a physics error) adds nothing.
    """

    def __init__(self) -> None:
        self.slip_max = 0.0
        self.dropped = False
        self.crushed = False
        self.force_max = 0.0
        self.force_sq = 0.0
        self.samples = 0

    def add(self, info: Mapping[str, Any]) -> None:
        """Record one sample's ``slip_max``, ``dropped``, ``crushed`` and ``internal_force``."""
        if "internal_force" not in info:
            return
        force = abs(float(info["internal_force"]))
        self.slip_max = max(self.slip_max, float(info["slip_max"]))
        self.dropped = self.dropped or bool(info["dropped"])
        self.crushed = self.crushed or bool(info["crushed"])
        self.force_max = max(self.force_max, force)
        self.force_sq += force * force
        self.samples += 1

    def outcome(self) -> dict[str, Any]:
        """The episode's :data:`GRASP_EPISODE_KEYS` (the force RMS ``nan`` without a sample)."""
        return {
            "slip_max": self.slip_max,
            "dropped": self.dropped,
            "crushed": self.crushed,
            "internal_force_max": self.force_max,
            "internal_force_rms": math.sqrt(self.force_sq / self.samples) if self.samples else math.nan,
        }


def _record_step(
    traj: dict[str, list], env: Any, controller: Any, info: dict, action: np.ndarray | None, tau: np.ndarray | None
) -> None:
    """Append one step to the time series of :data:`TRAJECTORY_KEYS` (``action is None``: the state after reset)."""
    rec = getattr(controller, "last_record", None) or {}
    di = getattr(controller, "last_di", None)
    for key in ("t", "y", "y_ref", "distances", "eta", "nu", "q", "qdot"):
        traj[key].append(info[key])
    traj["action"].append(np.zeros(env.action_space.shape) if action is None else action)
    traj["tau"].append(np.zeros(18) if tau is None else tau)
    traj["zeta_cmd"].append(None if action is None or "zeta_cmd" not in rec else rec["zeta_cmd"])
    traj["nn_output"].append(None if action is None or di is None else di.delta_hat)


def run_episode(env: Any, controller: Any, seed: int, *, save_trajectory: bool = False) -> dict:
    """Run one episode of ``controller`` on ``env`` from ``env.reset(seed=seed)`` to termination or truncation.

    Args:
        env: a UVDMS environment (``gymnasium.make`` result, with its time limit).
        controller: anything with ``reset(seed)`` and ``predict(obs, info) -> action`` (optional ``last_record``
            with ``max_slack``/``status``, optional ``last_di`` with the network output).
        seed: the episode seed (environment and controller).
        save_trajectory: also return the time series (``trajectory``).

    Returns:
        A JSON-serialisable dict with the keys of :data:`EPISODE_KEYS` (definitions in the module docstring).
    """
    transport = is_transport(env)
    obs, info = env.reset(seed=seed)
    controller.reset(seed)
    tracker = EpisodeTracker(env, info)
    judged = tracker.first_info  # the truth (at realism > 0 the controller sees only info's measurements)
    n_dis = len(judged["distances"])
    d_min = np.array(judged["distances"], dtype=float)
    traj: dict[str, list] = {k: [] for k in TRAJECTORY_KEYS}

    def record(info: dict, action: np.ndarray | None, tau: np.ndarray | None) -> None:
        if save_trajectory:
            _record_step(traj, env, controller, info, action, tau)

    record(judged, None, None)
    ret = cost = 0.0
    zone = 0
    slack_max: float | None = None
    unsolved: int | None = None
    times_ms: list[float] = []
    terminated = truncated = False
    has_nn = False
    while True:
        t0 = time.perf_counter()
        action = np.asarray(controller.predict(obs, info))
        times_ms.append((time.perf_counter() - t0) * 1e3)
        rec = getattr(controller, "last_record", None)
        if rec and "max_slack" in rec:
            slack_max = max(slack_max or 0.0, float(rec["max_slack"]))
            unsolved = (unsolved or 0) + int(rec.get("status", "solved") != "solved")
        has_nn = has_nn or getattr(controller, "last_di", None) is not None
        obs, reward, terminated, truncated, info = env.step(action)
        judged = tracker.step(info, terminated)
        ret += float(reward)
        cost += float(info["cost"])
        zone += int(info["cost_zone"] > 0)
        np.minimum(d_min, judged["distances"], out=d_min)
        record(judged, action, info.get("tau"))
        if terminated or truncated:
            break
    outcome = tracker.outcome()
    out: dict[str, Any] = {
        "seed": seed,
        "return": ret,
        "cost": cost,
        "contacts": outcome["contacts"],
        "zone_steps": zone,
        "min_distance": float(d_min.min()),
        "min_distance_by_pair": d_min[:n_dis],
        "rmse_pos": outcome["rmse_pos"],
        "rmse_ori": outcome["rmse_ori"],
        "final_pos_error": float(info["tracking_error"]),
        "final_ori_error": float(info["orientation_error"]) if transport else None,
        "success": outcome["success"],
        "controller_ms_median": float(np.median(times_ms)),
        "qp_slack_max": slack_max,
        "qp_unsolved": unsolved,
        "steps": outcome["steps"],
        "terminated": outcome["terminated"],
        "truncated": bool(truncated),
        "physics_error": outcome["physics_error"],
        **{key: outcome[key] for key in GRASP_EPISODE_KEYS},
    }
    if save_trajectory:
        if not has_nn:
            traj["nn_output"] = None  # type: ignore[assignment]
        out["trajectory"] = traj
    return to_jsonable(out)


def summarize(episodes: list[dict]) -> dict:
    """Means over episodes of every numeric (or boolean: the fraction) key, elementwise for lists.

    ``None`` values are left out of a mean; a key that is ``None`` in every episode is ``None``. Also
    ``episodes`` (count) and ``success_rate`` (= mean of ``success``).
    """
    out: dict[str, Any] = {"episodes": len(episodes)}
    for key in EPISODE_KEYS:
        if key in ("seed", "physics_error"):
            continue
        vals = [ep[key] for ep in episodes if ep.get(key) is not None]
        if not vals:
            out[key] = None
        elif isinstance(vals[0], list):
            out[key] = np.mean(np.array(vals, dtype=float), axis=0)
        else:
            out[key] = float(np.mean(np.array(vals, dtype=float)))
    out["success_rate"] = out.get("success")
    out["physics_errors"] = sum(ep.get("physics_error") is not None for ep in episodes)
    return to_jsonable(out)


def controller_settings(controller: Any) -> dict:
    """The configuration of a baseline (MPC and DI dataclasses as dicts) or an agent's description.

    A residual agent (:class:`uvdms_gym.residual.ResidualController`) records its base's MPC settings, its
    policy's description and ``residual_scale``.
    """
    from dataclasses import asdict, is_dataclass

    out: dict[str, Any] = {"class": type(controller).__name__}
    mpc = getattr(controller, "mpc", None)
    if mpc is not None and is_dataclass(getattr(mpc, "config", None)):
        out["mpc"] = asdict(mpc.config)
    di = getattr(controller, "di", None)
    if di is not None and is_dataclass(getattr(di, "config", None)):
        out["di"] = asdict(di.config)
    for attr in ("algo", "env_id", "num_timesteps", "source", "residual_scale"):
        if hasattr(controller, attr):
            out[attr] = getattr(controller, attr)
    return to_jsonable(out)


def seed_protocol(seeds: Sequence[int]) -> dict[str, Any]:
    """What a result records of the seed protocol (:mod:`uvdms_gym.seeds`) its episodes' ``seeds`` follow.

    Returns:
        ``{"protocol": PROTOCOL, "split": split}``: the split holding every one of ``seeds`` (``"validation"``,
        ``"test"``, ...), or ``None`` when they lie in no split or in several.
    """
    splits = {split_of(int(s)) for s in seeds}
    split = splits.pop() if len(splits) == 1 else None
    return protocol_record(split) if split is not None else {"protocol": PROTOCOL, "split": None}


def _run_episodes(
    env: Any, controller: Any, seeds: Sequence[int], save_trajectory: bool, progress_label: str | None
) -> list[dict]:
    """:func:`run_episode` on each of ``seeds`` in turn, behind a tqdm bar named ``progress_label`` (``None``: none)."""
    bar = None
    if progress_label is not None:
        from tqdm.auto import tqdm

        bar = tqdm(seeds, desc=progress_label, unit="ep", leave=False)
    results = []
    for s in bar if bar is not None else seeds:
        ep = run_episode(env, controller, s, save_trajectory=save_trajectory)
        results.append(ep)
        if bar is not None:
            rmse = f"{ep['rmse_pos']:.4f}" if ep["rmse_pos"] is not None else "nan"
            bar.set_postfix(rmse=rmse, c=ep["contacts"])
    if bar is not None:
        bar.close()
    return results


def evaluate_controller(
    make_controller: Callable[[Any], Any],
    env_id: str,
    env_kwargs: dict | None = None,
    episodes: int = 5,
    seed: int = 0,
    *,
    seeds: Sequence[int] | None = None,
    label: str = "controller",
    out: str | None = None,
    save_trajectory: bool = False,
    progress: bool = True,
    check: Callable[[Any, Any], None] | None = None,
) -> dict:
    """Evaluate the controller ``make_controller(env)`` over ``episodes`` seeded episodes.

    The episodes' seeds are ``seed, seed + 1, ...`` unless ``seeds`` names them (the draws of a split,
    :func:`uvdms_gym.seeds.split_seeds`, or the share of one training seed, :func:`uvdms_gym.seeds.assign_draws`).

    Args:
        make_controller: Builds the controller for the environment (called once, inside the timed block).
        env_id: Gymnasium id, e.g. ``"uvdms/CircleTrack-v0"``.
        env_kwargs: ``gymnasium.make`` keyword arguments (the effective ones are recorded in ``meta``).
        episodes: Number of episodes (>= 1).
        seed: Seed of the first episode (not used when ``seeds`` is given).
        seeds: The episodes' seeds, in order; ``len(seeds)`` must equal ``episodes``.
        label: What ``meta["controller"]`` records (a baseline name, an agent path) and the progress bar shows.
        out: JSON file to write (:func:`uvdms_gym.utils.io.write_json_atomic`); ``None`` writes nothing.
        save_trajectory: Keep each episode's time series.
        progress: Show a tqdm progress bar.
        check: Called as ``check(controller, env)`` before the first episode (raises on a mismatch).

    Returns:
        ``{"episodes": [...], "summary": {...}, "meta": {...}}``; ``meta`` holds the controller label, env id,
        effective env kwargs, seeds, the seed protocol they follow (``seed_protocol``: :func:`seed_protocol`),
        package versions, git revision, wall time, the machine and the load around the timed episodes
        (``timing``: :func:`uvdms_gym.utils.provenance.timing_record`; the per-episode ``controller_ms_median`` is
        only comparable between runs with ``overloaded`` false on the same machine) and the controller's settings
        (:func:`controller_settings`).

    Raises:
        ValueError: ``episodes < 1``, ``seeds`` of another length, or what ``make_controller`` and ``check``
            raise.
    """
    import gymnasium as gym

    import uvdms_gym  # noqa: F401  (registers the environments)

    seeds = _episode_seeds(episodes, seed, seeds)
    kwargs = dict(env_kwargs or {})
    env = gym.make(env_id, **kwargs)
    try:
        with timing_record() as timing:
            t_start = time.perf_counter()
            controller = make_controller(env)
            if check is not None:
                check(controller, env)
            results = _run_episodes(
                env, controller, seeds, save_trajectory, f"{label} on {env_id}" if progress else None
            )
            wall_s = time.perf_counter() - t_start
        settings = controller_settings(controller)
    finally:
        env.close()
    meta = {"controller": label, "env_id": env_id, "env_kwargs": kwargs, "episodes": episodes, "seeds": seeds}
    result = {"episodes": results, "summary": summarize(results), "meta": _run_meta(meta, wall_s, timing, settings)}
    if out is not None:
        write_json_atomic(out, result)
    return result


def _episode_seeds(episodes: int, seed: int, seeds: Sequence[int] | None) -> list[int]:
    """The episodes' seeds of :func:`evaluate_controller` (``seed, seed + 1, ...`` unless ``seeds`` names them).

    Raises:
        ValueError: ``episodes < 1`` or ``seeds`` of another length.
    """
    if episodes < 1:
        raise ValueError(f"episodes must be >= 1, got {episodes}")
    seeds = [int(seed) + i for i in range(episodes)] if seeds is None else [int(s) for s in seeds]
    if len(seeds) != episodes:
        raise ValueError(f"episodes={episodes} but {len(seeds)} seeds were given")
    return seeds


def _run_meta(meta: dict, wall_s: float, timing: dict, settings: Any) -> dict:
    """``meta`` of :func:`evaluate_controller`: the run's identity, then its seed protocol, provenance and timing."""
    return to_jsonable(
        {
            **meta,
            "seed_protocol": seed_protocol(meta["seeds"]),
            "versions": package_versions(),
            "git": git_info(),
            "wall_s": wall_s,
            "timing": timing,
            "controller_settings": settings,
        }
    )


def check_action_mode(name: str, env: Any, required: str) -> None:
    """Check that ``env`` has the action mode a controller needs.

    Args:
        name: The controller, for the message (``"campc-nndi"``, ``"agent runs/sac_0"``).
        env: The environment (wrapped or not).
        required: ``"velocity"`` or ``"torque"``.

    Raises:
        ValueError: The modes differ (the message says how to create the right environment).
    """
    mode = getattr(env.unwrapped, "action_mode", None)
    if mode != required:
        raise ValueError(
            f"controller {name!r} needs action_mode={required!r} but the environment has action_mode={mode!r}; "
            f"create it with env_kwargs action_mode={required}"
        )
