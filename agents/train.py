"""``python -m agents.train`` and the training names documented at this path (moved to :mod:`agents.training`).

The implementation lives in :mod:`agents.training.train` (the loop and ``--resume``), :mod:`agents.training.spec`
(the run specification) and :mod:`agents.training.segment` (one training segment); this module re-exports the
names users and older code import from ``agents.train`` (``agents.training.train.__all__``) and runs the command
line.
"""

import sys

from agents.training.train import *  # noqa: F403
from agents.training.train import __all__, main  # noqa: F401

if __name__ == "__main__":
    sys.exit(main())
