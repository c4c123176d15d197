"""The one place the project connects to Ray (the ``ray`` extra).

``uvdms leaderboard --backend ray``, ``uvdms sweep`` and ``uvdms tune`` all go through :func:`ray_session`.

Without an address a local Ray instance is started, sized to this machine (``num_cpus`` defaults to
``os.cpu_count()``), and shut down when the session ends, so no Ray process outlives the command. With an
address (``"auto"`` for the cluster this machine belongs to, ``"ray://host:10001"`` for Ray Client, or a
``host:port`` GCS address) the driver joins an existing cluster and only disconnects at the end.
"""

from __future__ import annotations

import contextlib
import os
import socket
from collections.abc import Iterator
from typing import Any

PROBE_TIMEOUT_S = 5.0
"""Seconds to wait for a TCP connection to a cluster address before giving up (:func:`probe_address`)."""
WORKER_NICENESS_ENV = "RAY_worker_niceness"
"""The environment variable the raylet reads its workers' niceness from (Ray's default: 15)."""
RAY_EXTRA_HINT = 'Ray is not installed: pip install -c constraints.txt -e ".[ray]"'


def require_ray() -> Any:
    """Import and return the ``ray`` module, or raise a :class:`RuntimeError` that says how to install it."""
    try:
        import ray
    except ImportError as err:  # pragma: no cover - the test extra installs ray
        raise RuntimeError(RAY_EXTRA_HINT) from err
    return ray


@contextlib.contextmanager
def ray_session(address: str | None = None, num_cpus: int | None = None) -> Iterator[Any]:
    """Connect to Ray for the duration of a ``with`` block and yield the ``ray`` module.

    Args:
        address: ``None`` starts a new local instance (also when ``RAY_ADDRESS`` is set or another cluster runs on
            this machine); otherwise the address of a running cluster (``"auto"``, ``"ray://host:port"``,
            ``"host:port"``).
        num_cpus: CPUs of the local instance (default: every core of this machine). Ignored with ``address``:
            a cluster's CPUs are those its nodes were started with.

    A session that is already connected (a caller's own ``ray.init``) is reused and left connected.

    Raises:
        RuntimeError: Ray is not installed (the message says how to install it).
        ConnectionError: No cluster answers at ``address``.
        ValueError: ``num_cpus < 1``.
    """
    ray = require_ray()
    if ray.is_initialized():
        yield ray
        return
    if num_cpus is not None and num_cpus < 1:
        raise ValueError(f"num_cpus must be >= 1, got {num_cpus}")
    if address is None:
        # Ray starts its workers at nice 15 unless told otherwise: beside anything else busy on this machine (a
        # training run) a tuning trial then got about 3 % of a core and stood still for minutes; the work here
        # is the user's foreground job, so the local instance runs its workers at the caller's priority
        os.environ.setdefault(WORKER_NICENESS_ENV, "0")
        # "local": a new instance even when RAY_ADDRESS is set or a `ray start` cluster runs on this machine
        # (ray.init() without an address would join that one, and refuse num_cpus)
        ray.init(
            address="local", num_cpus=num_cpus or os.cpu_count() or 1, include_dashboard=False, logging_level="WARNING"
        )
    else:
        probe_address(address)
        try:
            ray.init(address=address, logging_level="WARNING")
        except ConnectionError as err:
            raise ConnectionError(f"cannot connect to the Ray cluster at {address!r}: {err}") from err
    try:
        yield ray
    finally:
        ray.shutdown()


def probe_address(address: str, timeout: float = PROBE_TIMEOUT_S) -> None:
    """Raise :class:`ConnectionError` if nothing accepts a TCP connection at a ``host:port`` address.

    ``ray.init`` keeps retrying an address where no cluster listens for minutes; a refused or unanswered TCP
    connection says so in ``timeout`` seconds. ``"auto"`` (Ray finds the cluster of this machine, and fails
    at once when there is none) is not probed.
    """
    target = address.removeprefix("ray://")
    if target == "auto" or ":" not in target:
        return
    host, _, port = target.rpartition(":")
    try:
        with socket.create_connection((host.strip("[]"), int(port)), timeout=timeout):
            return
    except (OSError, ValueError) as err:
        raise ConnectionError(f"cannot connect to the Ray cluster at {address!r}: {err}") from None
