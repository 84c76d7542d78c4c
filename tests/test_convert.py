"""``motion/convert.py``: local body rotations to the character's hinge angles."""

import numpy as np

from jaxmotion.motion import rotations as rot
from jaxmotion.physics.character import character


def test_hinge_angles_without_range_fitting_match_the_fitted_ones_inside_the_ranges():
    """``local_quats_to_dof(fit_ranges=False)``: the plain decomposition (it used an undefined
    name for its branch choice). Inside the joint ranges both ways give the same angles."""
    from jaxmotion.motion.convert import local_quats_to_dof

    ch = character()
    rng = np.random.default_rng(0)
    lo, hi = ch.joint_range[:, 0], ch.joint_range[:, 1]
    dof = (lo + (hi - lo) * rng.uniform(0.4, 0.6, (5, ch.num_dof))).astype(np.float64)
    # Each body's rotation is the product of its hinges' rotations in joint order (MuJoCo's).
    local = np.tile(np.array([1.0, 0.0, 0.0, 0.0]), (5, ch.num_bodies, 1))
    for b in range(1, ch.num_bodies):
        for i in ch.body_joints(b):
            hinge = rot.quat_from_axis_angle(np.eye(3)[ch.joint_axis[i]], dof[:, i])
            local[:, b] = np.asarray(rot.quat_mul(local[:, b], hinge))
    plain = local_quats_to_dof(ch, local, fit_ranges=False)
    fitted = local_quats_to_dof(ch, local, fit_ranges=True)
    assert plain.shape == fitted.shape == (5, ch.num_dof)
    np.testing.assert_allclose(plain, fitted, atol=1e-5)
    np.testing.assert_allclose(fitted, dof, atol=1e-5)
