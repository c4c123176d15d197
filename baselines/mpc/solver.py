"""The ProxSuite build the MPC solves with: the portable (SSE2) build, checked at import (docs/REPRODUCTION.md, QP).

Every module of :mod:`baselines` that solves a QP takes ``proxsuite`` from here (:data:`proxsuite`), so that the
package is imported with its portable build before anything else imports it.
"""

from __future__ import annotations

import importlib
import sys
import types
import warnings

PORTABLE_PROXSUITE_BUILD = "proxsuite_pywrap"
"""Name of ProxSuite's Python module compiled for the base instruction set (SSE2 on x86-64), see
:func:`import_portable_proxsuite`."""


def import_portable_proxsuite() -> types.ModuleType:
    """Import ``proxsuite`` with its portable build rather than the widest SIMD build the CPU supports.

    ``proxsuite/__init__.py`` loads ``proxsuite_pywrap_avx512`` or ``proxsuite_pywrap_avx2`` when
    ``proxsuite.instructionset`` reports the instructions. Those builds are not bit-repeatable across processes:
    some of the solver's work buffers are plain ``malloc`` memory (16-byte aligned) that Eigen's AVX/AVX-512
    kernels read through unaligned maps, peeling a different number of leading elements depending on the
    address modulo 32/64 bytes, which changes the order of floating-point sums. Whether those buffers (1 to 4 MiB
    for the CAMPC transport QP) come from ``mmap`` (fixed alignment) or from the heap (any 16-byte boundary)
    depends on glibc's dynamic mmap threshold, which rises once the process has freed a large mapped block
    (importing ``scipy.stats``, ``matplotlib.pyplot`` or ``torch`` does); so the solution depended on the
    process's history and on each QP object's allocation. The portable build uses 16-byte vectors only, which
    every ``malloc`` block satisfies, and its arithmetic is the same on every x86-64 CPU (docs/REPRODUCTION.md, QP).

    The choice is made by answering ``proxsuite``'s import-time question with a stand-in
    ``proxsuite.instructionset`` module (replaced by the real one afterwards). A Python process can hold only one of the
    builds: if ``proxsuite`` was imported before this module, it is kept and a warning says which build it is.

    Returns:
        The ``proxsuite`` package.
    """
    if "proxsuite" not in sys.modules:
        stub = types.ModuleType("proxsuite.instructionset")
        stub.has_AVX512F = stub.has_AVX2 = lambda: False  # type: ignore[attr-defined]
        sys.modules[stub.__name__] = stub
        try:
            import proxsuite
        finally:
            if sys.modules.get(stub.__name__) is stub:
                del sys.modules[stub.__name__]
        importlib.import_module(stub.__name__)  # the real one, as ``proxsuite.instructionset`` for other users
    import proxsuite

    build = proxsuite_build(proxsuite)
    if build != PORTABLE_PROXSUITE_BUILD:
        warnings.warn(
            f"proxsuite was imported before baselines.mpc.solver and uses its {build} build: MPC results are not "
            "bit-repeatable across processes (import baselines first; docs/REPRODUCTION.md, QP)",
            RuntimeWarning,
            stacklevel=2,
        )
    return proxsuite


def proxsuite_build(module: types.ModuleType) -> str:
    """Name of the compiled module behind the ``proxsuite`` package (``"proxsuite_pywrap"``, ``..._avx2``, ...)."""
    return module.proxqp.dense.QP.__module__.split(".")[1]


proxsuite = import_portable_proxsuite()
PROXSUITE_BUILD = proxsuite_build(proxsuite)
"""The ProxSuite build this process solves with."""
