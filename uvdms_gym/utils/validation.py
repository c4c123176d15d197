"""The one check of a finite float vector, shared by the simulator, the kinematic model, obstacles and currents."""

from __future__ import annotations

import numpy as np


def finite_vector(value: object, n: int, name: str) -> np.ndarray:
    """``value`` as a float array of shape ``(n,)`` with finite entries, else a ``ValueError`` naming ``name``.

    Args:
        value: anything ``numpy.asarray(value, dtype=float)`` accepts.
        n: the required length.
        name: what the value is, the first word of the error message (e.g. ``"tau"``, ``"obstacle position"``).

    Returns:
        ``numpy.asarray(value, dtype=float)`` (no copy when ``value`` already is a float array).

    Raises:
        ValueError: ``value`` is not numeric, has another shape, or contains NaN or inf; the message says which
            (and the indices of NaN and inf).
    """
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be {n} numbers (shape ({n},)), got the non-numeric value {value!r}") from None
    if arr.shape != (n,):
        raise ValueError(f"{name} must be {n} numbers (shape ({n},)), got shape {arr.shape}")
    if not np.isfinite(arr).all():
        bad = [
            f"{kind} at indices {np.flatnonzero(mask).tolist()}"
            for kind, mask in (("NaN", np.isnan(arr)), ("inf", np.isinf(arr)))
            if mask.any()
        ]
        raise ValueError(f"{name} must be finite, got {' and '.join(bad)}")
    return arr
