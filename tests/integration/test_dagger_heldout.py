"""scripts/dagger_heldout.py: whole episodes are held out, disjoint from the fitted ones, and the error is the fit's."""

from __future__ import annotations

import numpy as np
import torch as th

from scripts.dagger_heldout import BLOCK, HELD_OUT, errors, split


def test_split_holds_out_whole_blocks_disjoint_from_the_fitted_ones() -> None:
    n = BLOCK * 400 + 7
    kept, held = split(n, train_fraction=1.0)
    block = np.arange(n) // BLOCK
    for mask in (kept, held):  # a block is wholly in or wholly out
        per_block = np.bincount(block, weights=mask, minlength=block.max() + 1)
        sizes = np.bincount(block)
        assert np.all((per_block == 0) | (per_block == sizes))
    assert not np.any(kept & held) and np.all(kept | held)
    assert abs(held.mean() - HELD_OUT) < 0.05
    half, held_again = split(n, train_fraction=0.5)
    assert np.array_equal(held, held_again)  # the same held-out episodes at every fraction
    assert not np.any(half & ~kept) and 0.35 < half.sum() / kept.sum() < 0.65


def test_errors_are_the_mean_squared_error_of_the_model_by_group() -> None:
    rng = np.random.default_rng(1)
    obs = rng.normal(size=(50, 40)).astype(np.float32)
    obs[:20, 10:28] = 0.0  # no opening direction: not near an obstacle
    labels = rng.uniform(-1, 1, size=(50, 18)).astype(np.float32)
    model = th.nn.Sequential(th.nn.Linear(40, 18), th.nn.Tanh())
    with th.no_grad():
        pred = model(th.as_tensor(obs)).numpy()
    sq = (pred - labels) ** 2
    out = errors(model, obs, labels, slice(10, 28))
    assert np.isclose(out["all"], sq.mean())
    assert np.isclose(out["elsewhere"], sq[:20].mean()) and np.isclose(out["near_obstacle"], sq[20:].mean())
    assert np.isclose(out["vehicle"], sq[:, :6].mean()) and np.isclose(out["arms"], sq[:, 6:].mean())
    assert out["share_of_states_near_obstacle"] == 0.6
