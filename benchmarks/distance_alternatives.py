"""The exact-distance implementations that were measured for the speed work, side by side (JSON medians, µs).

    python benchmarks/distance_alternatives.py

* ``numba``: ``compute_distances(kin, "exact")`` (the default, compiled kernels);
* ``numpy_reference``: ``compute_distances_reference(kin)`` (the vectorized numpy version);
* ``coal_*``: Pinocchio + coal ``computeDistances`` on the same 90 pairs (capsules on the link axes; the
  plates as boxes of their thickness, which would still need a conversion to the mid-surface convention):
  the C++ call alone, with the 90 distances read back into numpy, and with the closest points as well.

As a check that the coal model is the same geometry, the link-link rows from coal (capsule distance + 2 r,
minimum over the left links) are compared with the exact rows (``max_link_link_diff``).
"""

from __future__ import annotations

import json
import timeit

import coal
import numpy as np
import pinocchio as pin

from uvdms_gym import distances as D
from uvdms_gym.physics.kinematics import KinematicModel
from uvdms_gym.physics.model import link_segment
from uvdms_gym.physics.params import UVDMSParams


def _coal_geometry(params, model):
    gm = pin.GeometryModel()
    ids = {}
    for side in ("left", "right"):
        for i in range(params.arm.n_links):
            f = model.frames[model.getFrameId(f"{side}_link{i}")]
            a, b = link_segment(params, i)
            length = float(np.linalg.norm(b - a))
            z = (b - a) / length
            x = np.cross(z, [1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.cross(z, [0.0, 1.0, 0.0])
            x /= np.linalg.norm(x)
            placement = f.placement * pin.SE3(np.column_stack([x, np.cross(z, x), z]), 0.5 * (a + b))
            shape = coal.Capsule(params.arm.link_radius, length)
            obj = pin.GeometryObject(f"{side}_link{i}", f.parentJoint, f.parentFrame, placement, shape)
            ids[f"{side}_link{i}"] = gm.addGeometryObject(obj)
    fv = model.frames[model.getFrameId("vehicle")]
    for k, pl in enumerate(params.plates):
        u, v = np.array(pl.u), np.array(pl.v)
        placement = fv.placement * pin.SE3(np.column_stack([u, v, np.cross(u, v)]), np.array(pl.center))
        shape = coal.Box(2 * pl.half_extents[0], 2 * pl.half_extents[1], pl.thickness)
        ids[f"plate{k}"] = gm.addGeometryObject(
            pin.GeometryObject(f"plate{k}", fv.parentJoint, fv.parentFrame, placement, shape)
        )
    for i in range(1, 7):
        for j in range(7):
            gm.addCollisionPair(pin.CollisionPair(ids[f"right_link{i}"], ids[f"left_link{j}"]))
        for side in ("right", "left"):
            for k in range(len(params.plates)):
                gm.addCollisionPair(pin.CollisionPair(ids[f"{side}_link{i}"], ids[f"plate{k}"]))
    return gm


def _median_us(fn, number: int) -> float:
    fn()
    return float(np.median(timeit.repeat(fn, number=number, repeat=9)) / number * 1e6)


def main() -> None:
    """Print the medians and the coal geometry check as JSON."""
    params = UVDMSParams()
    kin = KinematicModel(params)
    kin.set_state(np.array([2.0, 0.0, 3.0, 0.1, 0.2, 0.3]), np.full(12, 0.4))
    gm = _coal_geometry(params, kin.model)
    gd = pin.GeometryData(gm)
    n_left = params.arm.n_links
    n_per_right = n_left + 2 * len(params.plates)  # pair order: per right link i, 7 left links then plates

    def coal_call():
        pin.updateGeometryPlacements(kin.model, kin.data, gm, gd)
        pin.computeDistances(gm, gd)

    def coal_distances():
        coal_call()
        return np.array([r.min_distance for r in gd.distanceResults])

    def coal_points():
        coal_call()
        return [(r.min_distance, r.getNearestPoint1(), r.getNearestPoint2()) for r in gd.distanceResults]

    link_link = coal_distances().reshape(6, n_per_right)[:, :n_left].min(1) + 2 * params.arm.link_radius
    out = {
        "pairs": len(gm.collisionPairs),
        "max_link_link_diff": float(np.abs(link_link - D.compute_distances(kin).d[:6]).max()),
        "numba_us": _median_us(lambda: D.compute_distances(kin), 2000),
        "numpy_reference_us": _median_us(lambda: D.compute_distances_reference(kin), 300),
        "coal_call_us": _median_us(coal_call, 1000),
        "coal_with_distances_us": _median_us(coal_distances, 1000),
        "coal_with_points_us": _median_us(coal_points, 300),
    }
    print(json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
