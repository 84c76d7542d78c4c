"""Clips perturbed the way a video pose estimate is (the PHC paper's noisy-input tests; notes phc.md §7).

``perturb_clip(clip, level, rng)`` returns a new clip (velocities and link poses rebuilt from the
perturbed coordinates, as an estimate would give them) with, scaled by ``level`` (1 = the
``PoseNoise`` defaults): root jitter stronger along the camera's depth axis, per-joint rotation
noise, both low-pass filtered (estimates are smoothed); a constant vertical offset of random sign
(floating or penetrating); and dropped frames that repeat the previous one. ``level`` 0 returns the
clip unchanged; the same ``rng`` seed gives the same perturbation.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from scipy.ndimage import gaussian_filter1d

from jaxmotion.motion.clip import Clip, build_clip


@dataclasses.dataclass(frozen=True)
class PoseNoise:
    """The perturbation at level 1."""

    root_lateral_m: float = 0.02
    """Std of the root jitter across the camera's view (m)."""
    root_depth_m: float = 0.08
    """Std along the camera's depth axis, where monocular estimates are worst (m)."""
    depth_axis: tuple[float, float, float] = (1.0, 0.0, 0.0)
    """The camera's viewing direction in the world (horizontal)."""
    joint_deg: float = 7.5
    """Std of the noise on every hinge angle (degrees)."""
    vertical_m: float = 0.075
    """Magnitude of the constant height offset (random sign: floating or penetrating)."""
    drop_rate: float = 0.05
    """Share of frames replaced by the previous one (dropped or frozen estimates)."""
    smooth_s: float = 0.067
    """Std of the Gaussian low-pass filter applied to the noise (s; 2 frames at 30 Hz)."""


def _smooth_noise(rng: np.random.Generator, shape: tuple[int, ...], sigma_frames: float) -> np.ndarray:
    """Unit-std Gaussian noise low-pass filtered along axis 0."""
    x = rng.normal(size=shape)
    if sigma_frames <= 0:
        return x
    y = gaussian_filter1d(x, sigma_frames, axis=0, mode="nearest")
    return y / max(float(y.std()), 1e-12)


def perturb_clip(clip: Clip, level: float, rng: np.random.Generator, noise: PoseNoise = PoseNoise()) -> Clip:
    """``clip`` as a noisy pose estimate would give it (see the module docstring)."""
    if level < 0:
        raise ValueError(f"noise level must be >= 0, got {level}")
    if level == 0:
        return clip
    T, sigma = clip.num_frames, noise.smooth_s * clip.fps
    depth = np.asarray(noise.depth_axis, np.float64)
    depth = depth / np.linalg.norm(depth)
    lateral = np.cross([0.0, 0.0, 1.0], depth)
    n = _smooth_noise(rng, (T, 2), sigma)
    root_pos = clip.root_pos + level * (
        noise.root_depth_m * n[:, :1] * depth + noise.root_lateral_m * n[:, 1:] * lateral
    )
    root_pos[:, 2] += level * noise.vertical_m * rng.choice([-1.0, 1.0])
    dof = clip.dof_pos + level * np.deg2rad(noise.joint_deg) * _smooth_noise(rng, clip.dof_pos.shape, sigma)
    root_quat = clip.root_quat.copy()
    dropped = rng.random(T) < min(level * noise.drop_rate, 1.0)
    dropped[0] = False
    for t in np.flatnonzero(dropped):  # in order, so runs of drops freeze on the last kept frame
        root_pos[t], root_quat[t], dof[t] = root_pos[t - 1], root_quat[t - 1], dof[t - 1]
    return build_clip(
        name=clip.name,
        path=clip.path,
        format=clip.format,
        fps=clip.fps,
        loop=clip.loop,
        sword_shield=clip.sword_shield,
        root_pos=root_pos,
        root_quat=root_quat,
        dof_pos=dof,
    )
