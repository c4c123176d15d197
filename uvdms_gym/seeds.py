"""The seed protocol: training, validation and test seeds in disjoint ranges (``docs/seeds.md``).

Every seed passed to an environment's ``reset()`` belongs to one split:

* ``training`` (``[0, 1e9)``): ``--seed`` of a training run and every seed derived from it (per-worker offsets,
  resumed segments, the training evaluation callback); also ``uvdms tune`` trials and ``uvdms sweep`` runs.
* ``validation`` (``[2e9, 3e9)``): public draws for development: tuning by hand, checkpoint selection and every
  figure of a design discussion. The leaderboards of 0.4.0 and earlier ranked on the first 20 of these
  (``2_000_000_000 + i``), which were used for development too; they are validation draws now.
* ``test`` (``[3e9, 3.5e9)``): the leaderboard's ranking, and nothing else.
* ``test2`` (``[3.5e9, 4e9)``): the leaderboard's second test set (the generalisation check on the randomised
  tasks: the same entries on other unseen draws).

Seeds between the ranges (``[1e9, 2e9)``) belong to no split. Draw ``i`` of a split is the seed ``start + i``
(:func:`split_seeds`); a multi-seed entry spreads the draws of a randomised task over its training seeds
(:func:`assign_draws`), so that ``n`` draws cost ``n`` episodes whatever the number of training seeds.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass

PROTOCOL = "uvdms-seeds-1"
"""Name of this protocol, recorded with every result it produces (and part of the leaderboard's cache keys)."""


@dataclass(frozen=True)
class SeedRange:
    """The seeds ``[start, stop)`` of one split."""

    name: str
    start: int
    stop: int

    def __contains__(self, seed: object) -> bool:
        return isinstance(seed, int) and self.start <= seed < self.stop

    @property
    def size(self) -> int:
        """How many seeds the range holds."""
        return self.stop - self.start


TRAINING = SeedRange("training", 0, 1_000_000_000)
VALIDATION = SeedRange("validation", 2_000_000_000, 3_000_000_000)
TEST = SeedRange("test", 3_000_000_000, 3_500_000_000)
TEST2 = SeedRange("test2", 3_500_000_000, 4_000_000_000)
SPLITS: dict[str, SeedRange] = {r.name: r for r in (TRAINING, VALIDATION, TEST, TEST2)}
"""Every split by name."""
EVALUATION_SPLITS: tuple[str, ...] = ("validation", "test", "test2")
"""The splits an evaluation can be asked for by name (``uvdms evaluate --split``, ``uvdms leaderboard --split``)."""
TEST_SPLITS: tuple[str, ...] = ("test", "test2")
"""The splits only the leaderboard's ranking uses: tuning, sweeps and training never see them."""


class SeedProtocolError(ValueError):
    """A seed outside the split it is used for (a training seed reaching the test range, an unknown split)."""


def seed_range(split: str) -> SeedRange:
    """The range of ``split`` (one of :data:`SPLITS`).

    Raises:
        SeedProtocolError: An unknown split.
    """
    try:
        return SPLITS[split]
    except KeyError:
        raise SeedProtocolError(f"unknown seed split {split!r}; choose from {', '.join(SPLITS)}") from None


def split_of(seed: int) -> str | None:
    """The split holding ``seed`` (``None`` for a seed between the ranges or outside them)."""
    for split in SPLITS.values():
        if int(seed) in split:
            return split.name
    return None


def split_seeds(split: str, count: int, first: int = 0) -> list[int]:
    """Draws ``first, ..., first + count - 1`` of ``split``: the seeds ``start + first + i``.

    Raises:
        SeedProtocolError: An unknown split, a negative ``count`` or ``first``, or draws beyond the range.
    """
    rng = seed_range(split)
    if count < 0 or first < 0:
        raise SeedProtocolError(f"draws of the {split} split need count >= 0 and first >= 0, got {count}, {first}")
    if first + count > rng.size:
        raise SeedProtocolError(f"the {split} split holds {rng.size} seeds, not {first + count}")
    return [rng.start + first + i for i in range(count)]


def assign_draws(draws: Sequence[int], runs: int, run: int) -> list[int]:
    """The draws that run ``run`` of ``runs`` (an entry's training seeds) evaluates: ``draws[i]``, ``i % runs == run``.

    Every draw is evaluated once, by one training seed, in turn; with one run it gets them all.

    Raises:
        ValueError: ``runs < 1`` or ``run`` not in ``[0, runs)``.
    """
    if runs < 1 or not 0 <= run < runs:
        raise ValueError(f"run must be in [0, {runs}), got {run}")
    return [seed for i, seed in enumerate(draws) if i % runs == run]


def check_seeds(seeds: Iterable[int], split: str, what: str) -> None:
    """Refuse, in one line, any of ``seeds`` outside ``split``.

    Args:
        seeds: The seeds to check (e.g. a training seed's largest derived seed).
        split: The split they must belong to.
        what: What they are, for the message (``"training seed 5 (its evaluation envs)"``).

    Raises:
        SeedProtocolError: A seed outside the split, naming it, its split and the allowed range.
    """
    rng = seed_range(split)
    for seed in seeds:
        if int(seed) not in rng:
            actual = split_of(int(seed))
            where = f"in the {actual} split" if actual else "in no split"
            raise SeedProtocolError(
                f"{what}: seed {int(seed)} is {where}; {split} seeds are [{rng.start}, {rng.stop})"
                + (" (test seeds are for the leaderboard's ranking only)" if actual in TEST_SPLITS else "")
            )


def check_not_test(seeds: Iterable[int], what: str) -> None:
    """Refuse, in one line, any of ``seeds`` in a test split (tuning, sweeps and training use no test seed).

    Raises:
        SeedProtocolError: A seed in :data:`TEST_SPLITS`.
    """
    for seed in seeds:
        actual = split_of(int(seed))
        if actual in TEST_SPLITS:
            raise SeedProtocolError(
                f"{what}: seed {int(seed)} is in the {actual} split, which only the leaderboard's ranking uses; "
                f"use training seeds [{TRAINING.start}, {TRAINING.stop}) or validation seeds "
                f"[{VALIDATION.start}, {VALIDATION.stop})"
            )


def protocol_record(split: str) -> dict[str, str]:
    """What a result records of the protocol that produced it: ``{"protocol": PROTOCOL, "split": split}``."""
    seed_range(split)
    return {"protocol": PROTOCOL, "split": split}
