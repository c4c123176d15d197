"""Loading trained agents: the names documented at this path, re-exported from :mod:`agents.export`.

``agents.policy.load_agent("trained_agents/<name>")`` is how the shipped agents' READMEs load them; the
implementation lives in :mod:`agents.export` (controller, SB3 zips, the weights-only format, the loader).
"""

from agents.export import *  # noqa: F403
from agents.export import __all__  # noqa: F401
