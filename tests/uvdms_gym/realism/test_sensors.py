"""The sensor model of uvdms_gym.realism.sensors against its definition (rates, latency, noise, bias, dropouts)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from uvdms_gym.realism.config import LEVELS, SENSOR_DIMS, SENSOR_NAMES, SensorSpec, to_substeps
from uvdms_gym.realism.sensors import Sensor, SensorBank, wrap_pi

DT = 0.01
N_SUB = 4


def _run(sensor: Sensor, truth: np.ndarray, n_steps: int) -> list[tuple[int, float, np.ndarray]]:
    """Sample every due substep 1..n_steps, release every substep: (release substep, t_sample, value)."""
    out = []
    for s in range(1, n_steps + 1):
        if sensor.due(s):
            sensor.sample(s, truth)
        out.extend((s, t, v) for t, v in sensor.release(s))
    return out


def _sensor(name: str, rng_seed: int = 0, truth: np.ndarray | None = None, **spec) -> Sensor:
    sensor = Sensor(name, SensorSpec(**spec), physics_dt=DT, control_substeps=N_SUB)
    sensor.reset(np.random.default_rng(rng_seed), np.zeros(SENSOR_DIMS[name]) if truth is None else truth)
    return sensor


def _initial(k_obstacles: int = 2) -> dict[str, np.ndarray]:
    values = {n: np.linspace(0.1, 0.5, d) for n, d in SENSOR_DIMS.items()}
    values["sonar"] = np.arange(6.0 * k_obstacles).reshape(k_obstacles, 6)
    return values


def test_white_noise_sigma_and_mean():
    sigma = (0.1, 0.2, 0.3)
    truth = np.array([1.0, -2.0, 0.5])
    got = _run(_sensor("dvl", truth=truth, period=0.01, sigma=sigma), truth, 10_000)
    values = np.array([v for _, _, v in got])
    assert values.shape == (10_000, 3)
    np.testing.assert_allclose(values.std(axis=0), sigma, rtol=0.05)
    assert np.all(np.abs(values.mean(axis=0) - truth) < 4 * np.array(sigma) / math.sqrt(10_000))


def test_bias_random_walk_variance_grows_linearly():
    walk, n_steps, seeds = 0.1, 200, 1500
    checks = (50, 100, 200)  # sample indices (period one substep): t = 0.5, 1, 2 s
    at = {k: [] for k in checks}
    for seed in range(seeds):
        got = _run(_sensor("gyro", rng_seed=seed, period=0.01, bias_walk=walk), np.zeros(3), n_steps)
        for k in checks:
            at[k].append(got[k - 1][2])
    for k in checks:
        t = k * DT
        var = np.var(np.array(at[k]))  # 3 components x seeds, mean 0
        assert abs(var / (walk**2 * t) - 1.0) < 0.1, (t, var)


def test_turn_on_bias_sigma_and_constant_without_walk():
    bias_sigma, seeds = 0.05, 3000
    first = []
    for seed in range(seeds):
        sensor = _sensor("dvl", rng_seed=seed, period=0.02, bias_sigma=bias_sigma)
        b0 = sensor.latest[1].copy()
        got = _run(sensor, np.zeros(3), 10)
        for _, _, v in got:  # no noise, no walk: every sample is the turn-on bias
            np.testing.assert_array_equal(v, b0)
        first.append(b0)
    np.testing.assert_allclose(np.std(np.array(first)), bias_sigma, rtol=0.05)


def test_sample_and_release_substeps_exact():
    sensor = _sensor("fix", period=0.03, latency=0.05)
    assert (sensor.period_steps, sensor.latency_steps) == (3, 5)
    got = _run(sensor, np.zeros(4), 100)
    sample_steps = [round(t / DT) for _, t, _ in got]
    assert sample_steps == list(range(3, 96, 3))  # every third substep after 0, released up to s = 100
    assert all(rel == s + 5 for (rel, _, _), s in zip(got, sample_steps, strict=True))
    assert sensor.latest[0] == pytest.approx(93 * DT)


def test_initial_sample_released_at_once_and_held():
    truth = np.array([1.0, 2.0, 3.0, 0.5])
    sensor = _sensor("fix", truth=truth, period=0.1, latency=0.05)
    t0, v0 = sensor.latest
    assert t0 == 0.0
    np.testing.assert_array_equal(v0, truth)
    assert sensor.release(4) == []  # the first later sample (s = 10) is released at s = 15
    assert sensor.latest[0] == 0.0
    sensor.sample(10, truth + 1.0)
    assert sensor.release(14) == []
    ((t, v),) = sensor.release(15)
    assert t == pytest.approx(0.1)
    np.testing.assert_array_equal(v, truth + 1.0)
    assert sensor.latest[0] == pytest.approx(0.1)


def test_encoders_sample_once_per_control_step():
    sensor = Sensor("encoders", LEVELS[1].encoders, physics_dt=DT, control_substeps=N_SUB)
    assert (sensor.period_steps, sensor.latency_steps) == (N_SUB, 0)
    assert [s for s in range(13) if sensor.due(s)] == [0, 4, 8, 12]


@pytest.mark.parametrize(
    ("period", "latency", "steps"),
    [(0.025, 0.015, (3, 2)), (0.024, 0.014, (2, 1)), (0.001, 0.004, (1, 0)), (0.2, 0.3, (20, 30))],
)
def test_rounding_rule(period, latency, steps):
    # nearest whole substep, halves up; a period is at least one substep, a latency may be zero
    sensor = Sensor("dvl", SensorSpec(period=period, latency=latency), physics_dt=DT, control_substeps=N_SUB)
    assert (sensor.period_steps, sensor.latency_steps) == steps
    assert sensor.period_steps == to_substeps(period, DT, minimum=1)


def _lost_runs(n_samples: int, p: float, n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    sensor = _sensor("dvl", rng_seed=seed, period=0.01, dropout_prob=p, dropout_len=n)
    got = _run(sensor, np.zeros(3), n_samples)
    delivered = np.zeros(n_samples + 1, bool)
    delivered[0] = True
    delivered[[round(t / DT) for _, t, _ in got]] = True
    edges = np.flatnonzero(np.diff(np.r_[1, delivered.astype(int), 1]))  # run starts/ends of lost samples
    runs = edges[1::2] - edges[::2]
    return delivered, runs[:-1] if not delivered[-1] else runs  # a run cut by the end is not whole


@pytest.mark.parametrize(("p", "n"), [(0.1, 10), (0.05, 5), (0.01, 1)])
def test_dropouts(p, n):
    delivered, runs = _lost_runs(100_000, p, n, seed=3)
    # a dropout loses exactly n due samples and can be followed at once by another: lost runs are multiples of n
    assert runs.size > 0 and np.all(runs % n == 0)
    expected = p * n / (1 + p * (n - 1))  # renewal: a dropout (n lost) with p, one delivered sample with 1 - p
    lost = 1.0 - delivered[1:-n].mean()
    assert abs(lost - expected) < 0.03 * expected + 0.002


def test_dropped_samples_still_advance_the_bias_walk_and_draws():
    # the draws do not depend on dropouts: the delivered samples equal those of the same seed without dropouts
    with_drop = _run(
        _sensor("gyro", rng_seed=5, period=0.01, sigma=0.1, bias_walk=0.2, dropout_prob=0.3, dropout_len=2),
        np.zeros(3),
        500,
    )
    no_drop = {
        round(t / DT): v
        for _, t, v in _run(
            _sensor("gyro", rng_seed=5, period=0.01, sigma=0.1, bias_walk=0.2, dropout_prob=1e-300, dropout_len=2),
            np.zeros(3),
            500,
        )
    }
    assert 100 < len(with_drop) < 450
    for _, t, v in with_drop:
        np.testing.assert_array_equal(v, no_drop[round(t / DT)])


def test_angle_wrapping():
    assert wrap_pi(np.array([math.pi]))[0] == math.pi
    assert wrap_pi(np.array([-math.pi]))[0] == math.pi
    np.testing.assert_allclose(wrap_pi(np.array([3 * math.pi / 2, -3.5])), [-math.pi / 2, 2 * math.pi - 3.5])
    truth = np.array([math.pi - 1e-3, -math.pi + 1e-3, 0.3])
    a = _run(_sensor("ahrs", rng_seed=1, truth=truth, period=0.01, sigma=0.05), truth, 2000)
    shifted = truth + np.array([-2 * math.pi, 2 * math.pi, 4 * math.pi])
    b = _run(_sensor("ahrs", rng_seed=1, truth=shifted, period=0.01, sigma=0.05), shifted, 2000)
    va, vb = np.array([v for *_, v in a]), np.array([v for *_, v in b])
    assert np.all((va > -math.pi) & (va <= math.pi))
    np.testing.assert_allclose(va, vb, atol=1e-12)
    assert (va[:, 0] < 0).any() and (va[:, 0] > 3).any()  # noise carried roll across pi, and it was wrapped
    fix_truth = np.array([10.0, -10.0, 7.0, math.pi - 1e-3])  # only the heading is an angle
    f = np.array([v for *_, v in _run(_sensor("fix", truth=fix_truth, period=0.01, sigma=0.01), fix_truth, 500)])
    assert np.all(np.abs(f[:, :3] - fix_truth[:3]) < 0.06) and (f[:, 3] < 0).any()


def _bank_samples(cfg, seed: int, episode: int, n_steps: int = 200) -> dict[str, list]:
    bank = SensorBank(cfg, physics_dt=DT, control_substeps=N_SUB)
    initial = _initial()
    bank.reset(seed, episode, initial)
    out = {n: list(v) for n, v in bank.initial().items()}
    for s in range(1, n_steps + 1):
        bank.sample(s, {n: initial[n] + 0.01 * s for n in bank.due(s)})
        if s % N_SUB == 0:
            for n, got in bank.release(s).items():
                out[n].extend(got)
    return out


def _same(a: list, b: list) -> bool:
    return len(a) == len(b) and all(ta == tb and np.array_equal(va, vb) for (ta, va), (tb, vb) in zip(a, b))


def test_same_seed_same_noise_new_episode_new_noise():
    cfg = LEVELS[3]
    a, b, c = _bank_samples(cfg, 7, 0), _bank_samples(cfg, 7, 0), _bank_samples(cfg, 7, 1)
    for name in SENSOR_NAMES:
        assert _same(a[name], b[name]), name
        assert not _same(a[name], c[name]), name


def test_streams_independent_across_sensors():
    cfg = LEVELS[2]
    other = dataclasses.replace(cfg, dvl=dataclasses.replace(cfg.dvl, sigma=0.3, dropout_prob=0.5))
    a, b = _bank_samples(cfg, 11, 0), _bank_samples(other, 11, 0)
    assert not _same(a["dvl"], b["dvl"])
    for name in SENSOR_NAMES:
        if name != "dvl":
            assert _same(a[name], b[name]), name


def test_bank_schedule_matches_each_sensor():
    bank = SensorBank(LEVELS[3], physics_dt=DT, control_substeps=N_SUB)
    for s in range(0, 500):
        assert bank.due(s) == tuple(n for n, sensor in bank.sensors.items() if s % sensor.period_steps == 0)
    periods = {n: sensor.period_steps for n, sensor in bank.sensors.items()}
    assert periods == {"ahrs": 1, "gyro": 1, "dvl": 20, "depth": 10, "fix": 100, "encoders": 4, "sonar": 40}


def test_sonar_rows_and_per_component_sigma():
    sigma = (0.1, 0.2, 0.3, 0.4, 0.5, 0.6)
    truth = np.arange(18.0).reshape(3, 6)
    got = _run(_sensor("sonar", truth=truth, period=0.01, sigma=sigma), truth, 4000)
    err = np.array([v for *_, v in got]) - truth
    assert err.shape == (4000, 3, 6)
    np.testing.assert_allclose(err.std(axis=(0, 1)), sigma, rtol=0.05)


def test_errors_name_the_bad_input():
    with pytest.raises(ValueError, match="sensor name"):
        Sensor("compass", SensorSpec(period=0.1), physics_dt=DT, control_substeps=N_SUB)
    sensor = Sensor("dvl", SensorSpec(period=0.02), physics_dt=DT, control_substeps=N_SUB)
    with pytest.raises(ValueError, match="reset"):
        sensor.sample(2, np.zeros(3))
    with pytest.raises(ValueError, match="initial dvl"):
        sensor.reset(np.random.default_rng(0), np.zeros(4))
    sensor.reset(np.random.default_rng(0), np.zeros(3))
    with pytest.raises(ValueError, match="substep 3 is not a sample"):
        sensor.sample(3, np.zeros(3))
    with pytest.raises(ValueError, match="dvl value must have shape"):
        sensor.sample(2, np.zeros(2))
    bank = SensorBank(LEVELS[1], physics_dt=DT, control_substeps=N_SUB)
    with pytest.raises(ValueError, match="missing"):
        bank.reset(0, 0, {"ahrs": np.zeros(3)})
    bank.reset(0, 0, _initial())
    with pytest.raises(ValueError, match="unknown sensor 'compass'"):
        bank.sample(1, {"compass": np.zeros(3)})


@pytest.mark.parametrize(
    ("name", "spec"),
    [
        ("gyro", {"period": 0.01, "sigma": 0.1, "bias_sigma": 0.2, "bias_walk": 0.3}),
        ("ahrs", {"period": 0.01, "sigma": 0.5}),  # wraps often
        ("dvl", {"period": 0.02, "latency": 0.03, "sigma": 0.1, "dropout_prob": 0.3, "dropout_len": 3}),
        ("sonar", {"period": 0.01, "sigma": (0.1, 0.2, 0.3, 0.4, 0.5, 0.6), "bias_walk": 0.1}),
    ],
)
def test_batches_equal_samples_one_at_a_time(name, spec):
    """sample_many over any batching gives the samples of sample() at each substep, bit for bit (draw blocks too)."""
    shape = (2, 6) if name == "sonar" else (SENSOR_DIMS[name],)
    truth = lambda s: np.full(shape, 3.0) + 0.01 * s  # noqa: E731  (angles beyond pi for the AHRS)
    one = Sensor(name, SensorSpec(**spec), physics_dt=DT, control_substeps=N_SUB)
    many = Sensor(name, SensorSpec(**spec), physics_dt=DT, control_substeps=N_SUB)
    one.reset(np.random.default_rng(9), truth(0))
    many.reset(np.random.default_rng(9), truth(0))
    due = [s for s in range(1, 1500) if s % one.period_steps == 0]  # several draw blocks
    got_one, got_many, k = [], [], 0
    rng = np.random.default_rng(0)
    while k < len(due):
        batch = due[k : k + int(rng.integers(1, 6))]
        for s in batch:
            one.sample(s, truth(s))
        many.sample_many(batch, np.array([truth(s) for s in batch]))
        k += len(batch)
        got_one += one.release(batch[-1])
        got_many += many.release(batch[-1])
    assert len(got_one) > 100
    assert _same(got_one, got_many)


def test_sample_many_checks_its_input():
    sensor = _sensor("dvl", period=0.02)
    with pytest.raises(ValueError, match="substep 3 is not a sample"):
        sensor.sample_many([2, 3], np.zeros((2, 3)))
    with pytest.raises(ValueError, match="dvl value must have shape"):
        sensor.sample_many([2, 4], np.zeros((3, 3)))


# Recorded with the per-sample implementation this batched one replaced (commit 097482c): per sensor the number of
# samples released over 800 substeps, the first sample's time and first three values, the last's time and last three.
RECORDED_STREAM = {
    "ahrs": (800, 0.01, [3.1088445055286966, -3.0803746856479335, 0.5215536944706866], 8.0,
             [-2.37843912468328, -2.3204340102579515, 1.3354687796885325]),
    "gyro": (800, 0.01, [0.12486974021938914, 0.3169498326194502, 0.47812056106074086], 8.0,
             [0.9150710434541074, 1.117743967350022, 1.2699237735317563]),
    "dvl": (39, 0.2, [-0.029752836822658297, 0.319066478895249, 0.3477097693425817], 7.8,
            [0.8591189430579564, 1.13052366277914, 1.2927497887127006]),
    "depth": (80, 0.1, [0.16769267091790735], 8.0, [0.9365035533146527]),
    "fix": (2, 1.0, [0.16277515402082873, 0.34671856289256653, 0.5518040004388655], 2.0,
            [0.35549764397717115, 0.5889813070138263, 0.7095985423177836]),
    "encoders": (200, 0.04, [0.1050043945622239, 0.14174252512349525, 0.1776164201890108], 8.0,
                 [1.2263122780801288, 1.2626112509849017, 1.300107616564806]),
    "sonar": (19, 0.4, [-0.0071537415484453845, 1.078965974770411, 1.9821321578030202], 7.6000000000000005,
              [9.727293634733488, 10.796856591372123, 11.80661530729704]),
}  # fmt: skip


def test_noise_stream_is_unchanged():
    """The level-3 samples of a seed, bit for bit as the per-sample draws gave them (committed episodes replay)."""
    bank = SensorBank(LEVELS[3], physics_dt=DT, control_substeps=N_SUB)
    values = _initial()
    values["ahrs"] = np.array([3.1, -3.1, 0.5])  # wraps
    bank.reset(7, 0, values)
    out: dict[str, list] = {n: [] for n in bank.sensors}
    for s in range(1, 801):
        bank.sample(s, {n: values[n] + 0.001 * s for n in bank.due(s)})
        if s % N_SUB == 0:
            for n, got in bank.release(s).items():
                out[n] += got
    for name, (count, t_first, first, t_last, last) in RECORDED_STREAM.items():
        got = out[name]
        assert len(got) == count, name
        assert (got[0][0], np.ravel(got[0][1])[:3].tolist()) == (t_first, first), name
        assert (got[-1][0], np.ravel(got[-1][1])[-3:].tolist()) == (t_last, last), name
