"""The training loop.

:func:`~agents.training.train.train` and ``--resume`` (``train``), the run specification (``spec``), one training
segment in named steps (``segment``), callbacks, models (buffers, action-layer scaling), run directories (``rundir``),
the command-line parser (``args``) and ``uvdms bench train`` (``bench``).
"""
