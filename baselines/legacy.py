"""The module paths ``baselines`` had before 0.4.0 grouped it by family: importing one fails in one line.

``import baselines.campc`` raises ``ModuleNotFoundError: baselines.campc was moved in 0.4.0: import from
baselines.mpc.campc`` (:mod:`uvdms_gym.utils.legacy`); ``import baselines`` installs the finder.
"""

from __future__ import annotations

REGROUPED: dict[str, str] = {
    "baselines.campc": "baselines.mpc.campc",
    "baselines.di": "baselines.inner_loop.di",
    "baselines.cascade": "baselines.inner_loop.cascade",
    "baselines.reproduce": "baselines.paper.reproduce",
    "baselines.figures": "baselines.paper.figures",
    "baselines.obstacle_figure": "baselines.paper.obstacle_figure",
    "baselines.evaluate": (
        "uvdms_gym.evaluation (run_episode, summarize, ...), uvdms_gym.utils.io (write_json_atomic) and "
        "leaderboard.running.evaluate (evaluate)"
    ),
}
"""Old module path of ``baselines`` -> where its names live now (``baselines.mpc`` and ``baselines.safety`` are
packages now: ``baselines.mpc.kinematic``, ``baselines.mpc.config``, ``baselines.mpc.solver``,
``baselines.mpc.damper``; ``baselines.safety.filter``)."""

MOVED_NAMES: dict[str, dict[str, str]] = {
    "baselines.mpc": {
        **dict.fromkeys(
            ["INF", "MPCConfig", "MPCProblem", "MPCStepRecord", "N_DIS", "N_DOF", "N_JOINTS", "QPMatrices"],
            "baselines.mpc.config",
        ),
        **dict.fromkeys(
            [
                "PORTABLE_PROXSUITE_BUILD",
                "PROXSUITE_BUILD",
                "import_portable_proxsuite",
                "proxsuite",
                "proxsuite_build",
            ],
            "baselines.mpc.solver",
        ),
        **dict.fromkeys(["damper_bound", "damper_shape"], "baselines.mpc.damper"),
        **dict.fromkeys(["KinematicMPC", "hold_matrix"], "baselines.mpc.kinematic"),
    },
    "baselines.safety": dict.fromkeys(["N", "SafetyFilter", "SafetyFilterConfig"], "baselines.safety.filter"),
}
"""The packages that were modules before 0.4.0 -> their former names -> the module each lives in now
(``from baselines.mpc import KinematicMPC`` fails in one line naming ``baselines.mpc.kinematic``)."""
