"""Shared utilities of the package, none of them physics.

* :mod:`~uvdms_gym.utils.io`: the atomic JSON writer, numpy-to-JSON, ``mirror_file``;
* :mod:`~uvdms_gym.utils.kwargs`: the ``k=v`` parser and the check of ``gymnasium.make`` keys;
* :mod:`~uvdms_gym.utils.provenance`: package versions, git revision, ``REPO_ROOT``, timing records;
* :mod:`~uvdms_gym.utils.cluster`: Ray session helpers;
* :mod:`~uvdms_gym.utils.display`: whether PyBullet's GUI can open;
* :mod:`~uvdms_gym.utils.jit`: the one numba entry point;
* :mod:`~uvdms_gym.utils.legacy`: the module paths removed in 0.4.0, failing in one line naming their homes.
* :mod:`~uvdms_gym.utils.validation`: the one check of a finite float vector.
"""
