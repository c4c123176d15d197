"""Record the v1 reference trajectories of ``realism=0`` (``tests/uvdms_gym/realism/test_realism_zero.py``).

Run once on the code whose physics is the reference (it was run on release 0.5.0, commit 1191a35, before the
``realism`` keyword existed):

    python benchmarks/record_v1_reference.py tests/data/v1_reference_trajectories.npz

Each case is a registered v1 id with fixed kwargs, seed and a fixed action sequence drawn from a seeded
generator; the file stores, per step, the state (eta, nu, q, qdot), the observation, the reward and the 18
distances; ``machine`` records where it ran (CPU model, numpy and pybullet versions): on the same machine the
test asks for equality bit for bit.
"""

from __future__ import annotations

import hashlib
import importlib.util
import platform
import sys
from importlib.metadata import version
from pathlib import Path

import numpy as np

import uvdms_gym  # noqa: F401  (registers the ids)

_V0_PATH = Path(__file__).with_name("record_v0_reference.py")
_spec = importlib.util.spec_from_file_location("record_v0_reference", _V0_PATH)
_V0 = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(_V0)
KEYS: tuple[str, ...] = (*_V0.KEYS, "tau")
"""The ``info`` arrays recorded per step: the v0 recorder's and the applied generalized force."""
_FREE_TORQUE = _V0._FREE_TORQUE
"""Torque mode run through contacts and large errors (the v0 recorder's), so that free dynamics are compared."""
CASES: dict[str, tuple[str, dict, float]] = {
    # name: (id, gym.make kwargs, action amplitude)
    "circle_random_hydro_velocity": ("uvdms/CircleTrack-v1", {"case": "random", "hydro_randomization": 0.3}, 0.5),
    "transport_random_current_velocity": (
        "uvdms/Transport-v1",
        {"goal": "random", "hydro_randomization": 0.3, "current": "random"},
        0.5,
    ),
    "obstacles_random_current_velocity": ("uvdms/TransportObstacles-v1", {"current": "random"}, 0.5),
    "circle_case2_torque": ("uvdms/CircleTrack-v1", {"case": 2, **_FREE_TORQUE}, 0.05),
}


def record(name: str, **extra: object) -> dict[str, np.ndarray]:
    """Roll out one case (its kwargs updated with ``extra``): the v0 recorder's rollout on :data:`CASES`."""
    return _V0.record(name, CASES, KEYS, **extra)


def machine() -> str:
    """Where a recording ran: CPU model, family, model number and flags (hashed), numpy and pybullet versions.

    Equal fingerprints mean the same instruction set and the same library builds, so the same code paths and bits;
    the model name alone is not enough (a virtual machine's "AMD EPYC" spans generations with other SIMD units).
    """
    info: dict[str, str] = {}
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as f:
            for line in f:
                if not line.strip():  # the first processor's block is enough
                    break
                key, _, value = line.partition(":")
                info[key.strip()] = value.strip()
    except OSError:
        pass
    fields = {k: info.get(k, "") for k in ("cpu family", "model", "flags")}
    fields["model name"] = info.get("model name", platform.processor() or platform.machine())
    flags = hashlib.sha256(fields["flags"].encode()).hexdigest()[:12]
    cpu = f"{fields['model name']} (family {fields['cpu family']}, model {fields['model']}, flags {flags})"
    return f"{cpu} | numpy {np.__version__} | pybullet {version('pybullet')}"


def main(path: str) -> None:
    """Record every case into one ``.npz`` file."""
    arrays: dict[str, np.ndarray] = {"machine": np.array(machine())}
    for name in CASES:
        arrays.update(record(name))
    np.savez_compressed(path, **arrays)


if __name__ == "__main__":
    main(sys.argv[1])
