"""Levelling a reference that stands on uneven feet (``motion/level.py``)."""

import dataclasses

import numpy as np
import pytest

from jaxmotion.motion.clip import build_clip, make_test_clip
from jaxmotion.motion.level import level_feet, sole_points
from jaxmotion.physics.character import character


def _standing(num_frames=4, tilt_deg=0.0, lift=0.0):
    """The zero pose with its soles 1 cm above the floor (+ ``lift``), the root rolled by ``tilt_deg``
    about the forward (x) axis, so that one sole is higher than the other."""
    c = make_test_clip(num_frames, root_vel=(0.0, 0.0, 0.0))
    c = dataclasses.replace(c, root_pos=c.root_pos + [0, 0, 0.01 + lift - sole_points(c)[0, :, 2].min()])
    h = np.radians(tilt_deg) / 2
    q = np.broadcast_to([np.cos(h), np.sin(h), 0.0, 0.0], (num_frames, 4))
    return build_clip(
        name="stand",
        path="",
        format="generated",
        fps=c.fps,
        loop=False,
        sword_shield=False,
        root_pos=c.root_pos,
        root_quat=q,
        dof_pos=c.dof_pos,
    )


def test_a_rolled_standing_pose_is_rolled_back_onto_both_feet():
    c = _standing(tilt_deg=3.0)
    s = sole_points(c)
    assert abs(s[0, 0, 2] - s[0, 1, 2]) > 0.005  # the roll lifts one foot by centimetres
    lv = level_feet(c)
    s = sole_points(lv)
    np.testing.assert_allclose(s[:, :, 2], 0.0, atol=1e-6)  # both soles on the floor
    # The zero pose stands level, so levelling undoes the roll: the root is upright again.
    np.testing.assert_allclose(np.abs(lv.root_quat[:, 0]), 1.0, atol=1e-6)
    np.testing.assert_array_equal(lv.dof_pos, c.dof_pos)


def test_frames_with_a_lifted_foot_are_left_alone():
    c = _standing(tilt_deg=3.0, lift=0.2)  # both feet 20 cm up: a jump, not a stance
    lv = level_feet(c)
    np.testing.assert_array_equal(lv.root_pos, c.root_pos)
    np.testing.assert_allclose(lv.root_quat, c.root_quat)


def test_the_levelled_pose_is_clamped_to_the_joint_ranges_first():
    ch = character(False)
    c = _standing()
    over = np.broadcast_to(ch.joint_range[:, 1] + 0.3, c.dof_pos.shape)
    c = build_clip(
        name="over",
        path="",
        format="generated",
        fps=c.fps,
        loop=False,
        sword_shield=False,
        root_pos=c.root_pos,
        root_quat=c.root_quat,
        dof_pos=over,
    )
    lv = level_feet(c)
    np.testing.assert_allclose(lv.dof_pos, np.broadcast_to(ch.joint_range[:, 1], c.dof_pos.shape))


def test_the_shared_squat_stands_on_both_feet_after_levelling(data_dir):
    from jaxmotion.motion.loaders import load_clip

    c = load_clip(data_dir / "compositemotion/gym/squat.json", character(False))
    s = sole_points(c)
    assert np.abs(s[:, 0, 2] - s[:, 1, 2]).max() > 0.03  # the measured defect: uneven by centimetres
    lv = level_feet(c)
    s = sole_points(lv)
    assert np.abs(s[:, :, 2]).max() < 1e-4
    tilt = 2 * np.degrees(np.arccos(np.clip(np.abs(np.sum(lv.root_quat * c.root_quat, -1)), 0, 1)))
    assert tilt.max() < 8.0  # a few degrees of body tilt, not a new pose


def test_a_level_feet_name_that_no_clip_has_is_an_error():
    from jaxmotion.envs.humanoid import EnvConfig, GroupConfig, HumanoidEnv
    from jaxmotion.motion.motionlib import MotionLib

    lib = MotionLib.from_clips([make_test_clip(8)])
    cfg = EnvConfig(groups=(GroupConfig(name="full"),), level_feet=("sqaut",))
    with pytest.raises(ValueError, match="sqaut"):
        HumanoidEnv(cfg, motion_libs=[lib], init_lib=lib)
