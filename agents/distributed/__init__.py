"""Many runs at once.

``uvdms sweep`` (``sweep``: seeds x grid; ``worker``: one run on a worker, checkpoints shipped; ``report``: the
summary) and ``uvdms tune`` (``tune``, with the search spaces of ``search_space``), locally or on Ray; ``cli`` registers
both commands.
"""
