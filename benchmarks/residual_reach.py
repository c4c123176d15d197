"""Can a residual of scale ``s`` over plain ``mpc`` do what CAMPC does? An oracle residual, per scale (JSON).

    python benchmarks/residual_reach.py [--episodes 10] [--scales 0.1 0.3 1.0] [--task circle|transport|case1|case2]
                                        [--teacher-margin 0.0]

The oracle residual is CAMPC's correction of plain MPC, clipped to what a residual agent of scale ``s`` can send:
``a = clip(a_mpc + s * clip((a_campc - a_mpc) / s, -1, 1), -1, 1)`` (``uvdms_gym.residual``'s formula with the
policy output ``teacher_residual(a_campc, a_mpc, s)``, the label ``--algo dagger`` learns from). Both MPCs see the
same state every step. ``s = inf`` (reported as the CAMPC row) sends CAMPC's action itself. If the oracle of scale
``s`` is not contact-free, no residual agent of that scale can learn CAMPC's avoidance by imitating it; the rows
give contact-free rate, success rate and position RMSE on the leaderboard's randomised task (the first validation
draws, ``uvdms_gym.seeds.split_seeds("validation", n)``, never test seeds; hydro +-30 %; ``case1``/``case2``: the
paper's fixed circles), the closest approach of any pair over the episodes, and the largest correction CAMPC needed,
``max |a_campc - a_mpc|``. ``--teacher-margin m`` moves CAMPC's collision thresholds out by ``m`` (the DAgger
teacher of ``teacher_margin=m``): the closest approach then says how much imitation error a learner of that teacher
can afford before it reaches ``d1``.
"""

from __future__ import annotations

import argparse
import json
from typing import Any

import gymnasium as gym
import numpy as np

import uvdms_gym  # noqa: F401  (registers the ids)
from baselines.controllers import make_baseline
from leaderboard.suite.registry import BaselineFactory
from leaderboard.suite.tasks import TASKS
from uvdms_gym.evaluation import run_episode, summarize
from uvdms_gym.residual import compose_residual, teacher_residual
from uvdms_gym.seeds import split_seeds


class OracleResidual:
    """``mpc`` plus CAMPC's correction clipped to a residual of scale ``scale`` (``None``: CAMPC itself)."""

    def __init__(self, env: Any, scale: float | None, margin: float = 0.0) -> None:
        self.mpc = make_baseline("mpc", env)
        self.campc = BaselineFactory("campc", collision_margin=margin)(env)
        self.scale = scale
        self.max_correction = 0.0

    def reset(self, seed: int | None = None) -> None:
        self.mpc.reset(seed)
        self.campc.reset(seed)

    def predict(self, obs: np.ndarray, info: dict[str, Any]) -> np.ndarray:
        a_mpc = np.asarray(self.mpc.predict(obs, info), dtype=np.float64)
        a_campc = np.asarray(self.campc.predict(obs, info), dtype=np.float64)
        self.max_correction = max(self.max_correction, float(np.max(np.abs(a_campc - a_mpc))))
        if self.scale is None:
            return a_campc.astype(np.float32)
        action, _clipped = compose_residual(a_mpc, teacher_residual(a_campc, a_mpc, self.scale), self.scale)
        return action


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=10)
    parser.add_argument("--scales", type=float, nargs="+", default=[0.1, 0.3, 1.0])
    parser.add_argument("--task", choices=("circle", "transport", "case1", "case2"), default="circle")
    parser.add_argument("--teacher-margin", type=float, default=0.0, help="m added to CAMPC's d1 and d2")
    args = parser.parse_args()
    name = args.task if args.task.startswith("case") else f"{args.task}-random"
    task = next(t for t in TASKS if t.name == name)
    out: dict[str, Any] = {"task": task.name, "episodes": args.episodes, "teacher_margin": args.teacher_margin}
    out["rows"] = {}
    for scale in [*args.scales, None]:
        env = gym.make(task.env_id, **task.spec("velocity")["env_kwargs"])
        controller = OracleResidual(env, scale, args.teacher_margin)
        results = [run_episode(env, controller, seed) for seed in split_seeds("validation", args.episodes)]
        env.close()
        summary = summarize(results)
        out["rows"]["campc" if scale is None else f"s={scale:g}"] = {
            "contact_free_rate": float(np.mean([r["contacts"] == 0 for r in results])),
            "success_rate": summary.get("success"),
            "rmse_pos_mm": None if summary.get("rmse_pos") is None else 1000.0 * summary["rmse_pos"],
            "min_distance_mm": 1000.0 * min(r["min_distance"] for r in results),
            "max_correction": controller.max_correction,
        }
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
