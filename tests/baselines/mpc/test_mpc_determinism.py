"""The MPC baselines repeat bit for bit in any process (docs/REPRODUCTION.md, QP).

Fresh interpreters run a short ``campc`` episode on the paper transport and hash the actions (float64 bytes):
one with nothing else imported, others with ``scipy.stats`` and ``matplotlib.pyplot`` imported first (what
made ProxSuite's SIMD builds take another path), a large array freed (which raises glibc's mmap threshold, so
that the solver's work buffers come from the heap) and several controllers per process, each built after a
differently sized allocation (which moves those buffers to other addresses). Every hash must be the same.
"""

from __future__ import annotations

import subprocess
import sys

import pytest

CHILD = r"""
import sys
heavy, n_controllers = sys.argv[1] == "heavy", int(sys.argv[2])
if heavy:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot  # noqa: F401
    import scipy.stats  # noqa: F401
import hashlib
import gymnasium as gym
import numpy as np
import uvdms_gym  # noqa: F401
from baselines.controllers import make_baseline
from baselines.mpc.solver import PROXSUITE_BUILD
from uvdms_gym.evaluation import run_episode
if heavy:
    np.ones(1 << 21).sum()  # a 16 MiB block mapped and freed: glibc raises its mmap threshold
env = gym.make("uvdms/Transport-v0", goal="paper", action_mode="velocity", max_episode_steps=15)
keep = []
hashes = []
for i in range(n_controllers):
    keep.append(bytearray(1024 + 16 * i))  # (not pymalloc) shift the heap between the controllers' QP buffers
    controller = make_baseline("campc", env)
    digest = hashlib.sha256()
    predict = controller.predict
    def recorded(obs, info, predict=predict, digest=digest):
        action = predict(obs, info)
        digest.update(np.asarray(action, dtype=np.float64).tobytes())
        return action
    controller.predict = recorded
    metrics = run_episode(env, controller, 0)
    digest.update(np.float64(metrics["qp_slack_max"]).tobytes())
    digest.update(np.float64(metrics["final_pos_error"]).tobytes())
    hashes.append(digest.hexdigest())
print(PROXSUITE_BUILD, *hashes)
"""


def _run(mode: str, n_controllers: int) -> tuple[str, list[str]]:
    proc = subprocess.run(
        [sys.executable, "-c", CHILD, mode, str(n_controllers)], capture_output=True, text=True, timeout=240
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    build, *hashes = proc.stdout.strip().splitlines()[-1].split()
    assert len(hashes) == n_controllers
    return build, hashes


@pytest.mark.portability
@pytest.mark.slow
def test_campc_transport_actions_repeat_bit_for_bit_across_processes():
    plain_build, plain = _run("plain", 1)
    heavy_build, heavy = _run("heavy", 6)
    assert plain_build == heavy_build
    assert set(heavy) == set(plain), f"action hashes differ between processes/controllers: {plain} vs {heavy}"


def test_portable_proxsuite_build_is_loaded_and_a_prior_simd_import_is_reported():
    code = (
        "import warnings, proxsuite\n"
        "with warnings.catch_warnings(record=True) as caught:\n"
        "    warnings.simplefilter('always')\n"
        "    from baselines.mpc.solver import PORTABLE_PROXSUITE_BUILD, PROXSUITE_BUILD\n"
        "import proxsuite.instructionset as isa\n"
        "simd = isa.has_AVX2() or isa.has_AVX512F()\n"
        "warned = any('bit-repeatable' in str(w.message) for w in caught)\n"
        "print(PROXSUITE_BUILD == PORTABLE_PROXSUITE_BUILD, simd, warned)\n"
    )
    fresh = subprocess.run(
        [sys.executable, "-c", "from baselines.mpc.solver import PROXSUITE_BUILD; print(PROXSUITE_BUILD)"],
        capture_output=True,
        text=True,
        check=True,
    )
    assert fresh.stdout.split()[-1] == "proxsuite_pywrap"
    prior = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    portable, simd, warned = prior.stdout.split()[-3:]
    # proxsuite imported first keeps its own choice (the widest build on a SIMD CPU); baselines.mpc.solver warns then
    assert portable == str(simd == "False")
    assert warned == str(portable == "False")
