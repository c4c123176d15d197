"""The ``uvdms`` command (layer 2, the composition: it may import every package of the project).

* :mod:`uvdms_cli.main`: the parser, ``uvdms demo`` and ``uvdms bench``, and the one-line error reporting;
* :mod:`uvdms_cli.evaluate`: ``uvdms evaluate`` (a baseline name or an agent path, through
  :mod:`leaderboard.suite.registry`).

The other subcommands register themselves from the packages they drive (``baselines.cli``: ``reproduce``;
``agents.cli``: ``train``, ``export-agent``; ``leaderboard.cli``: ``leaderboard``). ``python -m uvdms_cli`` is
the same as ``uvdms``.
"""

from uvdms_cli.main import main

__all__ = ["main"]
