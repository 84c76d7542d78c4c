"""Reference motions: loading clips onto the character, mirroring, body groups, and sampling.

All quaternions are wxyz (MuJoCo), the world frame is z-up. See ``loaders.load_clip`` for the
file formats, ``motionlib`` for the jit-friendly sampler used by the environments.
"""

from jaxmotion.motion.clip import Clip, build_clip, make_test_clip, mean_root_speed
from jaxmotion.motion.groups import BodyGroup, default_groups, group_indices, resolve_group
from jaxmotion.motion.loaders import MotionFileError, find_motion_files, load_clip, load_clips
from jaxmotion.motion.mirror import mirror_clip
from jaxmotion.motion.motionlib import (
    MotionLib,
    MotionState,
    load_motionlib,
    qpos_qvel,
    sample,
    sample_times,
    sample_windows,
)

__all__ = [
    "BodyGroup",
    "Clip",
    "MotionFileError",
    "MotionLib",
    "MotionState",
    "build_clip",
    "default_groups",
    "find_motion_files",
    "group_indices",
    "load_clip",
    "load_clips",
    "load_motionlib",
    "make_test_clip",
    "mean_root_speed",
    "mirror_clip",
    "qpos_qvel",
    "resolve_group",
    "sample",
    "sample_times",
    "sample_windows",
]
