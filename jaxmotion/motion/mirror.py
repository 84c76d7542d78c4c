"""Left/right mirroring of clips across the character's sagittal (x-z) plane."""

from __future__ import annotations

import numpy as np

from jaxmotion.motion.clip import Clip, build_clip
from jaxmotion.physics.character import Character


def _swap_side(name: str) -> str:
    if name.startswith("left_"):
        return "right_" + name[len("left_") :]
    if name.startswith("right_"):
        return "left_" + name[len("right_") :]
    return name


def mirror_dof_map(ch: Character) -> tuple[np.ndarray, np.ndarray]:
    """How hinge angles mirror: ``mirrored[:, i] = sign[i] * dof[:, src[i]]``.

    Left/right joints swap; hinges about x and z negate, about y keep (M Rx(a) M = Rx(-a),
    M Ry(b) M = Ry(b), M Rz(c) M = Rz(-c) for M = diag(1, -1, 1)).

    Args:
        ch: the character (must be left/right symmetric).

    Returns:
        (src [n_dof] int, sign [n_dof] float).
    """
    names = list(ch.joint_names)
    src = np.array([names.index(_swap_side(n)) for n in names])
    sign = np.array([1.0 if ax == 1 else -1.0 for ax in ch.joint_axis])
    return src, sign


def mirror_clip(clip: Clip) -> Clip:
    """Mirrors a clip left/right (y -> -y) and recomputes FK and velocities.

    Root position (x, y, z) -> (x, -y, z), root quaternion (w, x, y, z) -> (w, -x, y, -z), left and
    right hinges swap, angles about x and z negate. Mirroring twice gives the clip back.

    Args:
        clip: a 15-body clip.

    Returns:
        The mirrored clip, named ``<name>_mirror`` (a mirrored mirror gets its name back).

    Raises:
        ValueError: for the sword-and-shield character, which is not left/right symmetric.
    """
    if clip.sword_shield:
        raise ValueError(
            f"cannot mirror {clip.name!r}: the sword-and-shield character is not "
            "left/right symmetric (sword in the right hand, shield on the left arm)"
        )
    src, sign = mirror_dof_map(clip.character)
    root_pos = clip.root_pos * np.array([1.0, -1.0, 1.0])
    root_quat = clip.root_quat * np.array([1.0, -1.0, 1.0, -1.0])
    dof_pos = clip.dof_pos[:, src] * sign
    name = clip.name[: -len("_mirror")] if clip.name.endswith("_mirror") else clip.name + "_mirror"
    return build_clip(
        name=name,
        path=clip.path,
        format=clip.format,
        fps=clip.fps,
        loop=clip.loop,
        sword_shield=False,
        root_pos=root_pos,
        root_quat=root_quat,
        dof_pos=dof_pos,
        fk_error_m=clip.fk_error_m,
    )
