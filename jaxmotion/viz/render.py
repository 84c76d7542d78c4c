"""Offscreen rendering of rollouts: the simulated character coloured by body group, with the
reference motion overlaid as a translucent ghost, written out as MP4 (or GIF).

Headless OpenGL: ``gl_backend()`` picks ``MUJOCO_GL`` itself. A value the user set is respected;
otherwise EGL is tried, then OSMesa, each in a throw-away subprocess (a backend that fails can
leave PyOpenGL bound to the wrong platform, so it is never tried in this process), and the first
that renders is installed as the GL context class of ``mujoco.Renderer``. MuJoCo picks its
context class when ``mujoco`` is first imported, which in jaxmotion happens long before anything
renders, so the class is swapped in place rather than only exporting the variable.

The scene is one MJCF with two copies of the character: the simulated one (names as in
``physics.character.build_mjcf``) and a ghost (names prefixed ``ghost_``) whose geoms are
translucent and collide with nothing. Only kinematics is computed per frame (no physics step),
so the ghost never interacts with anything.

``render_rollout`` is what ``python -m jaxmotion.eval <run> --video FILE`` calls: deterministic
rollout episode 0, with the ghost replaying the *first* body group's reference clip (for a
composite run, e.g. upper = chest_open + lower = squat, the ghost shows the upper group's clip
as a whole-body motion; the other groups' clips are not drawn). The ghost's qpos comes from
MotionLib ``sample`` + ``qpos_qvel`` of that group's first clip at the control rate, repeated to
the episode length as ``envs.reference.reference_sequence`` does, and moved rigidly (xy + yaw) so that its
first root heading frame coincides with the simulation's first one, as ``envs.reference.world_aligned``.
The task's goal markers are drawn over it; when several policies took turns (``eval --switch``),
so is a sphere over the head in the acting policy's colour (``POLICY_COLORS``; eval prints which
colour is which run).
"""

from __future__ import annotations

import contextlib
import functools
import os
import subprocess
import sys
import warnings
import xml.etree.ElementTree as ET
from pathlib import Path
from collections.abc import Iterable, Iterator, Mapping, Sequence

import numpy as np

from jaxmotion.config.errors import JaxmotionError
from jaxmotion.envs.reference import align_pose, align_to_start, reference_state

GHOST_PREFIX = "ghost_"
MARKER_RADIUS = 0.08
MARKER_RGBA = {"target": (0.1, 0.8, 0.2, 0.9), "aim": (0.9, 0.15, 0.1, 0.9), "heading": (0.1, 0.4, 0.9, 0.9)}
"""Colours of the task markers by name (``Task.markers``; a trailing number is ignored: ball0 is a
ball); others are yellow."""
MARKER_RADII = {"ball": 0.05}
ACTING_PREFIX = "acting"
"""Markers named ``acting<i>`` show that policy ``i`` acts (policy switching): a sphere over the
head in ``POLICY_COLORS[i]``."""
ACTING_HEIGHT_M = 0.45  # above the head link's origin: clear of the head sphere (its top is 0.27 m up)
ACTING_RADIUS = 0.07
POLICY_COLORS = (
    ("white", (0.97, 0.97, 0.97, 1.0)),
    ("magenta", (0.95, 0.15, 0.85, 1.0)),
    ("cyan", (0.1, 0.9, 0.95, 1.0)),
    ("orange", (1.0, 0.55, 0.0, 1.0)),
    ("lime", (0.6, 1.0, 0.1, 1.0)),
    ("black", (0.05, 0.05, 0.05, 1.0)),  # last: the least visible against the dusk sky
)
"""(name, RGBA) of the policies that take turns, in ``evaluation.rollout.rollout``'s order: unlike the group and
task-marker colours, so that the sphere over the head reads as "who acts", and named, so that a
legend can be printed."""
GHOST_RGBA = (0.85, 0.9, 1.0, 0.3)
DEFAULT_LINK_RGBA = (0.7, 0.7, 0.7, 1.0)
# One colour per body group, in the order of cfg.env.groups (tab10-like, opaque).
GROUP_PALETTE = (
    (0.90, 0.33, 0.20, 1.0),  # orange-red
    (0.20, 0.50, 0.85, 1.0),  # blue
    (0.30, 0.70, 0.30, 1.0),  # green
    (0.75, 0.45, 0.85, 1.0),  # purple
    (0.95, 0.75, 0.20, 1.0),  # yellow
    (0.40, 0.80, 0.80, 1.0),  # teal
)

_PROBE = r"""
import mujoco, numpy as np
m = mujoco.MjModel.from_xml_string('<mujoco><worldbody><light pos="0 0 3"/>'
                                   '<geom type="sphere" size=".5"/></worldbody></mujoco>')
d = mujoco.MjData(m)
mujoco.mj_forward(m, d)
with mujoco.Renderer(m, 32, 32) as r:
    r.update_scene(d)
    img = r.render()
assert img.shape == (32, 32, 3) and img.max() > 0, "blank image"
print("ok")
"""


@contextlib.contextmanager
def quiet_fork():
    """Silences JAX's 'os.fork() was called' warning around fork+exec of a helper program (the
    GL probe, ffmpeg, Chromium): the child runs no Python and no JAX, it execs at once."""
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=r"os\.fork\(\) was called", category=RuntimeWarning)
        yield


def _probe(backend: str, timeout: float = 60.0) -> bool:
    """Whether ``MUJOCO_GL=backend`` renders a non-blank image, tried in a subprocess."""
    env = dict(os.environ, MUJOCO_GL=backend)
    env.pop("PYOPENGL_PLATFORM", None)
    try:
        with quiet_fork():
            r = subprocess.run([sys.executable, "-c", _PROBE], env=env, capture_output=True, text=True, timeout=timeout)
    except (subprocess.TimeoutExpired, OSError):
        return False
    return r.returncode == 0 and "ok" in r.stdout


def _install(backend: str) -> None:
    """Makes ``mujoco.Renderer`` create ``backend`` GL contexts from now on."""
    os.environ["MUJOCO_GL"] = backend
    if backend in ("egl", "osmesa"):
        os.environ.setdefault("PYOPENGL_PLATFORM", backend)
    from mujoco.rendering.classic import gl_context  # mujoco>=3.3 layout

    if backend == "egl":
        from mujoco.egl import GLContext
    elif backend == "osmesa":
        from mujoco.osmesa import GLContext
    else:
        from mujoco.glfw import GLContext
    gl_context.GLContext = GLContext


@functools.cache
def gl_backend() -> str | None:
    """The headless GL backend in use ('egl', 'osmesa', or the user's ``MUJOCO_GL``), or None.

    None means no backend could render (install ``libegl1 libegl-mesa0 libgl1-mesa-dri`` for
    EGL, or ``libosmesa6`` for OSMesa). The choice is made once per process.
    """
    user = os.environ.get("MUJOCO_GL", "").strip().lower()
    candidates = [user] if user else ["egl", "osmesa"]
    for b in candidates:
        if _probe(b):
            _install(b)
            return b
    return None


class NoGLError(JaxmotionError, RuntimeError):
    """No headless OpenGL backend renders on this machine."""


def require_gl() -> str:
    """``gl_backend()`` or a ``NoGLError`` saying what to install."""
    b = gl_backend()
    if b is None:
        tried = os.environ.get("MUJOCO_GL") or "egl, osmesa"
        raise NoGLError(
            f"no headless OpenGL backend works (tried MUJOCO_GL={tried}); install EGL "
            "(apt-get install libegl1 libegl-mesa0 libgl1-mesa-dri) or OSMesa (libosmesa6)"
        )
    return b


# ---- the scene ---------------------------------------------------------------------------------
def scene_mjcf(
    sword_shield: bool = False, ghost: bool = True, scenery: Sequence[Mapping[str, str]] = (), racket: bool = False
) -> str:
    """MJCF of the character (``racket``: with the tennis racket) over the floor, plus (``ghost``)
    a translucent, collision-free copy whose bodies, joints and geoms are named ``ghost_<name>``;
    its qpos follows the character's. ``scenery``: extra static geoms (MJCF attribute dicts, e.g.
    ``physics.arena.scenery``)."""
    from jaxmotion.physics.character import build_mjcf

    root = ET.fromstring(build_mjcf(sword_shield, racket=racket))
    wb = root.find("worldbody")
    for g in scenery:
        ET.SubElement(wb, "geom", contype="0", conaffinity="0", **dict(g))
    vis = root.find("visual")
    if vis is not None:  # a brighter headlight and cheaper shadows; keep the offscreen buffer
        ET.SubElement(vis, "quality", shadowsize="2048")
        ET.SubElement(vis, "headlight", ambient=".35 .35 .35", diffuse=".5 .5 .5", specular=".1 .1 .1")
    asset = root.find("asset")
    if asset is not None:  # a dusk-blue sky instead of black
        ET.SubElement(
            asset,
            "texture",
            type="skybox",
            builtin="gradient",
            rgb1=".35 .45 .55",
            rgb2=".05 .07 .1",
            width="64",
            height="512",
        )
    if ghost:
        body = next(b for b in wb if b.tag == "body")
        g = ET.fromstring(ET.tostring(body))
        for el in g.iter():
            if "name" in el.attrib:
                el.set("name", GHOST_PREFIX + el.get("name"))
            if el.tag == "geom":
                el.set("contype", "0")
                el.set("conaffinity", "0")
                el.set("rgba", " ".join(f"{x:g}" for x in GHOST_RGBA))
                el.set("group", "1")
                el.set("density", "1")  # irrelevant (never stepped), keeps the model light
            if el.tag == "joint":
                el.attrib.pop("armature", None)
        wb.append(g)
    return ET.tostring(root, encoding="unicode")


def group_colors(
    link_groups: Sequence[Sequence[int]], palette: Sequence[Sequence[float]] = GROUP_PALETTE
) -> dict[int, tuple[float, ...]]:
    """link index -> RGBA, group ``i`` in ``palette[i]``; a link in two groups keeps the first."""
    out: dict[int, tuple[float, ...]] = {}
    for i, links in enumerate(link_groups):
        for link in np.asarray(links).reshape(-1):
            out.setdefault(int(link), tuple(float(x) for x in palette[i % len(palette)]))
    return out


def learner_group_colors(learner) -> dict[int, tuple[float, ...]]:
    """Colours of a learner's body groups (``learner.env.group_idx``), in config order."""
    return group_colors([links for links, _ in learner.env.group_idx])


def _sword_shield_from_nq(nq: int) -> bool:
    from jaxmotion.physics.character import character

    for ss in (False, True):
        if 7 + character(ss).num_dof == nq:
            return ss
    raise ValueError(
        f"qpos has {nq} entries; the characters have {7 + character(False).num_dof} or {7 + character(True).num_dof}"
    )


class SceneRenderer:
    """A reusable renderer of the two-character scene (keeps one GL context)."""

    def __init__(
        self,
        sword_shield: bool = False,
        width: int = 640,
        height: int = 480,
        group_colors: Mapping[int, Sequence[float]] | None = None,
        ghost_rgba: Sequence[float] = GHOST_RGBA,
        scenery: Sequence[Mapping[str, str]] = (),
        racket: bool = False,
    ):
        import mujoco

        require_gl()
        self.mujoco = mujoco
        self.model = mujoco.MjModel.from_xml_string(
            scene_mjcf(sword_shield, ghost=True, scenery=scenery, racket=racket)
        )
        m = self.model
        m.vis.global_.offwidth = max(int(m.vis.global_.offwidth), width)
        m.vis.global_.offheight = max(int(m.vis.global_.offheight), height)
        m.vis.map.znear = 0.02
        self.data = mujoco.MjData(m)
        from jaxmotion.physics.character import character

        self.nb = character(sword_shield).num_bodies
        self.nq = 7 + character(sword_shield).num_dof
        assert m.nq == 2 * self.nq and m.nbody == 1 + 2 * self.nb, "unexpected scene layout"
        colors = dict(group_colors or {})
        body = m.geom_bodyid
        for gi in range(m.ngeom):
            b = int(body[gi])
            if 1 <= b <= self.nb:
                m.geom_rgba[gi] = colors.get(b - 1, DEFAULT_LINK_RGBA)
            elif b > self.nb:
                m.geom_rgba[gi] = ghost_rgba
        self._ghost_geoms = body > self.nb
        self.renderer = mujoco.Renderer(m, height=height, width=width)
        self.camera = mujoco.MjvCamera()
        self.camera.type = mujoco.mjtCamera.mjCAMERA_FREE
        self.camera.distance = 3.5
        self.camera.azimuth = 135.0
        self.camera.elevation = -15.0
        self.option = mujoco.MjvOption()
        self.width, self.height = width, height

    def render(
        self,
        qpos: np.ndarray,
        ghost_qpos: np.ndarray | None,
        lookat: np.ndarray,
        markers: Sequence[tuple[np.ndarray, Sequence[float]]] = (),
    ) -> np.ndarray:
        """One RGB frame [H, W, 3] uint8; ``ghost_qpos`` None hides the ghost. ``markers``: task
        goals as (segment [2, 3], rgba): a sphere where the segment has no length, else an arrow."""
        mj = self.mujoco
        self.data.qpos[: self.nq] = qpos
        if ghost_qpos is None:
            self.data.qpos[self.nq :] = qpos
            self.data.qpos[self.nq + 2] = -100.0  # far below the floor: invisible
            self.option.geomgroup[1] = 0
        else:
            self.data.qpos[self.nq :] = ghost_qpos
            self.option.geomgroup[1] = 1
        mj.mj_kinematics(self.model, self.data)
        mj.mj_comPos(self.model, self.data)  # the light tracks the CoM
        self.camera.lookat[:] = lookat
        self.renderer.update_scene(self.data, camera=self.camera, scene_option=self.option)
        add_markers(self.renderer.scene, markers)
        return self.renderer.render().copy()

    def close(self) -> None:
        self.renderer.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def add_markers(scn, markers: Sequence[tuple]) -> None:
    """Appends task markers to a scene: a [2, 3] segment (from, to) of zero length is a sphere,
    any other an arrow. Used by the video renderer and by the interactive viewer (``play.py``).
    A marker may carry its sphere radius as a third element (default ``MARKER_RADIUS``)."""
    import mujoco as mj

    for seg, rgba, *radius in markers:
        if scn.ngeom >= scn.maxgeom:
            break
        g = scn.geoms[scn.ngeom]
        a, b = np.asarray(seg[0], np.float64), np.asarray(seg[1], np.float64)
        rgba = np.asarray(rgba, np.float32)
        if np.linalg.norm(b - a) < 1e-6:
            mj.mjv_initGeom(
                g,
                mj.mjtGeom.mjGEOM_SPHERE,
                np.array([radius[0] if radius else MARKER_RADIUS, 0, 0]),
                a,
                np.eye(3).ravel(),
                rgba,
            )
        else:
            mj.mjv_initGeom(g, mj.mjtGeom.mjGEOM_ARROW, np.zeros(3), np.zeros(3), np.eye(3).ravel(), rgba)
            mj.mjv_connector(g, mj.mjtGeom.mjGEOM_ARROW, 0.02, a, b)
        scn.ngeom += 1


def policy_rgba(i: int) -> tuple[float, ...]:
    """Colour of policy ``i`` (``POLICY_COLORS``, cycled)."""
    return POLICY_COLORS[i % len(POLICY_COLORS)][1]


def policy_legend(names: Sequence[str]) -> str:
    """'white = A, magenta = B': which colour of the acting-policy sphere is which run."""
    return ", ".join(f"{POLICY_COLORS[i % len(POLICY_COLORS)][0]} = {n}" for i, n in enumerate(names))


def marker_style(name: str) -> tuple[tuple[float, ...], float]:
    """(RGBA, sphere radius) of a marker by name: ``acting<i>`` in policy ``i``'s colour, else by
    ``MARKER_RGBA``/``MARKER_RADII`` with a trailing number ignored (ball0 is a ball), yellow
    when unknown. The video and the HTML replay both draw with it, so their colours agree."""
    base = name.rstrip("0123456789")
    if base == ACTING_PREFIX and base != name:
        return policy_rgba(int(name[len(base) :])), ACTING_RADIUS
    return MARKER_RGBA.get(base, (0.9, 0.8, 0.1, 0.9)), MARKER_RADII.get(base, MARKER_RADIUS)


def marker_list(markers: Mapping[str, np.ndarray]) -> list[tuple[np.ndarray, Sequence[float], float]]:
    """(segment, colour, sphere radius) of one frame's markers (name -> [2, 3]). A segment with a
    non-finite coordinate is left out: the marker is absent on this frame (``acting_markers``)."""
    out = []
    for name, seg in markers.items():
        seg = np.asarray(seg)
        if np.isfinite(seg).all():
            out.append((seg, *marker_style(name)))
    return out


def acting_markers(head_pos: np.ndarray, acting: np.ndarray, num_policies: int) -> dict[str, np.ndarray]:
    """Markers showing which policy acts: ``acting<i>`` -> [T, 2, 3], a point ``ACTING_HEIGHT_M``
    above the head where policy ``i`` acts and NaN (not drawn) elsewhere; none for one policy, so
    a single-policy video is unchanged.

    Args:
      head_pos: [T, 3] world position of the head link.
      acting: [T] int, the acting policy per frame (``evaluation.rollout.rollout``'s ``acting``).
      num_policies: how many policies take turns.
    """
    if num_policies < 2:
        return {}
    p = np.asarray(head_pos, np.float64) + np.array([0.0, 0.0, ACTING_HEIGHT_M])
    acting = np.asarray(acting)
    out = {}
    for i in range(num_policies):
        q = np.where((acting == i)[:, None], p, np.nan)
        out[f"{ACTING_PREFIX}{i}"] = np.stack([q, q], axis=1)
    return out


def rollout_markers(
    learner, ro: Mapping[str, np.ndarray], episode: int, n: int, num_policies: int = 1
) -> dict[str, np.ndarray]:
    """The first ``n`` frames' markers of one ``evaluation.rollout.rollout`` episode, name -> [n, 2, 3]: the
    task's goal (``ro["markers"]``) and, when ``num_policies`` > 1, the acting policy's sphere."""
    out = {k: np.asarray(v)[:n, episode] for k, v in (ro.get("markers") or {}).items()}
    if num_policies > 1 and ro.get("acting") is not None:
        head = np.asarray(ro["pos"])[:n, episode, learner.env.character.body_index("head")]
        out.update(acting_markers(head, np.asarray(ro["acting"])[:n, episode], num_policies))
    return out


def follow_lookat(root_pos: np.ndarray, smoothing: float = 0.9, height: float = 0.9) -> np.ndarray:
    """[T, 3] camera targets following the root's xy (exponentially smoothed) at a fixed height."""
    root_pos = np.asarray(root_pos, np.float64)
    out = np.empty_like(root_pos)
    cur = root_pos[0, :2].copy()
    for t in range(len(root_pos)):
        cur = smoothing * cur + (1 - smoothing) * root_pos[t, :2] if t else cur
        out[t, :2] = cur
        out[t, 2] = height
    return out


def iter_frames(
    qpos_seq: np.ndarray,
    ref_qpos_seq: np.ndarray | None = None,
    group_colors: Mapping[int, Sequence[float]] | None = None,
    width: int = 640,
    height: int = 480,
    *,
    camera_distance: float = 3.5,
    camera_azimuth: float = 135.0,
    camera_elevation: float = -15.0,
    ghost_rgba: Sequence[float] = GHOST_RGBA,
    progress: bool = True,
    markers: Mapping[str, np.ndarray] | None = None,
    scenery: Sequence[Mapping[str, str]] = (),
    racket: bool = False,
) -> Iterator[np.ndarray]:
    """``render_frames`` one frame at a time (uint8 [H, W, 3] each), for long videos.
    ``markers``: name -> [T, 2, 3] task-goal segments to draw (``Task.markers``); ``scenery``:
    static geoms to add (ropes, piste lines); with it the camera follows the midpoint of the
    character and the ghost (a second player)."""
    qpos_seq = np.asarray(qpos_seq, np.float64)
    if qpos_seq.ndim != 2:
        raise ValueError(f"qpos_seq must be [T, nq], got shape {qpos_seq.shape}")
    if ref_qpos_seq is not None:
        ref_qpos_seq = np.asarray(ref_qpos_seq, np.float64)
        if ref_qpos_seq.shape != qpos_seq.shape:
            raise ValueError(f"ref_qpos_seq {ref_qpos_seq.shape} must match qpos_seq {qpos_seq.shape}")
    ss = _sword_shield_from_nq(qpos_seq.shape[1])
    track = qpos_seq[:, :3] if not scenery or ref_qpos_seq is None else 0.5 * (qpos_seq[:, :3] + ref_qpos_seq[:, :3])
    lookat = follow_lookat(track)
    from tqdm.auto import tqdm

    with SceneRenderer(ss, width, height, group_colors, ghost_rgba, scenery, racket) as sr:
        sr.camera.distance, sr.camera.azimuth, sr.camera.elevation = (camera_distance, camera_azimuth, camera_elevation)
        for t in tqdm(range(len(qpos_seq)), desc="render", unit="frame", disable=not progress, leave=False):
            mk = marker_list({name: seg[t] for name, seg in (markers or {}).items()})
            yield sr.render(qpos_seq[t], None if ref_qpos_seq is None else ref_qpos_seq[t], lookat[t], mk)


def render_frames(
    qpos_seq: np.ndarray,
    ref_qpos_seq: np.ndarray | None = None,
    group_colors: Mapping[int, Sequence[float]] | None = None,
    width: int = 640,
    height: int = 480,
    *,
    camera_distance: float = 3.5,
    camera_azimuth: float = 135.0,
    camera_elevation: float = -15.0,
    ghost_rgba: Sequence[float] = GHOST_RGBA,
    progress: bool = True,
) -> np.ndarray:
    """Renders a qpos sequence, optionally with the reference as a ghost.

    Args:
        qpos_seq: [T, nq] MuJoCo generalised positions of the simulated character (15- or
            17-body character, told apart by nq).
        ref_qpos_seq: None, or [T, nq] of the reference (already placed where it should appear).
        group_colors: link index -> RGBA for the simulated character's geoms (others grey).
        width, height: image size in pixels.
        camera_distance, camera_azimuth, camera_elevation: free camera (m, degrees, MuJoCo's
            convention: azimuth 135 / elevation -15 looks from the front-right, slightly above)
            whose target follows the simulated root's xy (smoothed) at 0.9 m height.
        ghost_rgba: colour of the ghost (alpha ~0.3).
        progress: show a tqdm bar.

    Returns:
        uint8 [T, H, W, 3].
    """
    frames = np.empty((len(qpos_seq), height, width, 3), np.uint8)
    for t, f in enumerate(
        iter_frames(
            qpos_seq,
            ref_qpos_seq,
            group_colors,
            width,
            height,
            camera_distance=camera_distance,
            camera_azimuth=camera_azimuth,
            camera_elevation=camera_elevation,
            ghost_rgba=ghost_rgba,
            progress=progress,
        )
    ):
        frames[t] = f
    return frames


def write_video(frames: np.ndarray | Iterable[np.ndarray], path: str | os.PathLike, fps: float = 30.0) -> Path:
    """Writes uint8 frames ([T, H, W, 3], or an iterable of [H, W, 3], consumed as it goes) as
    MP4 (H.264 via imageio-ffmpeg's bundled ffmpeg) or, for a ``.gif`` path, as GIF.

    Odd frame sizes are padded to even for H.264. Returns the path.
    """
    import imageio.v2 as imageio

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    if path.suffix.lower() == ".gif":
        imageio.mimsave(path, [np.asarray(f, np.uint8) for f in frames], duration=1000.0 / fps, loop=0)
        return path
    n = 0
    with (
        quiet_fork(),
        imageio.get_writer(
            path,
            fps=fps,
            codec="libx264",
            quality=7,
            pixelformat="yuv420p",
            macro_block_size=1,
            ffmpeg_log_level="error",
        ) as wr,
    ):
        for f in frames:
            f = np.asarray(f, np.uint8)
            h, w = f.shape[:2]
            if h % 2 or w % 2:
                f = np.pad(f, ((0, h % 2), (0, w % 2), (0, 0)), mode="edge")
            wr.append_data(f)
            n += 1
    if n == 0:
        raise ValueError(f"{path}: no frames to write")
    return path


# ---- the reference ghost -----------------------------------------------------------------------
# The alignment and the reference clip are eval's (one definition, so the ghost and the metrics agree).


def reference_qpos(learner, group: int, num_frames: int) -> np.ndarray:
    """[num_frames, nq] qpos of the group's first clip at the control rate, repeated (as
    ``envs.reference.reference_sequence``), in the clip's own world frame."""
    from jaxmotion.motion.motionlib import qpos_qvel

    return np.asarray(qpos_qvel(reference_state(learner, group, num_frames))[0], np.float64)


def aligned_reference_qpos(ref_qpos: np.ndarray, sim_qpos0: np.ndarray) -> np.ndarray:
    """Reference qpos [T, nq] moved rigidly (xy + yaw) onto the simulation's first root frame."""
    q, off = align_to_start(ref_qpos[:, :3], ref_qpos[:, 3:7], sim_qpos0[:3], sim_qpos0[3:7])
    out = np.array(ref_qpos, np.float64)
    out[:, :3], out[:, 3:7] = align_pose(q, off, ref_qpos[:, :3], ref_qpos[:, 3:7])
    return out


def render_rollout(
    learner,
    ro: Mapping[str, np.ndarray],
    path: str | os.PathLike,
    episode: int = 0,
    group: int = 0,
    width: int = 640,
    height: int = 480,
    fps: float | None = None,
    policies: Sequence[str] = (),
) -> Path:
    """Renders one episode of ``evaluation.rollout.rollout``'s output (alive frames only) with the ghost of
    ``group``'s reference clip (see the module docstring) and writes it to ``path``. ``policies``:
    names of the runs that took turns (``ro["acting"]`` indexes them); with two or more, a sphere
    over the head shows the acting one in its ``POLICY_COLORS`` colour (``policy_legend``)."""
    n = int(np.asarray(ro["alive"])[:, episode].sum())
    qpos = np.asarray(ro["qpos"])[:n, episode].astype(np.float64)
    ref = aligned_reference_qpos(reference_qpos(learner, group, n), qpos[0])
    markers = rollout_markers(learner, ro, episode, n, len(policies))
    frames = iter_frames(
        qpos, ref, learner_group_colors(learner), width, height, markers=markers, racket=learner.env.cfg.physics.racket
    )
    return write_video(frames, path, fps or 1.0 / learner.env.dt)
