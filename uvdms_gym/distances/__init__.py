"""The 18 collision distances: the exact computation, its compiled kernels, the geometry and PyBullet's queries.

* :mod:`~uvdms_gym.distances.exact`: ``compute_distances`` (exact, compiled; sampled: the paper's Algorithm 1),
  closest points, ``distance_jacobian`` (``J_dis``), the velocity damper ``S(d)``, and the numpy references;
* :mod:`~uvdms_gym.distances.kernels`: the numba kernels of the exact distances and ``J_dis``;
* :mod:`~uvdms_gym.distances.geometry`: point/segment/rectangle closest points, Algorithm 1;
* :mod:`~uvdms_gym.distances.pybullet_queries`: the same 18 distances from PyBullet's closest-point queries.

The public names of ``exact`` and ``geometry`` are importable from here (``from uvdms_gym.distances import
compute_distances``), as before the package was split.
"""

from uvdms_gym.distances.exact import (
    LINK_FRAMES,
    N_ROWS,
    ROW_NAMES,
    SIDES,
    DistanceResult,
    compute_distances,
    compute_distances_reference,
    contact_thresholds,
    distance_jacobian,
    distance_jacobian_reference,
    velocity_damper,
)
from uvdms_gym.distances.geometry import (
    algorithm1_rectangle,
    algorithm1_segment,
    point_rectangle,
    point_segment,
    rectangle_edges,
    sample_segment,
    segment_rectangle,
    segment_segment,
)

__all__ = [
    "LINK_FRAMES",
    "N_ROWS",
    "ROW_NAMES",
    "SIDES",
    "DistanceResult",
    "algorithm1_rectangle",
    "algorithm1_segment",
    "compute_distances",
    "compute_distances_reference",
    "contact_thresholds",
    "distance_jacobian",
    "distance_jacobian_reference",
    "point_rectangle",
    "point_segment",
    "rectangle_edges",
    "sample_segment",
    "segment_rectangle",
    "segment_segment",
    "velocity_damper",
]
