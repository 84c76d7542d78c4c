"""Tests of jaxmotion.metrics: DTW against a plain double loop, and the imitation error."""

from __future__ import annotations

import time

import numpy as np
import pytest

from jaxmotion.evaluation import metrics


def _reference_dtw(cost):
    """Textbook O(T1*T2) double loop with an explicit backtrack table."""
    t1, t2 = cost.shape
    acc = np.full((t1 + 1, t2 + 1), np.inf)
    acc[0, 0] = 0.0
    for i in range(1, t1 + 1):
        for j in range(1, t2 + 1):
            acc[i, j] = cost[i - 1, j - 1] + min(acc[i - 1, j], acc[i, j - 1], acc[i - 1, j - 1])
    return acc[1:, 1:]


def _assert_valid_path(path_i, path_j, t1, t2):
    assert len(path_i) == len(path_j)
    assert (path_i[0], path_j[0]) == (0, 0)
    assert (path_i[-1], path_j[-1]) == (t1 - 1, t2 - 1)
    steps = np.stack([np.diff(path_i), np.diff(path_j)], axis=1)
    allowed = {(1, 0), (0, 1), (1, 1)}
    assert all(tuple(s) in allowed for s in steps)


@pytest.mark.parametrize("shape", [(1, 1), (1, 5), (6, 1), (5, 5), (7, 12), (13, 4), (20, 20)])
def test_dtw_matches_double_loop(shape):
    rng = np.random.default_rng(sum(shape))
    for _ in range(5):
        cost = rng.random(shape)
        ref = _reference_dtw(cost)
        np.testing.assert_allclose(metrics.dtw_cost_matrix(cost), ref, rtol=1e-12, atol=1e-12)
        path_i, path_j = metrics.dtw_path(cost)
        _assert_valid_path(path_i, path_j, *shape)
        np.testing.assert_allclose(cost[path_i, path_j].sum(), ref[-1, -1], rtol=1e-12)


def test_dtw_hand_computed_3x3():
    cost = np.array([[1.0, 2.0, 3.0], [4.0, 1.0, 5.0], [6.0, 7.0, 1.0]])
    # Accumulated: row 0 = 1, 3, 6; row 1 = 5, 2, 7; row 2 = 11, 9, 3.
    expected = np.array([[1.0, 3.0, 6.0], [5.0, 2.0, 7.0], [11.0, 9.0, 3.0]])
    np.testing.assert_allclose(metrics.dtw_cost_matrix(cost), expected)
    path_i, path_j = metrics.dtw_path(cost)
    np.testing.assert_array_equal(path_i, [0, 1, 2])
    np.testing.assert_array_equal(path_j, [0, 1, 2])


def test_dtw_hand_computed_off_diagonal():
    # The cheap cells force a horizontal step first: (0,0) -> (0,1) -> (1,2) -> (2,2).
    cost = np.array([[0.0, 0.0, 9.0], [9.0, 9.0, 0.0], [9.0, 9.0, 0.0]])
    path_i, path_j = metrics.dtw_path(cost)
    np.testing.assert_array_equal(path_i, [0, 0, 1, 2])
    np.testing.assert_array_equal(path_j, [0, 1, 2, 2])
    assert metrics.dtw_cost_matrix(cost)[-1, -1] == 0.0


def test_dtw_1000x1000_is_fast():
    cost = np.random.default_rng(0).random((1000, 1000))
    start = time.perf_counter()
    path_i, path_j = metrics.dtw_path(cost)
    elapsed = time.perf_counter() - start
    _assert_valid_path(path_i, path_j, 1000, 1000)
    assert elapsed < 1.0, f"DTW on 1000x1000 took {elapsed:.2f} s"


def _trajectory(num_frames, num_links=5, seed=0):
    """Smooth, non-repeating link trajectories [T, L, 3] sampled on t in [0, 1]."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, 1.0, num_frames)[:, None, None]
    freq = rng.uniform(0.5, 1.5, size=(1, num_links, 3))
    phase = rng.uniform(0.0, 2 * np.pi, size=(1, num_links, 3))
    offset = rng.normal(size=(1, num_links, 3))
    return offset + 0.5 * np.sin(2 * np.pi * freq * t + phase) + 0.3 * t


def test_identical_sequences_have_zero_error():
    pos = _trajectory(60)
    mean, per_frame = metrics.dtw_imitation_error(pos, pos)
    assert mean == 0.0
    assert per_frame.shape == (60,)
    np.testing.assert_array_equal(per_frame, 0.0)


def test_time_stretch_is_absorbed_by_dtw():
    sim = _trajectory(200)
    ref = _trajectory(399)  # the same motion at twice the frame rate (every other frame shared)
    dtw_mean, _ = metrics.dtw_imitation_error(sim, ref)
    # Plain frame-by-frame error against the reference's first 200 frames (its first half).
    plain_mean, _ = metrics.frame_error(sim, ref[:200])
    assert dtw_mean < 0.01
    assert plain_mean > 0.1
    assert plain_mean > 20 * dtw_mean


def test_constant_offset_gives_offset():
    ref = _trajectory(40)
    sim = ref + np.array([0.1, 0.0, 0.0])
    mean, per_frame = metrics.dtw_imitation_error(sim, ref)
    assert mean == pytest.approx(0.1, abs=1e-9)
    np.testing.assert_allclose(per_frame, 0.1, atol=1e-9)


def test_offset_along_other_axes_is_euclidean():
    ref = np.zeros((3, 2, 3))
    sim = np.broadcast_to(np.array([0.03, 0.04, 0.0]), (3, 2, 3))
    mean, _ = metrics.dtw_imitation_error(sim, ref)
    assert mean == pytest.approx(0.05)


def test_link_distance_cost_hand_computed():
    sim = np.array([[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]]])  # [1, 2, 3]
    ref = np.array([[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]], [[0.0, 3.0, 4.0], [1.0, 0.0, 1.0]]])  # [2, 2, 3]
    np.testing.assert_allclose(metrics.link_distance_cost(sim, ref), [[0.0, 3.0]])


def test_shape_errors():
    with pytest.raises(ValueError, match="links"):
        metrics.dtw_imitation_error(np.zeros((4, 2, 3)), np.zeros((4, 3, 3)))
    with pytest.raises(ValueError, match=r"\[T, L, 3\]"):
        metrics.dtw_imitation_error(np.zeros((4, 2)), np.zeros((4, 2, 3)))
    with pytest.raises(ValueError, match="NaN"):
        metrics.dtw_path(np.array([[0.0, np.nan]]))


def test_mean_std():
    mean, std = metrics.mean_std([0.1, 0.2, 0.3])
    assert mean == pytest.approx(0.2)
    assert std == pytest.approx(np.std([0.1, 0.2, 0.3]))
    assert metrics.mean_std(np.array([2.0])) == (2.0, 0.0)
    with pytest.raises(ValueError):
        metrics.mean_std([])


def test_height_stats_pool_episodes_and_show_a_held_pose():
    """By hand: a held 0.4 m against a reference cycling 0.2 <-> 0.8 m."""
    ref = np.array([0.2, 0.5, 0.8, 0.5])
    h = metrics.height_stats([np.full(3, 0.4), np.array([0.4])], ref)
    assert h["sim_mean"] == pytest.approx(0.4) and h["sim_std"] == pytest.approx(0.0, abs=1e-12)
    assert (h["sim_min"], h["sim_max"]) == (pytest.approx(0.4), pytest.approx(0.4))
    assert h["ref_mean"] == pytest.approx(0.5) and h["ref_std"] == pytest.approx(np.sqrt(0.045))
    assert (h["ref_min"], h["ref_max"]) == (pytest.approx(0.2), pytest.approx(0.8))
    with pytest.raises(ValueError):
        metrics.height_stats([np.zeros(0)], ref)


def test_coverage_fails_a_held_pose_that_dtw_passes():
    """By hand, one link moving along z: the reference cycles 0.2 -> 0.8 m, one policy holds
    the bottom, another plays the whole cycle. DTW scores the hold better than its coverage."""
    ref = np.array([0.2, 0.35, 0.5, 0.65, 0.8])[:, None, None] * np.array([0.0, 0.0, 1.0])
    held = np.full((10, 1, 3), [0.0, 0.0, 0.2])
    cov = metrics.coverage(held, ref, radius=0.1)
    # Nearest simulated frame of each reference frame: 0, 0.15, 0.3, 0.45, 0.6 m away.
    assert cov["error_m"] == pytest.approx(0.3)
    assert cov["within"] == pytest.approx(0.2) and cov["radius_m"] == 0.1
    assert metrics.dtw_imitation_error(held, ref)[0] < cov["error_m"]
    full = metrics.coverage(np.concatenate([ref, ref[::-1]]), ref)
    assert full["error_m"] == pytest.approx(0.0, abs=1e-12) and full["within"] == 1.0
