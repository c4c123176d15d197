"""Cross-process bit-repeatability of the MPC baselines (docs/REPRODUCTION.md, QP).

Two probes:

* ``episodes``: fresh subprocesses run the first ``--steps`` steps of a baseline on the paper transport
  (``run_episode``, seed ``--seed``) with ``--controllers`` controllers each, after importing nothing extra
  (``plain``) or ``scipy.stats``, ``matplotlib.pyplot``, ``torch`` and ``leaderboard.running.runner`` (``heavy``, what
  the leaderboard's process holds). Each controller prints the SHA-256 of its actions (float64 bytes) and
  ``qp_slack_max``; bit-repeatable means one hash in every process.
* ``replay``: records the ProxSuite QPs of one ``campc`` transport episode, then solves the same sequence on
  fresh QP objects (cold init, then warm ``update`` + ``solve`` like :class:`baselines.mpc.kinematic.KinematicMPC`) with
  some heap allocated in between, and prints the hash of every trial's solutions. ``--build`` forces ProxSuite's
  ``avx512``, ``avx2`` or portable (``none``) Python module (the package otherwise picks the widest the CPU has).

Usage::

    .venv/bin/python benchmarks/mpc_determinism.py episodes --baseline campc --runs 3
    .venv/bin/python benchmarks/mpc_determinism.py replay --build avx512 --trials 16
"""

from __future__ import annotations

import argparse
import hashlib
import os
import pickle
import subprocess
import sys
import tempfile
import types
from pathlib import Path

EPISODE_CHILD = r"""
import hashlib, sys
mode, name, steps, n_ctrl, seed = sys.argv[1], sys.argv[2], int(sys.argv[3]), int(sys.argv[4]), int(sys.argv[5])
if mode == "heavy":
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot  # noqa: F401
    import scipy.stats  # noqa: F401
    import torch  # noqa: F401
    import leaderboard.running.runner  # noqa: F401
import gymnasium as gym
import numpy as np
import uvdms_gym  # noqa: F401
from baselines.controllers import BASELINES, make_baseline
from uvdms_gym.evaluation import run_episode
track = BASELINES[name]["action_mode"]
env = gym.make("uvdms/Transport-v0", goal="paper", action_mode=track, max_episode_steps=steps)
out = []
for ctrl in [make_baseline(name, env) for _ in range(n_ctrl)]:
    h = hashlib.sha256()
    predict = ctrl.predict
    def recorded(obs, info, predict=predict, h=h):
        action = predict(obs, info)
        h.update(np.asarray(action, dtype=np.float64).tobytes())
        return action
    ctrl.predict = recorded
    res = run_episode(env, ctrl, seed)
    out.append(f"{h.hexdigest()[:12]}:{res['qp_slack_max']!r}:{res['final_pos_error']!r}")
import proxsuite
print(proxsuite.proxqp.dense.QP.__module__.split(".")[1], " ".join(out))
"""


def episodes(args: argparse.Namespace) -> None:
    hashes: set[str] = set()
    for run in range(args.runs):
        for mode in ("plain", "heavy"):
            cmd = [sys.executable, "-c", EPISODE_CHILD, mode, args.baseline, str(args.steps), str(args.controllers)]
            cmd.append(str(args.seed))
            out = subprocess.run(cmd, capture_output=True, text=True, check=True).stdout.strip().splitlines()[-1]
            print(f"run {run} {mode:5s} {out}", flush=True)
            hashes.update(out.split()[1:])
    print(f"distinct results: {len(hashes)}")


def record(path: Path, steps: int) -> None:
    import gymnasium as gym

    import uvdms_gym  # noqa: F401
    from baselines.controllers import make_baseline
    from baselines.mpc.kinematic import KinematicMPC

    seq: list[dict] = []
    solve = KinematicMPC.solve

    def recording(self: KinematicMPC, problem: object) -> object:
        h, g, lo, hi = self._build(problem)
        arrays = (h, g, self._A, self._b, self._C, self._l, self._u, lo, hi)
        seq.append({"args": tuple(a.copy() for a in arrays), "mpc": self})
        return solve(self, problem)

    KinematicMPC.solve = recording
    env = gym.make("uvdms/Transport-v0", goal="paper", action_mode="velocity")
    ctrl = make_baseline("campc", env)
    obs, info = env.reset(seed=0)
    ctrl.reset(0)
    for _ in range(steps):
        obs, _, _, _, info = env.step(ctrl.predict(obs, info))
    KinematicMPC.solve = solve
    mpc = seq[0]["mpc"]
    cfg = mpc.config
    dims = (mpc.n, mpc.n_eq, mpc.n_in)
    data = {"args": [s["args"] for s in seq], "dims": dims, "cfg": (cfg.eps_abs, cfg.eps_rel, cfg.max_iter)}
    data["warm_mu_in"] = cfg.warm_mu_in
    path.write_bytes(pickle.dumps(data))


def replay(args: argparse.Namespace) -> None:
    path = Path(tempfile.gettempdir()) / "uvdms_qp_sequence.pkl"
    if not path.exists() or args.rerecord:
        subprocess.run([sys.executable, __file__, "record", str(path)], check=True)
    if args.build != "auto":
        # proxsuite/__init__.py asks ``proxsuite.instructionset`` which module to load: answer for it.
        fake = types.ModuleType("proxsuite.instructionset")
        fake.has_AVX512F = lambda: args.build == "avx512"  # type: ignore[attr-defined]
        fake.has_AVX2 = lambda: args.build in ("avx2", "avx512")  # type: ignore[attr-defined]
        sys.modules["proxsuite.instructionset"] = fake
    import numpy as np
    import proxsuite

    data = pickle.loads(path.read_bytes())
    warm = proxsuite.proxqp.InitialGuess.WARM_START_WITH_PREVIOUS_RESULT
    rng = np.random.default_rng(args.seed)
    keep: list[object] = []
    results = []
    for _ in range(args.trials):
        keep.append(bytearray(int(rng.integers(1, 5000))))  # move the heap a little between trials
        keep.append(np.empty(int(rng.integers(1, 3000))))
        qp = proxsuite.proxqp.dense.QP(*data["dims"], True, proxsuite.proxqp.dense.HessianType.Dense)
        qp.settings.eps_abs, qp.settings.eps_rel, qp.settings.max_iter = data["cfg"]
        h = hashlib.sha256()
        for k, qp_args in enumerate(data["args"]):
            if k == 0:
                qp.settings.initial_guess = proxsuite.proxqp.InitialGuess.NO_INITIAL_GUESS
                qp.init(*qp_args)
                qp.solve()
                qp.settings.initial_guess = warm
            else:
                qp.update(*qp_args, mu_in=data["warm_mu_in"])
                qp.solve()
            h.update(qp.results.x.tobytes())
        results.append(h.hexdigest()[:10])
    print(proxsuite.proxqp.dense.QP.__module__.split(".")[1], " ".join(results))
    print(f"distinct results: {len(set(results))}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="cmd", required=True)
    ep = sub.add_parser("episodes")
    ep.add_argument("--baseline", default="campc")
    ep.add_argument("--steps", type=int, default=20)
    ep.add_argument("--controllers", type=int, default=3)
    ep.add_argument("--seed", type=int, default=0)
    ep.add_argument("--runs", type=int, default=3)
    rp = sub.add_parser("replay")
    rp.add_argument("--build", choices=("auto", "avx512", "avx2", "none"), default="auto")
    rp.add_argument("--trials", type=int, default=16)
    rp.add_argument("--seed", type=int, default=1)
    rp.add_argument("--rerecord", action="store_true")
    rc = sub.add_parser("record")
    rc.add_argument("path", type=Path)
    rc.add_argument("--steps", type=int, default=30)
    args = parser.parse_args()
    os.environ.setdefault("PYTHONHASHSEED", "0")
    if args.cmd == "episodes":
        episodes(args)
    elif args.cmd == "replay":
        replay(args)
    else:
        record(args.path, args.steps)


if __name__ == "__main__":
    main()
