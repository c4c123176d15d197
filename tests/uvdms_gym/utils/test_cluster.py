"""``uvdms_gym.utils.cluster.ray_session``: without an address, a new local instance, whatever else runs here."""

from __future__ import annotations

import pytest

from tests.support.ray_cluster import ray_processes  # noqa: F401  (fixture)
from uvdms_gym.utils.cluster import ray_session

pytestmark = pytest.mark.slow  # a Ray instance


def test_no_address_starts_a_local_instance_beside_a_running_cluster(ray_processes, monkeypatch):  # noqa: F811
    from ray.cluster_utils import Cluster

    cluster = Cluster(initialize_head=True, head_node_args={"num_cpus": 1})  # records itself as this machine's
    try:
        monkeypatch.setenv("RAY_ADDRESS", cluster.address)  # and a user's environment pointing at it
        with ray_session(num_cpus=2) as ray:  # ray.init() would join the cluster and refuse num_cpus
            assert ray.cluster_resources()["CPU"] == 2
            assert ray.get_runtime_context().gcs_address != cluster.address
        with ray_session(address=cluster.address) as ray:  # an explicit address still joins it
            assert ray.cluster_resources()["CPU"] == 1
    finally:
        cluster.shutdown()


def test_a_local_instance_runs_its_workers_at_the_callers_priority(ray_processes, monkeypatch):  # noqa: F811
    import os

    monkeypatch.delenv("RAY_worker_niceness", raising=False)
    with ray_session(num_cpus=1) as ray:
        niceness = ray.get(ray.remote(lambda: os.nice(0)).remote())
    assert niceness == os.nice(0)  # Ray's default would be 15 above it
