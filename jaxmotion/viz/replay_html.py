"""A self-contained HTML replay of a rollout: three.js (inlined), the character's capsules,
spheres and boxes moved by the recorded link poses, the reference as a translucent ghost.

One file, no network at view time: ``jaxmotion/assets/three.min.js`` (three.js r160, MIT, the
classic non-module build; its licence header is kept and ``three.LICENSE`` sits next to it) is
inlined into the page together with the poses (float32, base64). The page has play/pause (space),
a frame slider, a speed selector, a ghost on/off checkbox, a follow-the-character checkbox, a
floor grid (1 m cells) and a small orbit camera (left drag: rotate, right drag or shift+drag:
pan, wheel: zoom). The world is MuJoCo's: z up, metres, quaternions wxyz. The task's goal
markers are drawn per frame as the video draws them (``render.marker_style``); after policy
switching the page names the acting run, in its colour, per frame. ``browser.check_in_browser``
opens a page in headless Chromium.

``python -m jaxmotion.eval <run> --html FILE`` writes deterministic rollout episode 0 with the
first body group's reference clip as the ghost (see ``render``'s module docstring).
"""

from __future__ import annotations

import base64
import html
import json
import os
from pathlib import Path
from collections.abc import Mapping, Sequence

import numpy as np

ASSETS = Path(__file__).with_name("assets")
THREE_JS = ASSETS / "three.min.js"
TEMPLATE = ASSETS / "replay.html"
"""The page: @@TITLE@@, @@DATA@@ (the recording as JSON), @@THREE@@ and @@APP@@ (scripts) filled in."""
APP_JS = ASSETS / "replay.js"
"""The viewer: reads the recording, builds the three.js scene, play/pause, scrub, speed, camera, ghost."""

_GEOM_TYPES = {2: "sphere", 3: "capsule", 5: "cylinder", 6: "box"}  # mjtGeom values


def character_geoms(
    sword_shield: bool = False,
    group_colors: Mapping[int, Sequence[float]] | None = None,
    default_rgba: Sequence[float] = (0.7, 0.7, 0.7, 1.0),
    racket: bool = False,
) -> list[dict]:
    """The character's geoms (``racket``: with the tennis racket) as plain dicts for ``write_html``.

    Each dict: ``body`` (link index, 0 = root), ``type`` (sphere | capsule | cylinder | box),
    ``size`` (MuJoCo's: radius / radius, half-length / half-sizes), ``pos`` [3] and ``quat`` [4]
    (wxyz) relative to the body frame, ``rgba`` (from ``group_colors`` by link, else
    ``default_rgba``). Taken from the compiled ``mujoco.MjModel`` of ``build_mjcf``, so
    ``fromto`` capsules come out as centre + orientation.
    """
    import mujoco
    from jaxmotion.physics.character import build_mjcf

    m = mujoco.MjModel.from_xml_string(build_mjcf(sword_shield, floor=False, racket=racket))
    colors = dict(group_colors or {})
    out = []
    for g in range(m.ngeom):
        b = int(m.geom_bodyid[g])
        typ = _GEOM_TYPES.get(int(m.geom_type[g]))
        if b == 0 or typ is None:
            continue
        out.append(
            {
                "body": b - 1,
                "type": typ,
                "size": [round(float(x), 6) for x in m.geom_size[g]],
                "pos": [round(float(x), 6) for x in m.geom_pos[g]],
                "quat": [round(float(x), 6) for x in m.geom_quat[g]],
                "rgba": [float(x) for x in colors.get(b - 1, default_rgba)],
            }
        )
    return out


def _b64(a: np.ndarray) -> str:
    return base64.b64encode(np.ascontiguousarray(a, "<f4").tobytes()).decode("ascii")


def _check(name: str, a, shape_tail: tuple[int, ...], T: int | None) -> np.ndarray:
    a = np.asarray(a, np.float32)
    if a.ndim != 3 or a.shape[2:] != shape_tail[1:] or a.shape[1] != shape_tail[0]:
        raise ValueError(f"{name} must be [T, {shape_tail[0]}, {shape_tail[1]}], got {a.shape}")
    if T is not None and a.shape[0] != T:
        raise ValueError(f"{name} has {a.shape[0]} frames, the simulation {T}")
    if not np.isfinite(a).all():
        raise ValueError(f"{name} contains NaN or inf")
    return a


def write_html(
    path: str | os.PathLike,
    body_names: Sequence[str],
    parents: Sequence[int],
    sim_pos: np.ndarray,
    sim_quat: np.ndarray,
    ref_pos: np.ndarray | None,
    ref_quat: np.ndarray | None,
    fps: float,
    geoms: Sequence[Mapping],
    *,
    title: str = "jaxmotion replay",
    legend: Mapping[str, Sequence[float]] | None = None,
    markers: Sequence[Mapping] = (),
    acting: np.ndarray | None = None,
    policies: Sequence[tuple[str, Sequence[float]]] = (),
) -> Path:
    """Writes the replay page.

    Args:
        path: output ``.html`` file.
        body_names, parents: the character's links (``character().body_names``/``parents``);
            drawn as thin bones between each link and its parent as well.
        sim_pos, sim_quat: [T, nb, 3] and [T, nb, 4] (wxyz) world-frame link poses.
        ref_pos, ref_quat: the same for the reference ghost, or None.
        fps: frames per second of the recording (the control rate).
        geoms: ``character_geoms(...)`` (or any list of such dicts).
        title: page title and heading.
        legend: optional name -> RGBA swatches (e.g. body group colours).
        markers: dicts with ``name``, ``seg`` [T, 2, 3] (world segment from, to per frame),
            ``rgba`` and ``radius``: drawn as ``render.py``'s video does (``marker_style``): a
            sphere where the segment has zero length, else an arrow; hidden on frames where it is
            not finite.
        acting: None, or [T] int: the index into ``policies`` of the policy acting per frame,
            named on screen with its colour (policy switching).
        policies: (name, RGBA) of the policies ``acting`` indexes.

    Returns:
        The path.
    """
    nb = len(body_names)
    if len(parents) != nb:
        raise ValueError(f"{len(parents)} parents for {nb} bodies")
    sp = _check("sim_pos", sim_pos, (nb, 3), None)
    T = sp.shape[0]
    sq = _check("sim_quat", sim_quat, (nb, 4), T)
    if (ref_pos is None) != (ref_quat is None):
        raise ValueError("give both ref_pos and ref_quat, or neither")
    marks = []
    for m in markers:
        seg = np.asarray(m["seg"], np.float32)
        if seg.shape != (T, 2, 3):
            raise ValueError(f"marker {m['name']!r} must be [{T}, 2, 3], got {seg.shape}")
        marks.append(
            {
                "name": str(m["name"]),
                "rgba": [float(x) for x in m["rgba"]],
                "radius": float(m["radius"]),
                "seg": _b64(seg),
            }
        )
    if acting is not None:
        acting = np.asarray(acting).astype(int).tolist()
        if len(acting) != T or not all(0 <= a < len(policies) for a in acting):
            raise ValueError(f"acting must be [{T}] indices into {len(policies)} policies")
    data = {
        "title": title,
        "fps": float(fps),
        "T": int(T),
        "nb": nb,
        "bodyNames": list(body_names),
        "parents": [int(p) for p in parents],
        "geoms": [dict(g) for g in geoms],
        "legend": {k: list(map(float, v)) for k, v in (legend or {}).items()},
        "simPos": _b64(sp),
        "simQuat": _b64(sq),
        "refPos": None,
        "refQuat": None,
        "markers": marks,
        "acting": acting,
        "policies": [{"name": str(n), "rgba": [float(x) for x in c]} for n, c in policies],
    }
    if ref_pos is not None:
        data["refPos"] = _b64(_check("ref_pos", ref_pos, (nb, 3), T))
        data["refQuat"] = _b64(_check("ref_quat", ref_quat, (nb, 4), T))
    three = THREE_JS.read_text(encoding="utf-8")
    if "</script" in three.lower():
        raise RuntimeError(f"{THREE_JS} contains '</script' and cannot be inlined")
    payload = json.dumps(data, separators=(",", ":")).replace("</", "<\\/")
    page = (
        TEMPLATE.read_text(encoding="utf-8")
        .replace("@@TITLE@@", html.escape(title))
        .replace("@@DATA@@", payload)
        .replace("@@APP@@", APP_JS.read_text(encoding="utf-8"))
        .replace("@@THREE@@", three)
    )
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(page, encoding="utf-8")
    return path


def write_rollout_html(
    learner,
    ro: Mapping[str, np.ndarray],
    path: str | os.PathLike,
    episode: int = 0,
    group: int = 0,
    title: str | None = None,
    policies: Sequence[str] = (),
) -> Path:
    """The replay page of one episode of ``evaluation.rollout.rollout``'s output (alive frames only), with
    ``group``'s reference clip as the ghost (``envs.reference.reference_sequence``, moved rigidly in xy +
    yaw onto the simulation's first root frame as ``envs.reference.world_aligned`` does) and the task's
    markers. ``policies``: names of the runs that took turns (``ro["acting"]`` indexes them); with
    two or more, the page names the acting one per frame and draws the video's sphere over the
    head in its colour."""
    from jaxmotion.envs.reference import reference_sequence
    from jaxmotion.viz.render import (
        GROUP_PALETTE,
        align_pose,
        align_to_start,
        learner_group_colors,
        marker_style,
        policy_rgba,
        rollout_markers,
    )

    ch = learner.env.character
    n = int(np.asarray(ro["alive"])[:, episode].sum())
    sp = np.asarray(ro["pos"])[:n, episode]
    sq = np.asarray(ro["quat"])[:n, episode]
    rp, rq = reference_sequence(learner, group, n)
    q, off = align_to_start(rp[:, 0], rq[:, 0], sp[0, 0], sq[0, 0])
    rp, rq = align_pose(q, off, rp, rq)
    names = [g.name for g in learner.cfg.env.groups]
    colors = learner_group_colors(learner)
    legend = {name: GROUP_PALETTE[i % len(GROUP_PALETTE)] for i, name in enumerate(names)}
    ref_name = names[group] if names else "reference"
    markers = [
        {"name": k, "seg": v, "rgba": marker_style(k)[0], "radius": marker_style(k)[1]}
        for k, v in rollout_markers(learner, ro, episode, n, len(policies)).items()
    ]
    switched = len(policies) > 1 and ro.get("acting") is not None
    return write_html(
        path,
        ch.body_names,
        ch.parents,
        sp,
        sq,
        rp,
        rq,
        1.0 / learner.env.dt,
        character_geoms(ch.sword_shield, colors, racket=learner.env.cfg.physics.racket),
        title=title or f"jaxmotion replay (ghost: {ref_name} reference)",
        legend=legend,
        markers=markers,
        acting=np.asarray(ro["acting"])[:n, episode] if switched else None,
        policies=[(name, policy_rgba(i)) for i, name in enumerate(policies)] if switched else (),
    )
