"""Deprecated: the evaluation protocol moved to :mod:`uvdms_gym.evaluation` (release 0.2; removed in 0.3).

The benchmark's definition of a result (:func:`~uvdms_gym.evaluation.run_episode`, the per-episode metrics,
the success rule, :func:`~uvdms_gym.evaluation.summarize`) belongs to the environment package, not to one
competitor. The old names still work here and emit a ``DeprecationWarning`` naming their new home
(``CHANGELOG.md`` lists them):

=======================  ===========================================================================
old name                 new home
=======================  ===========================================================================
``run_episode``          :func:`uvdms_gym.evaluation.run_episode`
``summarize``            :func:`uvdms_gym.evaluation.summarize`
``tracking_rmse``        :func:`uvdms_gym.evaluation.tracking_rmse`
``is_transport``         :func:`uvdms_gym.evaluation.is_transport`
``controller_settings``  :func:`uvdms_gym.evaluation.controller_settings`
``EPISODE_KEYS``         :data:`uvdms_gym.evaluation.EPISODE_KEYS` (also ``TRAJECTORY_KEYS``,
                         ``CIRCLE_SUCCESS_RMSE``)
``write_json_atomic``    :func:`uvdms_gym.utils.io.write_json_atomic`
``evaluate``             :func:`leaderboard.running.evaluate.evaluate` (baseline names and agent paths); the
                         alias here takes baseline names only, since ``baselines`` may not import ``agents``
=======================  ===========================================================================
"""

from __future__ import annotations

import warnings
from typing import Any

_MOVED: dict[str, str] = {
    "run_episode": "uvdms_gym.evaluation",
    "summarize": "uvdms_gym.evaluation",
    "tracking_rmse": "uvdms_gym.evaluation",
    "is_transport": "uvdms_gym.evaluation",
    "controller_settings": "uvdms_gym.evaluation",
    "EPISODE_KEYS": "uvdms_gym.evaluation",
    "TRAJECTORY_KEYS": "uvdms_gym.evaluation",
    "CIRCLE_SUCCESS_RMSE": "uvdms_gym.evaluation",
    "write_json_atomic": "uvdms_gym.utils.io",
}
"""Deprecated name -> the module that holds it now."""


def __getattr__(name: str) -> Any:
    """The moved names, with a ``DeprecationWarning`` (PEP 562)."""
    if name not in _MOVED:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    from uvdms_gym import evaluation
    from uvdms_gym.utils import io

    module = {"uvdms_gym.evaluation": evaluation, "uvdms_gym.utils.io": io}[_MOVED[name]]
    warnings.warn(
        f"baselines.evaluate.{name} is deprecated; import it from {_MOVED[name]}", DeprecationWarning, stacklevel=2
    )
    return getattr(module, name)


def evaluate(controller_spec: str, env_id: str, env_kwargs: dict | None = None, *args: Any, **options: Any) -> dict:
    """Deprecated: evaluate a named baseline; use :func:`leaderboard.running.evaluate.evaluate` (agents too).

    The baseline's ``action_mode`` is filled into ``env_kwargs`` when not given (an explicit, different one
    raises ``ValueError``). Further arguments (``episodes``, ``seed``, ``out``, ``save_trajectory``, ``progress``)
    and the result as :func:`leaderboard.running.evaluate.evaluate`; ``trust`` is accepted and unused.

    Raises:
        ValueError: ``controller_spec`` is not a baseline name (agents: :func:`leaderboard.running.evaluate.evaluate`),
            ``episodes < 1``, or an action-mode mismatch.
    """
    from baselines.controllers import BASELINES, make_baseline
    from uvdms_gym.evaluation import evaluate_controller

    warnings.warn(
        "baselines.evaluate.evaluate is deprecated; use leaderboard.running.evaluate.evaluate",
        DeprecationWarning,
        stacklevel=2,
    )
    if controller_spec not in BASELINES:
        raise ValueError(
            f"baselines.evaluate.evaluate takes a baseline name ({', '.join(BASELINES)}), got {controller_spec!r}; "
            "evaluate agents with leaderboard.running.evaluate.evaluate or `uvdms evaluate`"
        )
    kwargs = dict(env_kwargs or {})
    kwargs.setdefault("action_mode", BASELINES[controller_spec]["action_mode"])
    options.pop("trust", None)  # baselines load no files
    return evaluate_controller(
        lambda env: make_baseline(controller_spec, env), env_id, kwargs, *args, label=controller_spec, **options
    )
