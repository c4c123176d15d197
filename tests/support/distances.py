"""Shared pieces of the distance tests: the parameters and random states within the joint limits."""

import numpy as np

from uvdms_gym.physics.params import UVDMSParams

PARAMS = UVDMSParams()


def random_state(rng):
    eta = np.r_[rng.uniform(-3, 3, 3), rng.uniform(-0.8, 0.8, 2), rng.uniform(-np.pi, np.pi)]
    q = rng.uniform(PARAMS.q_min, PARAMS.q_max)
    return eta, q


def ref_point_segment(p, a, b):
    """Plain scalar projection (independent of the vectorized code)."""
    ab = b - a
    den = float(ab @ ab)
    t = 0.0 if den == 0.0 else min(max(float((p - a) @ ab) / den, 0.0), 1.0)
    return float(np.linalg.norm(p - (a + t * ab)))


def ref_point_rect(p, c, u, v, h):
    s = min(max(float((p - c) @ u), -h[0]), h[0])
    t = min(max(float((p - c) @ v), -h[1]), h[1])
    return float(np.linalg.norm(p - (c + s * u + t * v)))


class SegmentsOnly:
    """A stand-in for KinematicModel with arbitrary link segments (vehicle at the origin)."""

    def __init__(self, seg):
        self.seg = seg
        self.params = PARAMS

    def link_segments(self):
        return self.seg

    def frame_placement(self, name):
        assert name == "vehicle"
        return np.zeros(3), np.eye(3)

    def plates(self):
        return [(np.array(p.center), np.array(p.u), np.array(p.v), p.half_extents) for p in PARAMS.plates]


def check_against_reference(res, ref, seg, plates=None, unique_points=True):
    """The kernel's result ``res`` against the numpy reference ``ref`` at the same state.

    Distances agree to 1e-12 in every row. The closest points always lie on their segment / plate and
    realise ``d``. With ``unique_points``, rows with ``d > 1e-9`` must also have the reference's points and
    obstacle (1e-12), except at ties: the minimum is attained on two left links meeting at a joint (the
    choice is rounding noise in both implementations), then ``E`` is that joint point in both (1e-11).
    ``unique_points=False`` is for degenerate placements (parallel pairs: the closest points are not unique).
    """
    plates = SegmentsOnly(None).plates() if plates is None else plates
    np.testing.assert_allclose(res.d, ref.d, rtol=0, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(res.e - res.p, axis=1), res.d, rtol=0, atol=1e-12)
    assert res.obstacle_frame[6:] == ref.obstacle_frame[6:] and res.link_frame == ref.link_frame
    assert res.method == "exact" and res.obstacle_index.dtype.kind == "i"
    n_ties = 0
    for i in range(18):
        side, k = (1, i + 1) if i < 6 else ((1, i - 5) if i < 12 else (0, i - 11))
        assert ref_point_segment(res.p[i], *seg[side, k]) < 1e-12
        j = res.obstacle_index[i]
        if i < 6:
            assert res.obstacle_frame[i] == f"left_link{j}"
            assert ref_point_segment(res.e[i], *seg[0, j]) < 1e-12
        else:
            c, u, v, h = plates[j]
            assert ref_point_rect(res.e[i], c, u, v, h) < 1e-12
        if not unique_points or res.d[i] <= 1e-9:
            continue
        if j == ref.obstacle_index[i]:
            np.testing.assert_allclose(res.p[i], ref.p[i], rtol=0, atol=1e-12)
            np.testing.assert_allclose(res.e[i], ref.e[i], rtol=0, atol=1e-12)
        else:  # a tie between neighbouring left links at their common joint point
            assert i < 6 and abs(j - ref.obstacle_index[i]) == 1, (i, j, ref.obstacle_index[i])
            np.testing.assert_allclose(res.e[i], ref.e[i], rtol=0, atol=1e-11)
            n_ties += 1
    return n_ties
