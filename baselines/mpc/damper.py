"""The velocity damper of the collision rows: ``v_dis <= S(d) vbar - k_esc max(0, d1 - d)``.

``S(d) = sin^2(pi/2 clip((d - d1) / (d2 - d1), 0, 1))``, evaluated at the distance the measured approach leaves
after the lookahead time (docs/MODEL.md section 4; the discrete-time safety condition is in
:mod:`baselines.mpc.kinematic`). Used by the MPC's collision rows and by the safety filter.
"""

from __future__ import annotations

import numpy as np

from baselines.mpc.config import MPCConfig


def damper_shape(cfg: MPCConfig, d: np.ndarray, v_now: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The damper's shape ``S(d_eff)`` and the distance it is evaluated at, ``d_eff``.

    Args:
        cfg: The damper's parameters (``d1``, ``d2``, ``lookahead``).
        d: the distances, m.
        v_now: measured distance rates (positive approaching); with ``cfg.lookahead > 0``,
            ``d_eff = d - lookahead max(0, v_now)``, else ``d_eff = d``.

    Returns:
        ``(S, d_eff)``.
    """
    d = np.asarray(d, dtype=float)
    if v_now is not None and cfg.lookahead > 0.0:
        d = d - cfg.lookahead * np.maximum(0.0, np.asarray(v_now, dtype=float))
    x = np.minimum(np.maximum((d - cfg.d1) / (cfg.d2 - cfg.d1), 0.0), 1.0)  # np.clip's values, cheaper
    return np.sin(0.5 * np.pi * x) ** 2, d


def damper_bound(cfg: MPCConfig, d: np.ndarray, v_now: np.ndarray | None = None) -> np.ndarray:
    """The velocity damper's bound on the approach rates: ``S(d) vbar - k_esc max(0, d1 - d)`` (18).

    Args:
        cfg: The damper's parameters (``vbar``, ``d1``, ``d2``, ``k_escape``, ``lookahead``).
        d: the distances, m.
        v_now: measured distance rates (18, positive approaching); with ``cfg.lookahead > 0`` the bound is
            evaluated at ``d - lookahead max(0, v_now)``.

    Returns:
        The bound on ``v_dis = J_dis zeta`` for each row, m/s.
    """
    s, d_eff = damper_shape(cfg, d, v_now)
    return s * cfg.vbar - cfg.k_escape * np.maximum(0.0, cfg.d1 - d_eff)
