"""BVH reading and retargeting onto the character (``motion.bvh``, ``motion.retarget``).

A clip of ours is written out as BVH by a small writer here (independent of the parser: scipy's
Euler angles, its own FK) with the character's own skeleton, and with another skeleton (LAFAN1
joint names, other bone lengths, another rotation order per joint, Y-up, centimetres), then read
back and retargeted.
"""

from __future__ import annotations

import json
import re

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from jaxmotion.motion import rotations as rot
from jaxmotion.motion.__main__ import main as motion_main
from jaxmotion.motion.bvh import parse_bvh
from jaxmotion.motion.clip import make_test_clip
from jaxmotion.motion.data import data_dir
from jaxmotion.motion.errors import MotionFileError
from jaxmotion.motion.level import sole_points
from jaxmotion.motion.loaders import load_clip
from jaxmotion.motion.retarget import load_mapping, retarget_file
from jaxmotion.physics.character import character

CH = character(False)
# y-up -> z-up is p_z = C p_y; so p_y = C^T p_z.
C = np.array([[1.0, 0, 0], [0, 0, -1], [0, 1, 0]])
LAFAN = {
    "pelvis": "Hips",
    "torso": "Spine1",
    "head": "Neck",
    "right_upper_arm": "RightArm",
    "right_lower_arm": "RightForeArm",
    "right_hand": "RightHand",
    "left_upper_arm": "LeftArm",
    "left_lower_arm": "LeftForeArm",
    "left_hand": "LeftHand",
    "right_thigh": "RightUpLeg",
    "right_shin": "RightLeg",
    "right_foot": "RightFoot",
    "left_thigh": "LeftUpLeg",
    "left_shin": "LeftLeg",
    "left_foot": "LeftFoot",
}
ORDERS = ("ZXY", "XYZ", "YZX", "ZYX", "XZY", "YXZ")


def _walk_clip():
    """The shared DeepMimic walk when present, else a synthetic stepping clip."""
    path = data_dir() / "deepmimic" / "humanoid3d_walk.txt"
    if path.is_file():
        return load_clip(path)
    T = 40
    t = np.arange(T) / 30.0
    dof = np.zeros((T, CH.num_dof))
    names = list(CH.joint_names)
    for side, phase in (("right", 0.0), ("left", np.pi)):
        swing = np.sin(2 * np.pi * t + phase)
        dof[:, names.index(f"{side}_hip_y")] = -0.4 * np.maximum(swing, 0)
        dof[:, names.index(f"{side}_knee")] = 0.8 * np.maximum(swing, 0)
    return make_test_clip(T, 30.0, root_vel=(1.0, 0, 0), root_height=0.89, dof_pos=dof)


def write_bvh(path, clip, *, names, extra=(), scale=1.0, bone_scale=None, yup=False, orders=("XYZ",), fps=None):
    """Writes ``clip`` as BVH: one joint per body (``names``: body -> joint name), ``extra``
    leaf joints (name, parent body, z-up offset in m) with no rotation, offsets multiplied by
    ``bone_scale[body]`` and all lengths by ``scale`` (file units per metre), y-up if ``yup``,
    the i-th joint's Euler order ``orders[i % len(orders)]``."""
    bone_scale = bone_scale or {}
    leg = bone_scale.get("left_shin", 1.0)
    conv = C.T if yup else np.eye(3)
    q = clip.body_quat
    local = np.empty_like(q)
    local[:, 0] = q[:, 0]
    for b in range(1, CH.num_bodies):
        local[:, b] = rot.quat_mul(rot.quat_conj(q[:, CH.parents[b]]), q[:, b])
    children = {b: [c for c in range(CH.num_bodies) if CH.parents[c] == b] for b in range(CH.num_bodies)}
    order_of, lines, cols = {}, ["HIERARCHY"], []

    def joint(b, depth):
        ind = "  " * depth
        o = CH.body_offsets[b] * bone_scale.get(CH.body_names[b], 1.0) if b else np.zeros(3)
        o = conv @ o * scale
        order = orders[len(order_of) % len(orders)]
        order_of[b] = order
        lines.append(f"{ind}{'ROOT' if b == 0 else 'JOINT'} {names[CH.body_names[b]]}")
        lines.append(f"{ind}{{")
        lines.append(f"{ind}  OFFSET {o[0]:.6f} {o[1]:.6f} {o[2]:.6f}")
        rc = [f"{a}rotation" for a in order]
        lines.append(
            f"{ind}  CHANNELS {6 if b == 0 else 3} {'Xposition Yposition Zposition ' if b == 0 else ''}{' '.join(rc)}"
        )
        cols.append(b)
        for c in children[b]:
            joint(c, depth + 1)
        kids = [e for e in extra if e[1] == CH.body_names[b]]
        for name, _, off in kids:
            e = conv @ np.asarray(off) * scale
            lines.append(f"{ind}  JOINT {name}\n{ind}  {{\n{ind}    OFFSET {e[0]:.6f} {e[1]:.6f} {e[2]:.6f}")
            lines.append(f"{ind}    CHANNELS 3 Zrotation Xrotation Yrotation")
            lines.append(f"{ind}    End Site\n{ind}    {{\n{ind}      OFFSET 0 0 1\n{ind}    }}\n{ind}  }}")
            cols.append(None)
        if not children[b] and not kids:
            lines.append(f"{ind}  End Site\n{ind}  {{\n{ind}    OFFSET 0 0 0\n{ind}  }}")
        lines.append(f"{ind}}}")

    joint(0, 0)
    rows = []
    root = (conv @ (clip.root_pos * [1, 1, leg]).T).T * scale
    for t in range(clip.num_frames):
        vals = list(root[t])
        for b in cols:
            if b is None:
                vals += [0.0, 0.0, 0.0]
                continue
            m = conv @ rot.quat_to_mat(local[t, b]) @ conv.T
            vals += list(Rotation.from_matrix(m).as_euler(order_of[b], degrees=True))
        rows.append(" ".join(f"{v:.6f}" for v in vals))
    lines += ["MOTION", f"Frames: {clip.num_frames}", f"Frame Time: {1.0 / (fps or clip.fps):.8f}", *rows]
    path.write_text("\n".join(lines) + "\n")
    return path


SELF = {b: b for b in CH.body_names}
LAFAN_EXTRA = (
    ("Head", "head", (0.0, 0.0, 0.1)),
    ("RightToe", "right_foot", (0.12, 0.0, -0.04)),
    ("LeftToe", "left_foot", (0.12, 0.0, -0.04)),
)
OTHER = {
    "left_thigh": 1.1, "right_thigh": 1.1, "left_shin": 1.1, "right_shin": 1.1, "left_foot": 1.1, "right_foot": 1.1,
    "left_lower_arm": 0.9, "right_lower_arm": 0.9, "left_hand": 0.9, "right_hand": 0.9, "torso": 1.05, "head": 1.05,
}  # fmt: skip


@pytest.fixture(scope="module")
def walk():
    return _walk_clip()


def test_own_skeleton_round_trip(tmp_path, walk):
    """Our clip as BVH with our skeleton, mapped to itself: the link positions come back within 1 cm."""
    f = write_bvh(tmp_path / "self.bvh", walk, names=SELF, orders=ORDERS)
    clip, report = retarget_file(f, "humanoid", floor=False)
    err = np.linalg.norm(clip.body_pos - walk.body_pos, axis=-1)
    print(
        f"self round trip: link error mean {err.mean() * 1000:.2f} mm, max {err.max() * 1000:.2f} mm; "
        f"{report.summary()}"
    )
    assert err.max() < 0.01
    assert report.height_scale == pytest.approx(1.0, abs=1e-6)
    assert report.max_error_mm.max() < 10.0


CGSPEED = {**LAFAN, "torso": "Spine1", "head": "Head"}
CGSPEED_EXTRA = (("RightToeBase", "right_foot", (0.12, 0.0, -0.04)), ("LeftToeBase", "left_foot", (0.12, 0.0, -0.04)))
ASF = {
    "pelvis": "hip", "torso": "upperback", "head": "lowerneck",
    "right_upper_arm": "rhumerus", "right_lower_arm": "rradius", "right_hand": "rwrist",
    "left_upper_arm": "lhumerus", "left_lower_arm": "lradius", "left_hand": "lwrist",
    "right_thigh": "rfemur", "right_shin": "rtibia", "right_foot": "rfoot",
    "left_thigh": "lfemur", "left_shin": "ltibia", "left_foot": "lfoot",
}  # fmt: skip
ASF_EXTRA = (
    ("head", "head", (0.0, 0.0, 0.1)),
    ("rtoes", "right_foot", (0.12, 0.0, -0.04)),
    ("ltoes", "left_foot", (0.12, 0.0, -0.04)),
)


@pytest.mark.parametrize(
    "skeleton, names, extra",
    [("lafan1", LAFAN, LAFAN_EXTRA), ("cmu_cgspeed", CGSPEED, CGSPEED_EXTRA), ("cmu", ASF, ASF_EXTRA)],
)
def test_other_skeleton_feet_on_floor(tmp_path, walk, skeleton, names, extra):
    """Another skeleton's joint names, 10% longer legs, shorter forearms, mixed rotation orders,
    Y-up, centimetres: the mapping is found by the names, the feet land on the floor."""
    f = write_bvh(
        tmp_path / "other.bvh", walk, names=names, extra=extra, scale=100.0, bone_scale=OTHER, yup=True, orders=ORDERS
    )
    clip, report = retarget_file(f)
    assert report.skeleton == skeleton and report.metres_per_unit == 0.01
    assert report.height_scale == pytest.approx(1 / 1.1, rel=1e-3)
    low = sole_points(clip)[:, :, 2].min(axis=1)
    src = sole_points(walk)[:, :, 2].min(axis=1)
    contact = src < np.percentile(src, 5) + 0.02
    print(
        f"{skeleton}: {report.summary()}; lowest foot point on {contact.sum()} contact frames "
        f"{low[contact].min() * 100:.2f} to {low[contact].max() * 100:.2f} cm, overall min {low.min() * 100:.2f} cm"
    )
    assert np.abs(low[contact]).max() < 0.03
    assert low.min() > -0.02
    assert report.error_mm.mean() < 30.0


def test_cli_retarget_writes_a_clip(tmp_path, walk, capsys):
    short = make_test_clip(6, 30.0)
    f = write_bvh(tmp_path / "s.bvh", short, names=LAFAN, extra=LAFAN_EXTRA, scale=100.0, yup=True)
    out = tmp_path / "clip.json"
    assert motion_main(["retarget", str(f), "--skeleton", "lafan1", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "position error mean" in text and "lafan1" in text
    back, (clip, _) = load_clip(out), retarget_file(f, "lafan1")
    assert back.num_frames == 6 and json.loads(out.read_text())["fps"] == 30.0
    assert np.abs(back.body_pos - clip.body_pos).max() < 1e-3  # the JSON holds the retargeted clip
    assert motion_main([str(f)]) == 0  # the listing reads BVH too
    assert "skeleton lafan1" in capsys.readouterr().out


def _good_bvh(tmp_path):
    return write_bvh(tmp_path / "g.bvh", make_test_clip(3, 30.0), names=SELF).read_text()


@pytest.mark.parametrize(
    "edit, problem",
    [
        (lambda s: s[: len(s) - 40], "frame 2 has"),  # truncated mid-row
        (lambda s: s.replace("Frames: 3", "Frames: 5"), "truncated: the header says 5 frames"),
        (lambda s: s.replace("Xrotation", "Wrotation", 1), "unknown channel 'Wrotation'"),
        (lambda s: s.rstrip("\n") + " 0.5\n", "frame 2 has 49 values"),
        (lambda s: re.sub(r"(Frame Time: \S+\n)\S+", r"\1nan", s), "non-finite value 'nan' at frame 0"),
        (lambda s: s.split("MOTION")[0][:200], "no MOTION section"),
        (lambda s: s.replace("left_foot", "left_paw"), "does not cover this BVH: no joint 'left_foot'"),
    ],
)
def test_bad_bvh_one_line(tmp_path, edit, problem, capsys):
    f = tmp_path / "bad.bvh"
    f.write_text(edit(_good_bvh(tmp_path)))
    with pytest.raises(MotionFileError) as e:
        retarget_file(f, "humanoid")
    msg = str(e.value)
    assert "\n" not in msg and str(f) in msg and problem in msg, msg
    assert motion_main(["retarget", str(f), "--skeleton", "humanoid", "--out", str(tmp_path / "o.json")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and problem in err[0]


def test_unknown_skeleton_and_units(tmp_path):
    text = _good_bvh(tmp_path).replace("pelvis", "root_of_all")
    f = tmp_path / "odd.bvh"
    f.write_text(text)
    with pytest.raises(MotionFileError, match="no skeleton mapping covers this BVH"):
        load_clip(f)
    bvh = parse_bvh(text)
    assert bvh.rotation_order(0) == "XYZ" and bvh.num_frames == 3
    with pytest.raises(MotionFileError, match="units 'furlong'"):
        retarget_file(tmp_path / "g.bvh", "humanoid", units="furlong")
    assert load_mapping("cmu").joints[0] == "hip"
