"""The scoring maths on trajectories built in memory: alignments, errors, RPE, recall, turns."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import numpy.typing as npt
import pytest
from evo.core import metrics as evo_metrics
from evo.core.trajectory import PosePath3D

from air_sitl.eval import align
from air_sitl.eval.errors import EvalError
from air_sitl.eval.metrics import longest_run, rpe_errors, rpe_pairs
from air_sitl.eval.report import score
from air_sitl.eval.trajectory import NO_FRAME, NO_TIME, Estimate, Truth, match
from air_sitl.eval.turns import turn_mask

F64 = npt.NDArray[np.float64]
PERIOD_NS = 20_000_000


def make_truth(pos: F64, yaw: F64 | None = None, t0_ns: int = 5_000_000_000) -> Truth:
    n = pos.shape[0]
    if yaw is None:
        d = np.gradient(pos[:, :2], axis=0)
        yaw = np.arctan2(d[:, 1], d[:, 0])
    return Truth(
        where="mem",
        t_ns=t0_ns + np.arange(n, dtype=np.int64) * PERIOD_NS,
        pos_enu_m=pos,
        yaw_enu_rad=yaw,
    )


def by_frame(pos: F64, frames: npt.NDArray[np.int64] | None = None, name: str = "e") -> Estimate:
    idx = np.arange(pos.shape[0], dtype=np.int64) if frames is None else frames
    return Estimate(
        name=name,
        where="mem.csv",
        line=np.arange(idx.shape[0], dtype=np.int64) + 2,
        frame=idx,
        t_ns=np.full(idx.shape[0], NO_TIME, dtype=np.int64),
        pos_enu_m=pos,
        latency_wall_ms=None,
    )


def wiggly(n: int = 600, seed: int = 0) -> F64:
    """A curved 3-D path (a flight-like S with height changes), 15 m/s at 50 Hz."""
    s = np.arange(n) * 0.3
    rng = np.random.default_rng(seed)
    x = s + 40.0 * np.sin(s / 60.0)
    y = 80.0 * np.sin(s / 45.0) + 0.1 * rng.standard_normal(n)
    z = 200.0 + 5.0 * np.sin(s / 25.0)
    return np.column_stack((x, y, z))


def rot(axis: str, angle_rad: float) -> F64:
    c, s = math.cos(angle_rad), math.sin(angle_rad)
    if axis == "z":
        return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])
    return np.array([[1.0, 0, 0], [0, c, -s], [0, s, c]])


def test_a_constant_10_m_offset_is_10_m_unaligned_and_zero_after_se3() -> None:
    truth = make_truth(wiggly())
    est = by_frame(truth.pos_enu_m + np.array([6.0, 8.0, 0.0]))
    plain = score(truth, est, "none").report
    for key in ("mean", "median", "rmse", "p95", "max"):
        assert plain["horizontal_error_m"][key] == pytest.approx(10.0, abs=1e-12)
    assert plain["final_error_m"] == pytest.approx(10.0, abs=1e-12)
    assert plain["recall"]["5m"] == 0.0 and plain["recall"]["25m"] == 1.0
    assert plain["rpe"]["100m"]["rmse"] == pytest.approx(0.0, abs=1e-9)  # offsets cancel
    aligned = score(truth, est, "se3").report
    assert aligned["error_3d_m"]["max"] == pytest.approx(0.0, abs=1e-6)


def test_a_rotated_and_scaled_copy_is_zero_with_sim3_and_not_with_se3() -> None:
    truth = make_truth(wiggly())
    r = rot("z", 0.7) @ rot("x", 0.2)
    copy = 0.5 * truth.pos_enu_m @ r.T + np.array([100.0, -40.0, 7.0])
    est = by_frame(copy)
    assert score(truth, est, "sim3").report["error_3d_m"]["max"] == pytest.approx(0.0, abs=1e-6)
    assert score(truth, est, "se3").report["error_3d_m"]["rmse"] > 10.0
    assert score(truth, est, "none").report["error_3d_m"]["rmse"] > 10.0


@pytest.mark.parametrize("yaw_deg", [-170.0, -45.0, 0.0, 30.0, 100.0, 179.0])
def test_posyaw_equals_evo_se3_on_yaw_only_cases(yaw_deg: float) -> None:
    truth = wiggly()
    r = rot("z", math.radians(yaw_deg))
    est = truth @ r.T + np.array([-30.0, 55.0, -12.0])
    ours = align.posyaw(est, truth)
    evo = align.umeyama(est, truth, with_scale=False)
    assert evo is not None
    np.testing.assert_allclose(ours.rotation, evo.rotation, atol=1e-9)
    np.testing.assert_allclose(ours.translation, evo.translation, atol=1e-6)
    np.testing.assert_allclose(ours.apply(est), truth, atol=1e-6)


def test_posyaw_keeps_roll_and_pitch_errors_that_se3_removes() -> None:
    truth = wiggly()
    est = truth @ rot("x", 0.05).T
    pos_yaw = align.posyaw(est, truth)
    assert np.abs(pos_yaw.apply(est) - truth).max() > 1.0
    assert pos_yaw.rotation[2, 2] == 1.0  # a rotation about the vertical only


@pytest.mark.parametrize("how", ["none", "se3", "sim3"])
def test_errors_match_evo_ape_to_a_micrometre(how: str) -> None:
    truth = make_truth(wiggly(900, seed=3))
    rng = np.random.default_rng(4)
    noisy = truth.pos_enu_m @ rot("z", 0.02).T * 1.01 + rng.normal(0.0, 3.0, (900, 3)) + 5.0
    report = score(truth, by_frame(noisy), how).report

    def path(p: F64) -> PosePath3D:
        poses = [np.eye(4) for _ in range(p.shape[0])]
        for pose, xyz in zip(poses, p, strict=True):
            pose[:3, 3] = xyz
        return PosePath3D(poses_se3=poses)

    ref, est = path(truth.pos_enu_m), path(noisy)
    if how != "none":
        est.align(ref, correct_scale=how == "sim3")
    ape = evo_metrics.APE(evo_metrics.PoseRelation.translation_part)
    ape.process_data((ref, est))
    for ours, theirs in (("mean", "mean"), ("median", "median"), ("rmse", "rmse"), ("max", "max")):
        assert report["error_3d_m"][ours] == pytest.approx(ape.get_statistic(
            getattr(evo_metrics.StatisticsType, theirs)), abs=1e-6)  # fmt: skip


def test_rpe_on_a_hand_computed_case() -> None:
    # truth: 1 m per frame east; estimate: the same, but frame 5 is 2 m north
    pos = np.column_stack((np.arange(11.0), np.zeros(11), np.zeros(11)))
    est = pos.copy()
    est[5, 1] = 2.0
    path = np.arange(11.0)
    i, j = rpe_pairs(path, 3.0)
    assert i.tolist() == list(range(8)) and j.tolist() == list(range(3, 11))
    err = rpe_errors(est, pos, i, j)
    # pairs touching frame 5: (2, 5) and (5, 8): 2 m each, six others 0 m
    assert err.tolist() == [0.0, 0.0, 2.0, 0.0, 0.0, 2.0, 0.0, 0.0]
    # the report uses 100 m: scale the same case up
    truth = make_truth(pos * 50.0)
    report = score(truth, by_frame(est * 50.0), "none").report
    # pairs i -> i+2 (100 m); those touching frame 5: (3, 5) and (5, 7), 100 m each, of 9
    assert report["rpe"]["100m"]["mean"] == pytest.approx(200.0 / 9)
    assert report["rpe"]["100m"]["rmse"] == pytest.approx(math.sqrt(2 * 100.0**2 / 9))
    assert report["rpe"]["500m"] == {"mean": 0.0, "rmse": 0.0}  # only (0, 10): both exact


def test_dropped_rows_lower_availability_and_count_as_recall_misses() -> None:
    truth = make_truth(wiggly(500))
    keep = np.flatnonzero(np.arange(500) % 4 != 0)  # 375 of 500
    est = by_frame(truth.pos_enu_m[keep] + np.array([3.0, 0.0, 0.0]), keep)
    report = score(truth, est, "none").report
    assert report["frames"] == 500
    assert report["estimated_frames"] == 375
    assert report["availability"] == 0.75
    assert report["recall"] == {"5m": 0.75, "10m": 0.75, "25m": 0.75, "50m": 0.75}
    assert report["longest_outage_s"] == pytest.approx(0.02)
    assert report["time_to_first_fix_s"] == pytest.approx(0.02)  # frame 0 was dropped


def test_all_nan_rows_are_no_estimate_and_an_empty_estimate_is_all_null() -> None:
    truth = make_truth(wiggly(200))
    pos = truth.pos_enu_m.copy()
    pos[50:150] = np.nan
    report = score(truth, by_frame(pos), "none").report
    assert report["estimated_frames"] == 100
    assert report["longest_outage_s"] == pytest.approx(100 * 0.02)
    nothing = score(truth, by_frame(np.full((200, 3), np.nan)), "se3").report
    assert nothing["availability"] == 0.0
    assert nothing["horizontal_error_m"]["rmse"] is None
    assert nothing["final_error_m"] is None and nothing["drift_pct"] is None
    assert nothing["time_to_first_fix_s"] is None
    assert nothing["latency_ms"] == {"median": None, "p95": None}
    assert nothing["longest_outage_s"] == pytest.approx(4.0)


def test_time_keyed_estimates_get_interpolated_truth_never_the_nearest_sample() -> None:
    truth = make_truth(wiggly(300))
    # estimates a quarter frame after each frame, exactly on the straight segment between frames
    t = truth.t_ns[:-1] + PERIOD_NS // 4
    p = truth.pos_enu_m[:-1] + 0.25 * np.diff(truth.pos_enu_m, axis=0)
    est = Estimate(
        name="t", where="mem.tum", line=np.arange(299, dtype=np.int64) + 1,
        frame=np.full(299, NO_FRAME, dtype=np.int64), t_ns=t.astype(np.int64), pos_enu_m=p,
        latency_wall_ms=None,
    )  # fmt: skip
    report = score(truth, est, "none").report
    assert report["error_3d_m"]["max"] == pytest.approx(0.0, abs=1e-9)
    assert report["estimated_frames"] == 299


def test_a_frame_estimated_twice_is_refused_with_both_lines() -> None:
    truth = make_truth(wiggly(50))
    frames = np.array([0, 1, 2, 2, 3], dtype=np.int64)
    with pytest.raises(EvalError, match=r"mem.csv: line 5: frame 2 already estimated at line 4"):
        match(truth, by_frame(truth.pos_enu_m[frames], frames))


@pytest.mark.parametrize(("rate_deg_s", "turning"), [(5.0, True), (-5.0, True), (1.0, False)])
def test_turn_mask_from_the_yaw_rate(rate_deg_s: float, turning: bool) -> None:
    t = np.arange(500, dtype=np.int64) * PERIOD_NS
    yaw = np.angle(np.exp(1j * np.radians(rate_deg_s) * t / 1e9))  # wrapped to (-pi, pi]
    mask = turn_mask(t, yaw)
    assert mask.all() == turning and mask.any() == turning


def test_turn_mask_smooths_over_one_second() -> None:
    # a 0.2 s yaw step of 1 degree (5 deg/s) is a blip, not a turn, once averaged over 1 s
    t = np.arange(500, dtype=np.int64) * PERIOD_NS
    yaw = np.zeros(500)
    yaw[250:] = np.radians(1.0)
    assert not turn_mask(t, yaw).any()


def test_longest_run() -> None:
    assert longest_run(np.array([False, True, True, False, True])) == 2
    assert longest_run(np.zeros(3, dtype=bool)) == 0
    assert longest_run(np.ones(3, dtype=bool)) == 3


def with_fix(est: Estimate, fix: list[float]) -> Estimate:
    return dataclasses.replace(est, fix=np.array(fix, dtype=np.float64))


def test_fix_rate_counts_accepted_fixes_over_all_frames_beside_availability() -> None:
    """Propagated frames (fix 0) keep availability at 1; the fix rate and the longest time
    without a fix say what the map gave. Frames without a row count as without a fix."""
    truth = make_truth(wiggly(10))
    est = with_fix(by_frame(truth.pos_enu_m), [1, 0, 0, 1, 1, 0, 0, 0, 1, 0])
    report = score(truth, est, "none").report
    assert report["availability"] == 1.0
    assert report["fix_rate"] == pytest.approx(0.4)
    assert report["longest_without_fix_s"] == pytest.approx(3 * 0.02)
    keep = np.array([0, 1, 2, 3], dtype=np.int64)  # frames 4..9 unanswered
    part = with_fix(by_frame(truth.pos_enu_m[keep], keep), [1, 1, 0, 1])
    report = score(truth, part, "none").report
    assert report["fix_rate"] == pytest.approx(0.3)
    assert report["longest_without_fix_s"] == pytest.approx(6 * 0.02)


def test_all_refused_is_fix_rate_0_and_unsaid_is_null() -> None:
    truth = make_truth(wiggly(50))
    refused = score(truth, with_fix(by_frame(truth.pos_enu_m), [0.0] * 50), "none").report
    assert refused["availability"] == 1.0
    assert refused["fix_rate"] == 0.0
    assert refused["longest_without_fix_s"] == pytest.approx(50 * 0.02)
    for est in (by_frame(truth.pos_enu_m), with_fix(by_frame(truth.pos_enu_m), [math.nan] * 50)):
        report = score(truth, est, "none").report
        assert report["fix_rate"] is None and report["longest_without_fix_s"] is None
    # a time-keyed row's fix belongs to the frame its time maps to
    t = truth.t_ns[:10] + PERIOD_NS // 4
    by_time = Estimate(
        name="t", where="mem.csv", line=np.arange(10, dtype=np.int64) + 2,
        frame=np.full(10, NO_FRAME, dtype=np.int64), t_ns=t.astype(np.int64),
        pos_enu_m=truth.pos_enu_m[:10], latency_wall_ms=None,
        fix=np.array([0, 0, 1, 0, 0, 0, 0, 0, 0, 1], dtype=np.float64),
    )  # fmt: skip
    m = match(truth, by_time)
    assert m.fix_frames is not None and m.fix_frames.tolist() == [2, 9]


def test_an_alignment_that_cannot_be_computed_gives_null_figures_not_zeros() -> None:
    truth = make_truth(wiggly(100))
    two = np.array([10, 60], dtype=np.int64)
    report = score(truth, by_frame(truth.pos_enu_m[two], two), "se3").report
    assert report["estimated_frames"] == 2 and report["availability"] == 0.02
    assert report["horizontal_error_m"]["rmse"] is None
    assert report["recall"] == {"5m": None, "10m": None, "25m": None, "50m": None}
    assert report["final_error_m"] is None
    # with nothing estimated every frame is a miss, whatever the alignment
    none = score(truth, by_frame(np.full((100, 3), np.nan)), "sim3").report
    assert none["recall"] == {"5m": 0.0, "10m": 0.0, "25m": 0.0, "50m": 0.0}
