"""Building blocks every other part of :mod:`agents` uses (as SB3's ``common``).

The env factory and vector envs (``envs``, ``vecenv``, ``rollouts`` with :class:`~agents.common.rollouts.RolloutPPO`),
the training-side wrappers, the learning-curve record, the thread policy, the shared names (``names``) and where the
configs and shipped agents live (``paths``), and the module paths removed in 0.4.0 with the loading of files
pickled under them (``legacy``).
"""
