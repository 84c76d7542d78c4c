"""Evaluation metrics on host arrays (numpy): DTW imitation error and summaries.

The imitation error follows Xu et al. 2023 (Composite Motion Learning with Task Control), Eq. 11:
per frame, the mean over a body group's links of the distance between simulated and reference
link positions, after aligning the two sequences in time with dynamic time warping, so that a
policy that follows the motion a little faster or slower is not penalised for the timing.
Positions are taken as given (world frame, metres); subtract a root trajectory first for a
root-relative error.
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np


def dtw_cost_matrix(cost: np.ndarray) -> np.ndarray:
    """Accumulated DTW cost for steps (1, 0), (0, 1) and (1, 1).

    ``D[i, j] = cost[i, j] + min(D[i-1, j], D[i, j-1], D[i-1, j-1])``, with ``D[0, 0] = cost[0, 0]``.
    Each row is computed at once: with ``m[j] = min(D[i-1, j], D[i-1, j-1])`` and ``S`` the running
    sum of the row's costs, ``D[i, j] = S[j] + min_{k <= j} (m[k] - S[k-1])``, a cumulative minimum.

    Args:
        cost: [T1, T2] non-negative, finite local costs.

    Returns:
        [T1, T2] accumulated costs; ``D[-1, -1]`` is the cost of the optimal alignment.
    """
    cost = _check_cost(cost)
    t1, t2 = cost.shape
    acc = np.empty((t1, t2), dtype=np.float64)
    acc[0] = np.cumsum(cost[0])
    for i in range(1, t1):
        prev = acc[i - 1]
        reach = prev.copy()  # best way into (i, j) from row i-1
        np.minimum(reach[1:], prev[:-1], out=reach[1:])
        run = np.cumsum(cost[i])
        run_before = np.concatenate(([0.0], run[:-1]))
        acc[i] = run + np.minimum.accumulate(reach - run_before)
    return acc


def dtw_path(cost: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Optimal monotone alignment of two sequences under a local cost.

    Args:
        cost: [T1, T2] local costs between frame i of one sequence and frame j of the other.

    Returns:
        ``(path_i, path_j)``, int arrays of equal length K (max(T1, T2) <= K <= T1 + T2 - 1),
        from (0, 0) to (T1-1, T2-1); each step advances i, j or both by one.
    """
    acc = dtw_cost_matrix(cost)
    i, j = acc.shape[0] - 1, acc.shape[1] - 1
    path = [(i, j)]
    while i > 0 or j > 0:
        if i == 0:
            j -= 1
        elif j == 0:
            i -= 1
        else:
            # Ties prefer the diagonal, then the shorter path.
            moves = ((i - 1, j - 1), (i - 1, j), (i, j - 1))
            i, j = min(moves, key=lambda ij: acc[ij])
        path.append((i, j))
    path_ij = np.asarray(path[::-1], dtype=np.int64)
    return path_ij[:, 0], path_ij[:, 1]


def link_distance_cost(sim_pos: np.ndarray, ref_pos: np.ndarray) -> np.ndarray:
    """Pairwise per-frame cost: mean over links of the Euclidean link distance.

    Args:
        sim_pos: [T1, L, 3] simulated link positions.
        ref_pos: [T2, L, 3] reference link positions, same links in the same order.

    Returns:
        [T1, T2] with ``cost[i, j] = mean_l ||sim_pos[i, l] - ref_pos[j, l]||``.
    """
    sim_pos, ref_pos = _check_positions(sim_pos, ref_pos)
    cost = np.zeros((sim_pos.shape[0], ref_pos.shape[0]), dtype=np.float64)
    # One link at a time keeps memory at [T1, T2, 3] instead of [T1, T2, L, 3].
    for link in range(sim_pos.shape[1]):
        diff = sim_pos[:, None, link, :] - ref_pos[None, :, link, :]
        cost += np.sqrt(np.einsum("ijk,ijk->ij", diff, diff))
    return cost / sim_pos.shape[1]


def dtw_imitation_error(sim_pos: np.ndarray, ref_pos: np.ndarray) -> tuple[float, np.ndarray]:
    """Imitation error after DTW alignment (Xu et al. 2023, Eq. 11).

    Args:
        sim_pos: [T1, L, 3] simulated link positions (metres).
        ref_pos: [T2, L, 3] reference link positions (metres), same links in the same order.

    Returns:
        ``(mean, per_frame)``: per_frame is [K], the Eq. 11 error e_t of each aligned pair of
        frames along the optimal DTW path; mean is its average, in metres.
    """
    cost = link_distance_cost(sim_pos, ref_pos)
    path_i, path_j = dtw_path(cost)
    per_frame = cost[path_i, path_j]
    return float(per_frame.mean()), per_frame


def frame_error(sim_pos: np.ndarray, ref_pos: np.ndarray) -> tuple[float, np.ndarray]:
    """Frame-by-frame Eq. 11 error without time alignment (for comparison with DTW).

    Args:
        sim_pos: [T, L, 3] simulated link positions.
        ref_pos: [T, L, 3] reference link positions at the same frames.

    Returns:
        ``(mean, per_frame)`` with per_frame [T].
    """
    sim_pos, ref_pos = _check_positions(sim_pos, ref_pos)
    if sim_pos.shape[0] != ref_pos.shape[0]:
        raise ValueError(f"frame_error needs equal lengths, got {sim_pos.shape[0]} and {ref_pos.shape[0]}")
    per_frame = np.linalg.norm(sim_pos - ref_pos, axis=-1).mean(axis=-1)
    return float(per_frame.mean()), per_frame


def mean_std(xs: Iterable[float]) -> tuple[float, float]:
    """Mean and (population, ddof=0) standard deviation, as the papers' "a ± b".

    Args:
        xs: one or more numbers (e.g. the error of each evaluation episode).

    Returns:
        ``(mean, std)`` as Python floats.
    """
    arr = np.asarray(list(xs) if not isinstance(xs, np.ndarray) else xs, dtype=np.float64)
    if arr.size == 0:
        raise ValueError("mean_std of an empty sequence")
    return float(arr.mean()), float(arr.std())


def height_stats(sim_z: Iterable[np.ndarray], ref_z: np.ndarray) -> dict[str, float]:
    """Mean, std and range (m) of a link's height over the simulated episodes' frames (pooled)
    and over the reference's. DTW may pair many frames of a held pose with one part of a cyclic
    reference (a half-squat held against a squat scores low); the height's spread shows that.

    Args:
      sim_z: per episode, the link's heights [T_e] over the frames it played.
      ref_z: [T] the reference link's heights.
    """
    sim = np.concatenate([np.asarray(z, np.float64).reshape(-1) for z in sim_z])
    ref = np.asarray(ref_z, np.float64).reshape(-1)
    if sim.size == 0 or ref.size == 0:
        raise ValueError("height_stats needs at least one simulated and one reference frame")
    out = {}
    for name, z in (("sim", sim), ("ref", ref)):
        out.update(
            {
                f"{name}_mean": float(z.mean()),
                f"{name}_std": float(z.std()),
                f"{name}_min": float(z.min()),
                f"{name}_max": float(z.max()),
            }
        )
    return out


def coverage(sim_pos: np.ndarray, ref_pos: np.ndarray, radius: float = 0.1) -> dict[str, float]:
    """How much of the reference the simulation shows: for every reference frame, the Eq. 11
    distance to the nearest simulated frame (any episode, any time). DTW measures the other
    direction (every simulated frame near some reference frame), which a policy that repeats
    one part of the clip passes; this one it fails (the recall to DTW's precision).

    Args:
      sim_pos: [N, L, 3] simulated link positions, frames of all episodes pooled.
      ref_pos: [T, L, 3] reference link positions (e.g. one pass of the clip), same links.
      radius: the distance (m) within which a reference frame counts as shown.

    Returns:
      ``{"error_m": mean nearest distance, "within": share of reference frames within radius,
      "radius_m": radius}``.
    """
    nearest = link_distance_cost(sim_pos, ref_pos).min(axis=0)
    return {"error_m": float(nearest.mean()), "within": float(np.mean(nearest <= radius)), "radius_m": float(radius)}


def _check_cost(cost: np.ndarray) -> np.ndarray:
    cost = np.asarray(cost, dtype=np.float64)
    if cost.ndim != 2 or cost.shape[0] == 0 or cost.shape[1] == 0:
        raise ValueError(f"DTW cost must be a non-empty [T1, T2] matrix, got shape {cost.shape}")
    if not np.all(np.isfinite(cost)):
        raise ValueError("DTW cost contains NaN or inf")
    return cost


def _check_positions(sim_pos: np.ndarray, ref_pos: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    sim_pos = np.asarray(sim_pos, dtype=np.float64)
    ref_pos = np.asarray(ref_pos, dtype=np.float64)
    for name, arr in (("sim_pos", sim_pos), ("ref_pos", ref_pos)):
        if arr.ndim != 3 or arr.shape[-1] != 3 or arr.shape[0] == 0 or arr.shape[1] == 0:
            raise ValueError(f"{name} must be [T, L, 3] with T, L > 0, got shape {arr.shape}")
    if sim_pos.shape[1] != ref_pos.shape[1]:
        raise ValueError(f"sim_pos has {sim_pos.shape[1]} links and ref_pos {ref_pos.shape[1]}; they must match")
    return sim_pos, ref_pos
