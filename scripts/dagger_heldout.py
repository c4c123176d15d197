"""How well a network fits a DAgger run's labels on episodes it did not see (JSON on stdout).

    python scripts/dagger_heldout.py RUN_DIR [--steps 25000] [--net 256x256] [--weight-decay 0]
                                             [--train-fraction 1.0] [--threads 2]

Reads the run's labelled states (``replay_buffer.pkl``, saved by ``uvdms train --algo dagger``; every state the
learner visited with the teacher's command there), holds out 10 % of the episodes (blocks of :data:`BLOCK` stored
states, one 600-step episode of each of the run's 2 environments), refits a fresh MLP of ``--net`` (ReLU, a ``tanh``
output as SB3's actor) to ``--train-fraction`` of the others by least squares (Adam, batch 256, learning rate 1e-3
falling linearly to 0 over ``--steps``; AdamW with ``--weight-decay``), and prints the mean squared error per command
on the training and the held-out states: overall, where the obstacle features weigh an opening direction (a part's
predicted gap under 40 cm), elsewhere, in the hold (the reference at rest) and for the vehicle's and the arms'
commands. ``docs/challenged.md`` ("Where the network's error is") reports its figures for the obstacle network's
pilots. Seeded: the same arguments give the same split and the same fit on one machine.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np
import torch as th
import yaml
from stable_baselines3.common.save_util import load_from_pkl

from agents.algos.dagger import reference_at_rest
from uvdms_gym.residual.tracking_features import TRACKING_SIZE

BLOCK = 1200
"""Stored states per held-out unit: 600 steps of the run's 2 environments (the buffer interleaves them)."""
HELD_OUT = 0.1
"""Share of the blocks held out."""
OPENING_SUM = 18
"""The obstacle features end with the weighted sum of the opening directions (``ObstacleFeatures``)."""
VEHICLE = 6
"""The first commands are the vehicle's, the others the arms' joints."""


def labelled_states(run_dir: Path) -> tuple[np.ndarray, np.ndarray, dict]:
    """The run's stored observations and labels (flattened over its environments) and its ``config.yml`` entry."""
    buffer = load_from_pkl(run_dir / "replay_buffer.pkl")
    n = buffer.buffer_size if buffer.full else buffer.pos
    obs = buffer.observations[:n].reshape(-1, buffer.observations.shape[-1]).astype(np.float32)
    labels = buffer.labels[:n].reshape(-1, buffer.labels.shape[-1]).astype(np.float32)
    config = yaml.safe_load((run_dir / "config.yml").read_text())["config"]
    return obs, labels, config


def split(n: int, train_fraction: float, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Masks of the training and held-out states: whole blocks, :data:`HELD_OUT` of them held out."""
    rng = np.random.default_rng(seed)
    block = np.arange(n) // BLOCK
    held = (rng.random(block.max() + 1) < HELD_OUT)[block]
    kept = (rng.random(block.max() + 1) < train_fraction)[block] & ~held
    return kept, held


def fit(x: th.Tensor, y: th.Tensor, net: tuple[int, ...], steps: int, weight_decay: float) -> th.nn.Module:
    """A fresh MLP fitted to ``(x, y)`` by least squares (see the module)."""
    th.manual_seed(0)
    layers: list[th.nn.Module] = []
    width = x.shape[1]
    for size in net:
        layers += [th.nn.Linear(width, size), th.nn.ReLU()]
        width = size
    model = th.nn.Sequential(*layers, th.nn.Linear(width, y.shape[1]), th.nn.Tanh())
    optim = th.optim.AdamW if weight_decay else th.optim.Adam
    opt = optim(model.parameters(), lr=1e-3, **({"weight_decay": weight_decay} if weight_decay else {}))
    draws = th.Generator().manual_seed(0)
    for k in range(steps):
        for group in opt.param_groups:
            group["lr"] = 1e-3 * (1 - k / steps)
        idx = th.randint(0, len(x), (256,), generator=draws)
        loss = ((model(x[idx]) - y[idx]) ** 2).mean()
        opt.zero_grad()
        loss.backward()
        opt.step()
    return model


def errors(model: th.nn.Module, obs: np.ndarray, labels: np.ndarray, opening: slice | None) -> dict[str, float]:
    """Mean squared error per command, overall and by kind of state and command."""
    with th.no_grad():
        err = ((model(th.as_tensor(obs)) - th.as_tensor(labels)) ** 2).numpy()
    groups = {"all": np.ones(len(err), dtype=bool), "hold": reference_at_rest(obs)}
    if opening is not None:
        groups["near_obstacle"] = np.linalg.norm(obs[:, opening], axis=1) > 0
        groups["elsewhere"] = ~groups["near_obstacle"]
    out = {name: float(err[mask].mean()) for name, mask in groups.items() if mask.any()}
    out |= {"vehicle": float(err[:, :VEHICLE].mean()), "arms": float(err[:, VEHICLE:].mean())}
    out["share_of_states_near_obstacle"] = float(groups["near_obstacle"].mean()) if opening is not None else None
    return out


def main(argv: list[str] | None = None) -> int:
    """Parse the arguments, fit, print the JSON record."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run_dir", type=Path)
    parser.add_argument("--steps", type=int, default=25000)
    parser.add_argument("--net", default="256x256", help="hidden layer sizes, e.g. 512x512")
    parser.add_argument("--weight-decay", type=float, default=0.0)
    parser.add_argument("--train-fraction", type=float, default=1.0, help="share of the non-held-out episodes fitted")
    parser.add_argument("--threads", type=int, default=2)
    args = parser.parse_args(argv)
    th.set_num_threads(args.threads)
    obs, labels, config = labelled_states(args.run_dir)
    end = obs.shape[1] - (TRACKING_SIZE if config.get("tracking_features") else 0)
    opening = slice(end - OPENING_SUM, end) if config.get("obstacle_features") else None
    kept, held = split(len(obs), args.train_fraction)
    net = tuple(int(v) for v in args.net.split("x"))
    model = fit(th.as_tensor(obs[kept]), th.as_tensor(labels[kept]), net, args.steps, args.weight_decay)
    record = {
        "run_dir": str(args.run_dir),
        "states": {"training": int(kept.sum()), "held_out": int(held.sum())},
        "label_variance": float(labels.var(axis=0).mean()),
        "arguments": {k: (str(v) if isinstance(v, Path) else v) for k, v in vars(args).items()},
        "training": errors(model, obs[kept], labels[kept], opening),
        "held_out": errors(model, obs[held], labels[held], opening),
    }
    sys.stdout.write(json.dumps(record, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
