"""Commands and the library leave nothing in the system temp directory.

SB3 makes an empty ``SB3-<date>`` folder per model that learns without a configured logger (``uvdms bench train``
made ~35); the simulator's URDF files live in a per-process folder removed at exit. The one folder that may appear
is torch's own compilation cache (``torchinductor_<user>``, made by torch's Adam on its first step, reused).
"""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap

import pytest

SCRIPT = textwrap.dedent(
    """
    import gymnasium as gym
    import uvdms_gym
    from agents.training.bench import _block, _build

    env = gym.make("uvdms/Transport-v1")
    env.reset(seed=0)
    env.step(env.action_space.sample())
    env.close()
    for algo in ("ppo", "sac"):
        model = _build(algo, 1, "dummy", 64)
        assert _block(model, 32 if algo == "sac" else 64)[0] > 0
        model.get_env().close()
    print("ok")
    """
)


@pytest.mark.slow
def test_an_env_and_bench_train_models_leave_the_temp_directory_as_they_found_it(tmp_path):
    temp = tmp_path / "system_temp"
    temp.mkdir()
    env = {k: v for k, v in os.environ.items() if k != "SB3_LOGDIR"}  # SB3 would fall back to the temp directory
    env["TMPDIR"] = str(temp)
    proc = subprocess.run([sys.executable, "-c", SCRIPT], env=env, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0 and "ok" in proc.stdout, proc.stderr[-2000:]
    left = sorted(p.name for p in temp.iterdir() if not p.name.startswith("torchinductor_"))
    assert left == []
