"""``realism=0`` is the oracle of release 0.5.0: the same trajectories, observations and rewards, bit for bit.

``tests/data/v1_reference_trajectories.npz`` was recorded by ``benchmarks/record_v1_reference.py`` on release 0.5.0
(commit 1191a35, before the ``realism`` keyword existed) for every v1 id and the obstacle task. On the machine that
recorded it (its ``machine`` entry: CPU model, numpy and pybullet versions) the comparison is exact equality; on
another CPU numpy's transcendental functions may differ in the last bit (``test_same_physics.py``), so there the
states are compared to 1e-9, as the v0 reference is.
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

HERE = Path(__file__).resolve().parents[2]  # tests/
_RECORDER = HERE.parent / "benchmarks" / "record_v1_reference.py"
_spec = importlib.util.spec_from_file_location("record_v1_reference", _RECORDER)
recorder = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(recorder)
REFERENCE = np.load(HERE / "data" / "v1_reference_trajectories.npz")
SAME_MACHINE = str(REFERENCE["machine"]) == recorder.machine()


@pytest.mark.parametrize("realism", [None, 0, {"level": 0}])
@pytest.mark.parametrize("name", list(recorder.CASES))
def test_realism_zero_replays_release_0_5_0(name, realism):
    extra = {} if realism is None else {"realism": realism}
    now = recorder.record(name, **extra)
    assert len(now[f"{name}/reward"]) == len(REFERENCE[f"{name}/reward"]), "episode length changed"
    for key in ("eta", "nu", "q", "qdot", "distances", "tau", "reward", "obs"):
        ref, got = REFERENCE[f"{name}/{key}"], now[f"{name}/{key}"]
        if SAME_MACHINE:
            np.testing.assert_array_equal(got, ref, err_msg=f"{name}/{key}")
        elif key == "obs":  # float32 values of states that agree to 1e-9
            np.testing.assert_allclose(got, ref, rtol=1e-6, atol=1e-6, err_msg=f"{name}/{key}")
        else:
            np.testing.assert_allclose(got, ref, rtol=0.0, atol=1e-9, err_msg=f"{name}/{key}")
