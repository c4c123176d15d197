"""What the leaderboard ranks, and on what.

The task suite, tracks and evaluation seeds (``tasks``), the entries (``entries``: baselines, agent folders,
multi-seed folders), an agent folder's plain-text records (``agent_files``), what an entry is made of
(``entry_info``) and the controller registry that resolves a name or a path to a controller (``registry``).
"""
