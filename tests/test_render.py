"""Tests of jaxmotion.render (offscreen MuJoCo frames, video files) and jaxmotion.replay_html
(the self-contained three.js page, checked in headless Chromium by jaxmotion.browser).
Numpy/MuJoCo only: quick under JAX_DISABLE_JIT=1."""

from __future__ import annotations

import numpy as np
import pytest

from jaxmotion.viz import browser as B
from jaxmotion.viz import render as RD
from jaxmotion.viz import replay_html as H
from jaxmotion.motion import group_indices, make_test_clip
from jaxmotion.motion import rotations as R
from jaxmotion.physics.character import character

W, H_PX = 120, 90


@pytest.fixture(scope="module")
def gl():
    b = RD.gl_backend()
    if b is None:
        pytest.skip(
            "no headless OpenGL backend works (neither MUJOCO_GL=egl nor osmesa); "
            "install libegl1 libegl-mesa0 libgl1-mesa-dri or libosmesa6"
        )
    return b


def _clip_qpos(num_frames=3, sign=1.0, root_vel=(1.0, 0.0, 0.0)):
    ch = character()
    dof = sign * 0.6 * np.sin(np.linspace(0, 2.5, num_frames))[:, None] * np.ones(ch.num_dof)
    c = make_test_clip(num_frames, fps=10.0, dof_pos=dof, root_vel=root_vel)
    qpos = np.concatenate([c.root_pos, c.root_quat, c.dof_pos], axis=-1)
    return c, qpos


def _colors():
    ch = character()
    return RD.group_colors([group_indices(g, ch)[0] for g in ("upper", "lower")])


def test_scene_has_a_collision_free_ghost():
    import mujoco

    ch = character()
    m = mujoco.MjModel.from_xml_string(RD.scene_mjcf(False, ghost=True))
    assert m.nq == 2 * (7 + ch.num_dof) and m.nbody == 1 + 2 * ch.num_bodies
    ghost = m.geom_bodyid > ch.num_bodies
    assert ghost.sum() == sum(m.geom_bodyid[~ghost] >= 1)
    assert (m.geom_contype[ghost] == 0).all() and (m.geom_conaffinity[ghost] == 0).all()
    assert np.allclose(m.geom_rgba[ghost, 3], RD.GHOST_RGBA[3])
    assert m.body(ch.num_bodies + 1).name == RD.GHOST_PREFIX + ch.body_names[0]


def test_group_colors_first_group_wins():
    cols = RD.group_colors([[0, 1], [1, 2]])
    assert cols[0] == cols[1] == RD.GROUP_PALETTE[0] and cols[2] == RD.GROUP_PALETTE[1]


def test_aligned_reference_starts_on_the_simulation():
    _, ref = _clip_qpos(5)
    _, sim = _clip_qpos(5)
    yaw = 1.1
    sim[:, 3:7] = R.quat_mul(np.array([np.cos(yaw / 2), 0, 0, np.sin(yaw / 2)]), sim[:, 3:7])
    sim[:, :2] += [2.0, -3.0]
    out = RD.aligned_reference_qpos(ref, sim[0])
    np.testing.assert_allclose(out[0, :2], sim[0, :2], atol=1e-5)
    np.testing.assert_allclose(out[:, 2], ref[:, 2], atol=1e-5)  # height kept
    np.testing.assert_allclose(R.heading_angle(out[0, 3:7]), R.heading_angle(sim[0, 3:7]), atol=1e-5)
    np.testing.assert_array_equal(out[:, 7:], ref[:, 7:])
    # The reference's displacement is rotated with it (it moved +x; now along the sim's heading).
    d = out[-1, :2] - out[0, :2]
    assert np.isclose(np.arctan2(d[1], d[0]), yaw, atol=1e-4)


def test_render_frames_not_blank_and_moving(gl):
    _, q = _clip_qpos(3)
    _, ref = _clip_qpos(3, sign=-1.0, root_vel=(0.5, 0.3, 0.0))
    frames = RD.render_frames(q, ref, _colors(), W, H_PX, progress=False)
    assert frames.shape == (3, H_PX, W, 3) and frames.dtype == np.uint8
    for f in frames:
        assert f.std() > 10, "blank frame"
    for a, b in zip(frames[:-1], frames[1:]):
        assert np.abs(a.astype(int) - b.astype(int)).mean() > 0.5, "frames do not change"
    # Links are coloured by group: the upper group's orange-red shows up.
    r, g, b = (frames[..., i].astype(int) for i in range(3))
    assert ((r - b > 60) & (r > 120)).sum() > 20
    # The ghost is drawn: the same poses without it render differently.
    plain = RD.render_frames(q[:1], None, _colors(), W, H_PX, progress=False)
    assert np.abs(plain[0].astype(int) - frames[0].astype(int)).mean() > 0.2


def test_task_markers_are_drawn(gl):
    """A target point (sphere) and an aim direction (arrow) from ``Task.markers`` appear in the
    frame in their colours, and only where the markers are given."""
    _, q = _clip_qpos(2)
    q = q[:1]
    root = q[0, :3]
    target = np.array([root[0] + 0.8, root[1] + 0.8, 0.1])
    hand = root + np.array([0.0, -0.3, 0.4])
    markers = {"target": np.stack([target, target])[None], "aim": np.stack([hand, hand + [0.0, -0.6, 0.3]])[None]}
    size = (2 * W, 2 * H_PX)
    plain = next(RD.iter_frames(q, None, _colors(), *size, progress=False)).astype(int)
    drawn = next(RD.iter_frames(q, None, _colors(), *size, progress=False, markers=markers)).astype(int)
    changed = np.abs(drawn - plain).sum(-1) > 30
    assert changed.sum() > 50
    r, g, b = (drawn[..., i] for i in range(3))
    green = changed & (g - r > 60) & (g - b > 60)
    red = changed & (r - g > 60) & (r - b > 60)
    assert green.sum() > 20 and red.sum() > 10


def test_acting_sphere_only_with_several_policies():
    """The acting-policy marker: none for one policy; with several, one sphere per frame over the
    head in the acting policy's colour (the others are NaN, which ``marker_list`` leaves out)."""
    head = np.array([[0.0, 0.0, 1.5], [1.0, 0.0, 1.4], [2.0, 0.0, 1.3]])
    acting = np.array([0, 1, 1])
    assert RD.acting_markers(head, acting, 1) == {}
    mk = RD.acting_markers(head, acting, 3)
    assert set(mk) == {"acting0", "acting1", "acting2"}
    for t in range(3):
        ((seg, rgba, radius),) = RD.marker_list({k: v[t] for k, v in mk.items()})
        np.testing.assert_allclose(seg, [head[t] + [0, 0, RD.ACTING_HEIGHT_M]] * 2)
        assert rgba == RD.policy_rgba(acting[t]) and radius == RD.ACTING_RADIUS
    assert len({RD.policy_rgba(i) for i in range(len(RD.POLICY_COLORS))}) == len(RD.POLICY_COLORS)
    assert RD.marker_style("ball2") == (RD.MARKER_RGBA.get("ball", (0.9, 0.8, 0.1, 0.9)), RD.MARKER_RADII["ball"])
    assert RD.policy_legend(["a", "b"]) == f"{RD.POLICY_COLORS[0][0]} = a, {RD.POLICY_COLORS[1][0]} = b"


def test_acting_sphere_is_drawn_over_the_head(gl):
    """Policy 1's magenta sphere shows above the character, where a single-policy frame has none."""
    _, q = _clip_qpos(2)
    q = q[:1]
    head = q[:, :3] + [0.0, 0.0, 0.5]  # roughly the head of the upright test pose
    size = (2 * W, 2 * H_PX)
    plain = next(RD.iter_frames(q, None, _colors(), *size, progress=False)).astype(int)
    drawn = next(
        RD.iter_frames(q, None, _colors(), *size, progress=False, markers=RD.acting_markers(head, np.array([1]), 2))
    ).astype(int)
    changed = np.abs(drawn - plain).sum(-1) > 30
    r, g, b = (drawn[..., i] for i in range(3))
    magenta = changed & (r - g > 80) & (b - g > 80)
    assert magenta.sum() > 20
    rows = np.nonzero(magenta.any(1))[0]
    body = np.nonzero((np.abs(plain - plain[0, 0]).sum(-1) > 60).any(1))[0]  # rows the character fills
    assert rows.mean() < body.mean()  # above the body's middle (image rows grow downwards)


def test_render_frames_rejects_bad_shapes(gl):
    _, q = _clip_qpos(2)
    with pytest.raises(ValueError, match="must match"):
        RD.render_frames(q, q[:1], None, 32, 32, progress=False)
    with pytest.raises(ValueError, match="qpos has"):
        RD.render_frames(q[:, :10], None, None, 32, 32, progress=False)


def test_write_video_mp4_and_gif(tmp_path):
    rng = np.random.default_rng(0)
    frames = rng.integers(0, 255, (4, 33, 47, 3), dtype=np.uint8)  # odd sizes are padded for H.264
    mp4 = RD.write_video(frames, tmp_path / "v.mp4", fps=10)
    assert mp4.stat().st_size > 100 and mp4.read_bytes()[4:8] == b"ftyp"
    gif = RD.write_video(frames, tmp_path / "v.gif", fps=10)
    assert gif.read_bytes()[:6] in (b"GIF89a", b"GIF87a")
    from PIL import Image

    with Image.open(gif) as im:
        assert im.n_frames == 4


# ---- the HTML replay ---------------------------------------------------------------------------
def _page(tmp_path, with_ref=True):
    ch = character()
    c, _ = _clip_qpos(12)
    r, _ = _clip_qpos(12, sign=-1.0, root_vel=(0.8, 0.2, 0.0))
    cols = _colors()
    return H.write_html(
        tmp_path / "replay.html",
        ch.body_names,
        ch.parents,
        c.body_pos,
        c.body_quat,
        r.body_pos if with_ref else None,
        r.body_quat if with_ref else None,
        10.0,
        H.character_geoms(False, cols),
        legend={"upper": RD.GROUP_PALETTE[0], "lower": RD.GROUP_PALETTE[1]},
    )


def test_character_geoms_match_the_model():
    ch = character()
    geoms = H.character_geoms(False, {0: (1, 0, 0, 1)})
    assert {g["body"] for g in geoms} == set(range(ch.num_bodies))
    assert {g["type"] for g in geoms} == {"sphere", "capsule", "box"}
    pelvis = [g for g in geoms if g["body"] == 0]
    assert all(g["rgba"] == [1, 0, 0, 1] for g in pelvis)
    thigh = next(g for g in geoms if g["body"] == ch.body_index("right_thigh"))
    np.testing.assert_allclose(thigh["pos"], [0, 0, -0.21], atol=1e-6)  # fromto centre
    np.testing.assert_allclose(thigh["size"][:2], [0.055, 0.15], atol=1e-6)
    ss = H.character_geoms(True)
    assert "cylinder" in {g["type"] for g in ss}  # the shield


def test_write_html_is_self_contained(tmp_path):
    p = _page(tmp_path)
    text = p.read_text()
    assert text.count("<script") == 3  # data, three.js, app
    assert "@license" in text and "SPDX-License-Identifier: MIT" in text  # three.js header kept
    three = H.THREE_JS.read_text()
    assert three in text  # inlined verbatim
    ours = text.replace(three, "")
    for external in ("<script src", "<link ", "import(", "fetch(", "XMLHttpRequest"):
        assert external not in ours  # nothing is loaded at view time
    with pytest.raises(ValueError, match="frames"):
        ch = character()
        c, _ = _clip_qpos(4)
        H.write_html(
            tmp_path / "bad.html",
            ch.body_names,
            ch.parents,
            c.body_pos,
            c.body_quat,
            c.body_pos[:2],
            c.body_quat[:2],
            10.0,
            [],
        )


def test_write_html_carries_markers_and_acting_labels(tmp_path):
    """Markers and the acting policy go into the page's data as given; bad ones are refused."""
    import base64
    import json

    ch = character()
    c, _ = _clip_qpos(4)
    seg = np.zeros((4, 2, 3), np.float32)
    seg[:, 1, 0] = 1.0  # an arrow along x
    seg[2] = np.nan  # hidden on frame 2
    args = (ch.body_names, ch.parents, c.body_pos, c.body_quat, None, None, 10.0, [])
    marks = [{"name": "aim", "seg": seg, "rgba": RD.MARKER_RGBA["aim"], "radius": 0.08}]
    pols = [("A", RD.policy_rgba(0)), ("B", RD.policy_rgba(1))]
    p = H.write_html(tmp_path / "m.html", *args, markers=marks, acting=np.array([0, 0, 1, 1]), policies=pols)
    text = p.read_text()
    start = text.index('id="replay-data">') + len('id="replay-data">')
    data = json.loads(text[start : text.index("</script>", start)])
    (m,) = data["markers"]
    assert m["name"] == "aim" and m["rgba"] == list(RD.MARKER_RGBA["aim"]) and m["radius"] == 0.08
    np.testing.assert_array_equal(np.frombuffer(base64.b64decode(m["seg"]), "<f4").reshape(4, 2, 3), seg)
    assert data["acting"] == [0, 0, 1, 1] and [q["name"] for q in data["policies"]] == ["A", "B"]
    assert 'id="acting"' in text and "showActing(f)" in text and "showMarkers(f)" in text
    with pytest.raises(ValueError, match="marker 'aim'"):
        H.write_html(tmp_path / "bad.html", *args, markers=[dict(marks[0], seg=seg[:3])])
    with pytest.raises(ValueError, match="acting"):
        H.write_html(tmp_path / "bad.html", *args, acting=np.array([0, 0, 2, 1]), policies=pols)


@pytest.fixture(scope="module")
def chromium():
    path = B.find_chromium()
    if path is None:
        pytest.skip("Chromium not installed (apt-get install chromium): cannot check the HTML replay")
    return path


def test_html_replay_renders_in_headless_chromium(tmp_path, chromium):
    p = _page(tmp_path)
    res = B.check_in_browser(p, tmp_path / "shot.png", width=640, height=480, frame=6, chromium=chromium)
    assert res["ready"], f"page did not start: {res}"
    assert res["errors"] == [], res["errors"]
    from PIL import Image

    img = np.asarray(Image.open(res["png"]).convert("RGB")).astype(int)
    assert img.shape == (480, 640, 3)
    centre = img[120:360, 200:440]
    r, b = centre[..., 0], centre[..., 2]
    # The floor and the sky are blue-grey; the character's upper body is orange-red and its
    # lower body a saturated blue.
    orange = (r - b > 60) & (r > 120)
    blue = (b - r > 80) & (b > 150)
    assert orange.sum() > 150, f"no upper-body pixels near the centre ({orange.sum()})"
    assert blue.sum() > 150, f"no lower-body pixels near the centre ({blue.sum()})"
    bg = np.array([0x1D, 0x24, 0x30])
    assert (np.abs(centre - bg).sum(-1) > 30).mean() > 0.3, "mostly blank canvas"


def test_ghost_alignment_matches_eval_world_aligned():
    from jaxmotion.envs.reference import world_aligned

    ref, _ = _clip_qpos(6, root_vel=(0.7, 0.2, 0.0))
    sim, _ = _clip_qpos(6, sign=-1.0)
    yaw = -0.6
    sq = R.quat_mul(np.array([np.cos(yaw / 2), 0, 0, np.sin(yaw / 2)]), sim.body_quat)
    sp = sim.body_pos + np.array([1.0, 2.0, 0.0])
    q, off = RD.align_to_start(ref.body_pos[:, 0], ref.body_quat[:, 0], sp[0, 0], sq[0, 0])
    p, _ = RD.align_pose(q, off, ref.body_pos, ref.body_quat)
    f32 = lambda x: np.asarray(x, np.float32)
    expected = world_aligned(f32(ref.body_pos), f32(ref.body_quat), f32(sp[0]), f32(sq[0]))
    np.testing.assert_allclose(p, expected, atol=1e-5)
