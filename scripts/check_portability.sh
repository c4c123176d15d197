#!/usr/bin/env bash
# Rerun the tests marked `portability` (floats compared across thread counts, processes or machines, or with
# committed numbers) under settings that make this machine compute like another x86-64 CPU: other torch, MKL,
# OpenBLAS, numpy and numba code paths, and other thread counts. See docs/testing.md ("Portability").
#
#   scripts/check_portability.sh                    # every variant, then all of them at once
#   scripts/check_portability.sh -k same_physics    # extra arguments go to pytest
#   PYTHON=.venv/bin/python scripts/check_portability.sh
#
# Exit status: 0 if every variant passed, 1 otherwise (the failing variants are listed at the end).
set -uo pipefail
cd "$(dirname "$0")/.."
PYTHON=${PYTHON:-$( [ -x .venv/bin/python ] && echo .venv/bin/python || echo python3 )}

# numpy's runtime-dispatched SIMD features present on this CPU (X86_V3 ... on numpy >= 2.4, AVX2 FMA3 ... before):
# disabling them all leaves numpy its baseline code paths.
npy_features=$("$PYTHON" -c '
from numpy._core._multiarray_umath import __cpu_baseline__, __cpu_dispatch__, __cpu_features__
print(",".join(f for f in __cpu_dispatch__ if __cpu_features__.get(f) and f not in __cpu_baseline__))')
numba_cache=$(mktemp -d)  # numba kernels built for a generic CPU, kept apart from the project's cache
trap 'rm -rf "$numba_cache"' EXIT
[ -n "${OPENBLAS_CORETYPE:-}" ] && echo "note: OPENBLAS_CORETYPE=$OPENBLAS_CORETYPE is set here; variants override it"

variants=(
  "OMP_NUM_THREADS=1"                      # one thread for torch (intra-op), MKL and OpenBLAS
  "OMP_NUM_THREADS=2"                      # two
  "MKL_CBWR=COMPATIBLE"                    # torch's MKL matrix products: the SSE2 code path instead of this CPU's
  "ATEN_CPU_CAPABILITY=default"            # torch's own vectorised kernels without AVX2/AVX-512
  "OPENBLAS_CORETYPE=Prescott"             # numpy/scipy's OpenBLAS: SSE3 kernels without fused multiply-adds
  "NPY_DISABLE_CPU_FEATURES=$npy_features" # numpy's ufuncs without their AVX2/AVX-512 loops
  "NUMBA_CPU_NAME=generic NUMBA_CACHE_DIR=$numba_cache" # numba kernels compiled for a generic x86-64
)
variants+=("MKL_CBWR=COMPATIBLE ATEN_CPU_CAPABILITY=default OPENBLAS_CORETYPE=Prescott \
NPY_DISABLE_CPU_FEATURES=$npy_features NUMBA_CPU_NAME=generic NUMBA_CACHE_DIR=$numba_cache OMP_NUM_THREADS=2")

failed=()
for variant in "${variants[@]}"; do
  echo "=== $variant"
  # shellcheck disable=SC2086  # the variant is a list of NAME=VALUE words
  if ! env $variant "$PYTHON" -m pytest -q -n 0 -p no:cacheprovider -m portability "$@"; then
    failed+=("$variant")
  fi
done
if [ ${#failed[@]} -gt 0 ]; then
  printf 'failed under: %s\n' "${failed[@]}"
  exit 1
fi
echo "every variant passed"
