"""The paper's reproduction (``uvdms reproduce``): experiments, acceptance checks and figures.

* :mod:`~baselines.paper.reproduce`: the experiments, the acceptance checks and ``summary.md``;
* :mod:`~baselines.paper.figures`: the figures, numbered like the paper's;
* :mod:`~baselines.paper.obstacle_figure`: the scripted outer-obstacle scenario and its figure.
"""
