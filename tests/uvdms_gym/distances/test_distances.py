"""Tests of uvdms_gym.distances: exact geometry, Algorithm 1 / Theorem 1, PyBullet cross-check, J_dis, S(d).

Every reference here is computed independently of the code under test: segment distances by 1-D convex
minimisation of a point-to-segment (point-to-rectangle) distance along one segment (scipy, on a dense
grid bracket), point-to-rectangle by a dense grid over the rectangle, distances by PyBullet's own
collision engine, and J_dis by central finite differences of d along pin.integrate. The compiled default
path ("exact", numba kernels) is also checked against the numpy reference implementation
(compute_distances_reference / distance_jacobian_reference) to rounding.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from scipy.optimize import minimize_scalar

from tests.support.distances import (
    PARAMS,
    SegmentsOnly,
    check_against_reference,
    random_state,
    ref_point_rect,
    ref_point_segment,
)
from uvdms_gym import distances as D


# ----------------------------------------------------------------------------------------------- helpers
def _convex_min_1d(f, n_grid=401):
    """Minimum of a convex function on [0, 1]: dense grid, then bounded Brent refinement in the bracket."""
    lam = np.linspace(0.0, 1.0, n_grid)
    vals = np.array([f(x) for x in lam])
    k = int(np.argmin(vals))
    lo, hi = lam[max(k - 1, 0)], lam[min(k + 1, n_grid - 1)]
    res = minimize_scalar(f, bounds=(lo, hi), method="bounded", options={"xatol": 1e-12})
    return min(vals[k], res.fun, f(0.0), f(1.0))


def _ref_segment_segment(a0, a1, b0, b1):
    return _convex_min_1d(lambda s: ref_point_segment(a0 + s * (a1 - a0), b0, b1))


def _ref_segment_rect(a0, a1, c, u, v, h):
    return _convex_min_1d(lambda s: ref_point_rect(a0 + s * (a1 - a0), c, u, v, h))


def _random_frame(rng):
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    return q[:, 0], q[:, 1]


def _random_segment_pairs(rng, n, max_len=0.3):
    """Random pairs, with a share of parallel, collinear, intersecting and degenerate cases."""
    pairs = []
    for i in range(n):
        a0 = rng.uniform(-0.3, 0.3, 3)
        da = rng.normal(size=3)
        da *= rng.uniform(0.02, max_len) / np.linalg.norm(da)
        b0 = rng.uniform(-0.3, 0.3, 3)
        db = rng.normal(size=3)
        db *= rng.uniform(0.02, max_len) / np.linalg.norm(db)
        kind = i % 6
        if kind == 1:  # parallel (or anti-parallel), overlapping or not
            db = da * rng.uniform(-1.5, 1.5)
        elif kind == 2:  # collinear
            b0 = a0 + da * rng.uniform(-1.5, 1.5)
            db = da * rng.uniform(-1.0, 1.0)
        elif kind == 3:  # intersecting: both pass through a common point
            x = a0 + rng.uniform(0, 1) * da
            b0 = x - rng.uniform(0, 1) * db
        elif kind == 4:  # nearly parallel
            db = da + 1e-7 * rng.normal(size=3)
        pairs.append((a0, a0 + da, b0, b0 + db))
    return [np.array(x) for x in zip(*pairs)]


# -------------------------------------------------------------------------------------- pure geometry
def test_segment_segment_matches_independent_minimisation():
    rng = np.random.default_rng(1)
    a0, a1, b0, b1 = _random_segment_pairs(rng, 300)
    d, pa, pb_ = D.segment_segment(a0, a1, b0, b1)
    ref = np.array([_ref_segment_segment(*x) for x in zip(a0, a1, b0, b1)])
    # ref is the distance of a feasible pair of points: an upper bound on the true minimum (tight to ~1e-9)
    assert np.all(d <= ref + 1e-13), np.max(d - ref)
    assert np.all(d >= ref - 1e-8), np.max(ref - d)
    # closest points lie on their segments and realise the distance
    np.testing.assert_allclose(np.linalg.norm(pa - pb_, axis=1), d, atol=1e-12)
    on_a = [ref_point_segment(p, x, y) for p, x, y in zip(pa, a0, a1)]
    on_b = [ref_point_segment(p, x, y) for p, x, y in zip(pb_, b0, b1)]
    assert max(on_a) < 1e-12 and max(on_b) < 1e-12
    # intersecting pairs (kind 3) have zero distance
    assert np.all(d[3::6] < 1e-12)


def test_segment_segment_degenerate_and_broadcasting():
    a = np.array([0.0, 0.0, 0.0])
    b = np.array([1.0, 0.0, 0.0])
    p = np.array([0.5, 2.0, 0.0])
    # point vs segment, segment vs point, point vs point
    assert D.segment_segment(p, p, a, b)[0] == pytest.approx(2.0)
    d, pa, _ = D.segment_segment(a, b, p, p)
    assert d == pytest.approx(2.0)
    np.testing.assert_allclose(pa, [0.5, 0.0, 0.0])
    assert D.segment_segment(a, a, p, p)[0] == pytest.approx(np.linalg.norm(p))
    # parallel overlapping: the line distance; parallel disjoint: end point to end point
    near, far = np.array([0.3, 0.1, 0.0]), np.array([2.0, 0.1, 0.0])
    assert D.segment_segment(a, b, a + near, b + near)[0] == pytest.approx(0.1)
    assert D.segment_segment(a, b, a + far, b + far)[0] == pytest.approx(np.hypot(1.0, 0.1))
    # broadcasting over leading dims
    rng = np.random.default_rng(2)
    A0, A1 = rng.normal(size=(4, 1, 3)), rng.normal(size=(4, 1, 3))
    B0, B1 = rng.normal(size=(1, 5, 3)), rng.normal(size=(1, 5, 3))
    d, pa, _ = D.segment_segment(A0, A1, B0, B1)
    assert d.shape == (4, 5) and pa.shape == (4, 5, 3)
    assert d[2, 3] == pytest.approx(D.segment_segment(A0[2, 0], A1[2, 0], B0[0, 3], B1[0, 3])[0])


def test_point_segment_and_point_rectangle_against_dense_grids():
    rng = np.random.default_rng(3)
    for _ in range(30):
        a, b, p = rng.normal(size=(3, 3))
        lam = np.linspace(0, 1, 20001)[:, None]
        ref = np.linalg.norm(a + lam * (b - a) - p, axis=1).min()
        d, q = D.point_segment(p, a, b)
        assert ref - 1e-6 <= d <= ref + 1e-12
        assert np.linalg.norm(q - p) == pytest.approx(d)
    for _ in range(30):
        c = rng.normal(size=3)
        u, v = _random_frame(rng)
        h = rng.uniform(0.05, 0.4, 2)
        p = c + rng.normal(scale=0.3, size=3)
        s, t = np.meshgrid(np.linspace(-h[0], h[0], 401), np.linspace(-h[1], h[1], 401))
        grid = c + s.reshape(-1, 1) * u + t.reshape(-1, 1) * v
        ref = np.linalg.norm(grid - p, axis=1).min()
        d, q = D.point_rectangle(p, c, u, v, h)
        assert ref - 2e-3 <= d <= ref + 1e-12  # grid spacing <= 2 mm
        assert abs((q - c) @ u) <= h[0] + 1e-12 and abs((q - c) @ v) <= h[1] + 1e-12


def _random_link_rect_pairs(rng, n, max_len=0.3):
    out = []
    for i in range(n):
        c = rng.uniform(-0.2, 0.2, 3)
        u, v = _random_frame(rng)
        h = rng.uniform(0.03, 0.3, 2)
        a0 = c + rng.normal(scale=0.25, size=3)
        da = rng.normal(size=3)
        da *= rng.uniform(0.02, max_len) / np.linalg.norm(da)
        kind = i % 5
        if kind == 1:  # parallel to the plate
            da -= (da @ np.cross(u, v)) * np.cross(u, v)
        elif kind == 2:  # parallel to an edge
            da = u * rng.uniform(0.02, max_len)
        elif kind == 3:  # crossing the plate inside
            x = c + rng.uniform(-1, 1) * h[0] * u + rng.uniform(-1, 1) * h[1] * v
            a0 = x - rng.uniform(0, 1) * da
        out.append((a0, a0 + da, c, u, v, h))
    return [np.array(x) for x in zip(*out)]


def test_segment_rectangle_matches_independent_minimisation():
    rng = np.random.default_rng(4)
    a0, a1, c, u, v, h = _random_link_rect_pairs(rng, 300)
    d, p, e = D.segment_rectangle(a0, a1, c, u, v, h)
    ref = np.array([_ref_segment_rect(*x) for x in zip(a0, a1, c, u, v, h)])
    assert np.all(d <= ref + 1e-13), np.max(d - ref)
    assert np.all(d >= ref - 1e-8), np.max(ref - d)
    np.testing.assert_allclose(np.linalg.norm(p - e, axis=1), d, atol=1e-12)
    assert max(ref_point_rect(x, *r) for x, *r in zip(e, c, u, v, h)) < 1e-12
    assert max(ref_point_segment(x, y, z) for x, y, z in zip(p, a0, a1)) < 1e-12
    assert np.all(d[3::5] < 1e-12)  # crossing cases


# ----------------------------------------------------------------------------- Algorithm 1 / Theorem 1
N_SAMPLES = 20


def test_sample_segment_includes_both_ends():
    pts = D.sample_segment(np.zeros(3), np.array([1.0, 0.0, 0.0]), 4)
    np.testing.assert_allclose(pts[:, 0], [0, 0.25, 0.5, 0.75, 1.0])


def test_theorem1_segment_pairs():
    """d' <= d* always; with both ends sampled, r/2 <= d* - d' <= r = |AB|/n (tight: d' = d - r).

    So the error bound for n = 20 is |AB|/20: <= 1 cm for |AB| <= 0.2 m (every UVDMS link, the longest is
    0.2 m), <= 1.5 cm for |AB| <= 0.3 m. The paper's "error within 1 cm with n >= 20" holds for these links;
    a 0.3 m link would need n >= 30 (checked below: the error does reach r).
    """
    rng = np.random.default_rng(5)
    a0, a1, b0, b1 = _random_segment_pairs(rng, 1000)
    d_star = D.segment_segment(a0, a1, b0, b1)[0]
    d_p, p, e = D.algorithm1_segment(a0, a1, b0, b1, N_SAMPLES)
    r = np.linalg.norm(a1 - a0, axis=1) / N_SAMPLES
    err = d_star - d_p
    assert np.all(err > 0.0)  # Theorem 1 (strict, since r > 0)
    assert np.all(err <= r + 1e-12)
    assert np.all(err >= r / 2 - 1e-12)
    short = np.linalg.norm(a1 - a0, axis=1) <= 0.2
    assert short.sum() > 500 and np.all(err[short] <= 0.01 + 1e-12)
    assert err.max() > 0.0125  # for links up to 0.3 m the 1 cm claim does not hold at n = 20
    np.testing.assert_allclose(np.linalg.norm(e - p, axis=1), d_p + r, atol=1e-12)


def test_theorem1_link_rectangle_pairs():
    rng = np.random.default_rng(6)
    a0, a1, c, u, v, h = _random_link_rect_pairs(rng, 1000)
    d_star = D.segment_rectangle(a0, a1, c, u, v, h)[0]
    d_p, _, _ = D.algorithm1_rectangle(a0, a1, c, u, v, h, N_SAMPLES)
    r = np.linalg.norm(a1 - a0, axis=1) / N_SAMPLES
    err = d_star - d_p
    assert np.all(err > 0.0)
    assert np.all(err <= r + 1e-12) and np.all(err >= r / 2 - 1e-12)
    short = np.linalg.norm(a1 - a0, axis=1) <= 0.2
    assert np.all(err[short] <= 0.01 + 1e-12)


def test_algorithm1_min_over_several_obstacles():
    rng = np.random.default_rng(7)
    a, b = rng.normal(size=(2, 5, 3))
    c, d = rng.normal(size=(2, 5, 7, 3))
    d_many = D.algorithm1_segment(a, b, c, d, 10)[0]
    d_each = np.array([[D.algorithm1_segment(a[i], b[i], c[i, j], d[i, j], 10)[0] for j in range(7)] for i in range(5)])
    np.testing.assert_allclose(d_many, d_each.min(axis=1), atol=1e-14)


# ------------------------------------------------------------------------------- the 18 UVDMS distances


def test_exact_rows_match_generic_geometry(kin):
    rng = np.random.default_rng(8)
    for it in range(100):
        eta, q = random_state(rng)
        if it % 2:  # joint angles in {-90, 0, 90} deg: many parallel and collinear link pairs (q = 0 first)
            q = 0.5 * np.pi * rng.integers(-1, 2, 12) * (it > 1)
        kin.set_state(eta, q)
        res = D.compute_distances(kin)
        seg = kin.link_segments()
        plates = kin.plates()
        for i in range(6):  # right link i+1 vs every left link
            a0, a1 = seg[1, i + 1]
            dl = [D.segment_segment(a0, a1, *seg[0, j])[0] for j in range(7)]
            assert res.d[i] == pytest.approx(min(dl), abs=1e-12)
            assert dl[res.obstacle_index[i]] == pytest.approx(min(dl), abs=1e-12)  # ties at shared joints
            assert res.link_frame[i] == f"right_link{i + 1}"
            assert res.obstacle_frame[i] == f"left_link{res.obstacle_index[i]}"
        for i in range(12):
            side, k = (1, i + 1) if i < 6 else (0, i - 5)
            a0, a1 = seg[side, k]
            dp = [D.segment_rectangle(a0, a1, c, u, v, np.array(h))[0] for c, u, v, h in plates]
            assert res.d[6 + i] == pytest.approx(min(dp), abs=1e-12)
            assert res.d[6 + i] == pytest.approx(dp[res.obstacle_index[6 + i]], abs=1e-12)
            assert res.link_frame[6 + i] == f"{D.SIDES[side]}_link{k}"
            assert res.obstacle_frame[6 + i] == "vehicle"
            c, u, v, h = plates[res.obstacle_index[6 + i]]
            assert ref_point_rect(res.e[6 + i], c, u, v, h) < 1e-12  # E on the plate of kin.plates()
            assert ref_point_segment(res.p[6 + i], a0, a1) < 1e-12
        np.testing.assert_allclose(np.linalg.norm(res.e - res.p, axis=1), res.d, atol=1e-12)


@pytest.mark.slow
def test_exact_link_link_rows_nearly_parallel():
    """Right links nearly parallel (~1e-8 .. 1e-4 rad) to left links, partly overlapping."""
    rng = np.random.default_rng(13)
    for _ in range(12):
        seg = np.empty((2, 7, 2, 3))
        base_dir = rng.normal(size=3)
        base_dir /= np.linalg.norm(base_dir)
        for side in range(2):
            for k in range(7):
                a0 = rng.uniform(-0.3, 0.3, 3)
                tilt = 10.0 ** rng.uniform(-8, -4) * rng.normal(size=3)
                seg[side, k] = a0, a0 + rng.uniform(0.05, 0.3) * (base_dir + tilt)
        res = D.compute_distances(SegmentsOnly(seg))
        check_against_reference(res, D.compute_distances_reference(SegmentsOnly(seg)), seg, unique_points=False)
        for i in range(6):
            a0, a1 = seg[1, i + 1]
            ref = min(_ref_segment_segment(a0, a1, *seg[0, j]) for j in range(7))
            assert ref - 1e-8 <= res.d[i] <= ref + 1e-13


@pytest.mark.slow
def test_exact_link_plate_rows_degenerate_placements():
    """Links near the plates: parallel to a plate, parallel to an edge, beside edges/corners, crossing."""
    rng = np.random.default_rng(14)
    plates = SegmentsOnly(None).plates()
    for _ in range(12):
        seg = np.empty((2, 7, 2, 3))
        for side in range(2):
            for k in range(7):
                c, u, v, h = plates[rng.integers(len(plates))]
                n = np.cross(u, v)
                s0, t0 = rng.uniform(-1.3, 1.3, 2) * h
                a0 = c + s0 * u + t0 * v + rng.uniform(-0.06, 0.06) * n
                kind = rng.integers(4)
                length = rng.uniform(0.05, 0.2)
                if kind == 0:  # parallel to the plate
                    w = rng.normal(size=2)
                    da = length * (w[0] * u + w[1] * v) / np.linalg.norm(w)
                elif kind == 1:  # parallel to an edge
                    da = length * (u if rng.random() < 0.5 else v) * rng.choice([-1.0, 1.0])
                else:
                    da = rng.normal(size=3)
                    da *= length / np.linalg.norm(da)
                seg[side, k] = a0, a0 + da
        res = D.compute_distances(SegmentsOnly(seg))
        check_against_reference(res, D.compute_distances_reference(SegmentsOnly(seg)), seg, unique_points=False)
        for i in range(12):
            a0, a1 = seg[1, i + 1] if i < 6 else seg[0, i - 5]
            ref = min(_ref_segment_rect(a0, a1, c, u, v, np.array(h)) for c, u, v, h in plates)
            assert ref - 1e-8 <= res.d[6 + i] <= ref + 1e-13


def test_sampled_rows_are_conservative(kin):
    rng = np.random.default_rng(9)
    seg_len = np.r_[PARAMS.arm.link_length[1:], PARAMS.arm.link_length[1:], PARAMS.arm.link_length[1:]]
    r = seg_len / N_SAMPLES
    for _ in range(50):
        kin.set_state(*random_state(rng))
        ex = D.compute_distances(kin, "exact")
        sa = D.compute_distances(kin, "sampled", n=N_SAMPLES)
        err = ex.d - sa.d
        assert np.all(err > 0.0) and np.all(err <= r + 1e-12) and np.all(err <= 0.01 + 1e-12)
        np.testing.assert_allclose(np.linalg.norm(sa.e - sa.p, axis=1), sa.d + r, atol=1e-12)


# ---------------------------------------------------------------------------------------------- J_dis
def _unique_rows(kin, res, gap=0.005, min_angle=0.05):
    """Rows whose closest-point pair is unique and whose nearest obstacle does not switch nearby."""
    seg = kin.link_segments()
    plates = kin.plates()
    ok = np.zeros(18, dtype=bool)
    for i in range(6):
        a0, a1 = seg[1, i + 1]
        dl = np.array([D.segment_segment(a0, a1, *seg[0, j])[0] for j in range(7)])
        j = res.obstacle_index[i]
        b0, b1 = seg[0, j]
        da, db = (a1 - a0) / np.linalg.norm(a1 - a0), (b1 - b0) / np.linalg.norm(b1 - b0)
        second = np.partition(dl, 1)[1]
        ok[i] = np.linalg.norm(np.cross(da, db)) > min_angle and second - dl[j] > gap and res.d[i] > 0.01
    for i in range(12):
        side, k = (1, i + 1) if i < 6 else (0, i - 5)
        a0, a1 = seg[side, k]
        dp = np.array([D.segment_rectangle(a0, a1, c, u, v, np.array(h))[0] for c, u, v, h in plates])
        _, u, v, _ = plates[res.obstacle_index[6 + i]]
        da = (a1 - a0) / np.linalg.norm(a1 - a0)
        second = np.partition(dp, 1)[1]
        ok[6 + i] = abs(da @ np.cross(u, v)) > min_angle and second - dp.min() > gap and res.d[6 + i] > 0.01
    return ok


def test_distance_jacobian_matches_point_jacobians_and_finite_differences(kin):
    rng = np.random.default_rng(11)
    eps = 1e-6
    n_checked = 0
    for _ in range(40):
        eta, q = random_state(rng)
        kin.set_state(eta, q)
        res = D.compute_distances(kin)
        jd = D.distance_jacobian(kin, res)
        # reference from the full 3x18 point Jacobians of both closest points
        jref = np.array(
            [
                res.normals[i]
                @ (
                    kin.point_jacobian(res.link_frame[i], res.p[i])
                    - kin.point_jacobian(res.obstacle_frame[i], res.e[i])
                )
                for i in range(18)
            ]
        )
        assert np.abs(jref[:, :6]).max() < 1e-12  # the vehicle's own motion cancels in every row
        np.testing.assert_allclose(jd, jref, atol=1e-12)
        np.testing.assert_allclose(D.distance_jacobian_reference(kin, res), jref, atol=1e-12)
        assert np.all(jd[:, :6] == 0.0)
        ok = _unique_rows(kin, res)
        config = kin.config.copy()
        for _ in range(3):
            zeta = rng.normal(size=18)
            kin.set_configuration(pin.integrate(kin.model, config, eps * zeta))
            d_plus = D.compute_distances(kin).d
            kin.set_configuration(pin.integrate(kin.model, config, -eps * zeta))
            d_minus = D.compute_distances(kin).d
            fd = (d_plus - d_minus) / (2 * eps)
            np.testing.assert_allclose(fd[ok], -(jd @ zeta)[ok], atol=2e-6, rtol=1e-5)
            n_checked += int(ok.sum())
        kin.set_configuration(config)
    assert n_checked > 40 * 3 * 18 * 0.4  # most rows qualify (measured: 55 %)


def test_distance_jacobian_base_motion_does_not_change_distances(kin):
    rng = np.random.default_rng(12)
    kin.set_state(*random_state(rng))
    d0 = D.compute_distances(kin).d
    config = kin.config.copy()
    zeta = np.zeros(18)
    zeta[:6] = rng.normal(size=6)
    kin.set_configuration(pin.integrate(kin.model, config, zeta))
    np.testing.assert_allclose(D.compute_distances(kin).d, d0, atol=1e-12)


# -------------------------------------------------------------------------------------- velocity damper
def test_velocity_damper():
    d1, d2 = 0.05, 0.12
    assert D.velocity_damper(d1) == 0.0
    assert D.velocity_damper(d2) == pytest.approx(1.0, abs=1e-15)
    assert D.velocity_damper(0.5 * (d1 + d2)) == pytest.approx(0.5)  # sin^2(pi/4)
    assert D.velocity_damper(0.0) == 0.0 and D.velocity_damper(-1.0) == 0.0
    assert D.velocity_damper(0.3) == 1.0
    x = d1 + 0.25 * (d2 - d1)
    assert D.velocity_damper(x) == pytest.approx(np.sin(np.pi / 8) ** 2)
    d = np.linspace(-0.1, 0.3, 2001)
    s = D.velocity_damper(d)
    assert s.shape == d.shape and np.all(np.diff(s) >= 0.0)
    assert np.all((s > 0) == (d > d1)) and np.all((s < 1) == (d < d2 - 1e-12))
    # continuous (Lipschitz with the sin^2 slope bound pi / (2 (d2 - d1))): no jump at d1 or d2
    assert np.abs(np.diff(s)).max() <= np.pi / (2 * (d2 - d1)) * (d[1] - d[0]) + 1e-12
    np.testing.assert_allclose(D.velocity_damper(d, 0.1, 0.2)[d >= 0.2], 1.0)
