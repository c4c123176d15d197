"""Computing the episodes.

One episode as a job (``jobs``), :func:`~leaderboard.running.runner.run_leaderboard` (``runner``), the per-episode
cache (``cache``), episodes reused from an earlier output (``reuse``), the output folder's lock (``lock``), the Ray
backend (``distributed``) and ``uvdms evaluate`` of one entry (``evaluate``).
"""
