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
from typing import Mapping, Sequence

import numpy as np

ASSETS = Path(__file__).with_name("assets")
THREE_JS = ASSETS / "three.min.js"

_GEOM_TYPES = {2: "sphere", 3: "capsule", 5: "cylinder", 6: "box"}  # mjtGeom values


def character_geoms(sword_shield: bool = False,
                    group_colors: Mapping[int, Sequence[float]] | None = None,
                    default_rgba: Sequence[float] = (0.7, 0.7, 0.7, 1.0), racket: bool = False) -> list[dict]:
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
        out.append({"body": b - 1, "type": typ, "size": [round(float(x), 6) for x in m.geom_size[g]],
                    "pos": [round(float(x), 6) for x in m.geom_pos[g]],
                    "quat": [round(float(x), 6) for x in m.geom_quat[g]],
                    "rgba": [float(x) for x in colors.get(b - 1, default_rgba)]})
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


def write_html(path: str | os.PathLike, body_names: Sequence[str], parents: Sequence[int],
               sim_pos: np.ndarray, sim_quat: np.ndarray, ref_pos: np.ndarray | None,
               ref_quat: np.ndarray | None, fps: float, geoms: Sequence[Mapping],
               *, title: str = "jaxmotion replay",
               legend: Mapping[str, Sequence[float]] | None = None, markers: Sequence[Mapping] = (),
               acting: np.ndarray | None = None,
               policies: Sequence[tuple[str, Sequence[float]]] = ()) -> Path:
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
        marks.append({"name": str(m["name"]), "rgba": [float(x) for x in m["rgba"]],
                      "radius": float(m["radius"]), "seg": _b64(seg)})
    if acting is not None:
        acting = np.asarray(acting).astype(int).tolist()
        if len(acting) != T or not all(0 <= a < len(policies) for a in acting):
            raise ValueError(f"acting must be [{T}] indices into {len(policies)} policies")
    data = {
        "title": title, "fps": float(fps), "T": int(T), "nb": nb,
        "bodyNames": list(body_names), "parents": [int(p) for p in parents],
        "geoms": [dict(g) for g in geoms], "legend": {k: list(map(float, v)) for k, v in (legend or {}).items()},
        "simPos": _b64(sp), "simQuat": _b64(sq), "refPos": None, "refQuat": None, "markers": marks,
        "acting": acting, "policies": [{"name": str(n), "rgba": [float(x) for x in c]} for n, c in policies],
    }
    if ref_pos is not None:
        data["refPos"] = _b64(_check("ref_pos", ref_pos, (nb, 3), T))
        data["refQuat"] = _b64(_check("ref_quat", ref_quat, (nb, 4), T))
    three = THREE_JS.read_text(encoding="utf-8")
    if "</script" in three.lower():
        raise RuntimeError(f"{THREE_JS} contains '</script' and cannot be inlined")
    payload = json.dumps(data, separators=(",", ":")).replace("</", "<\\/")
    page = (_TEMPLATE.replace("@@TITLE@@", html.escape(title))
            .replace("@@DATA@@", payload)
            .replace("@@APP@@", _APP_JS)
            .replace("@@THREE@@", three))
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(page, encoding="utf-8")
    return path


_TEMPLATE = """<!DOCTYPE html>
<html lang="en">
<head>
<meta charset="utf-8">
<title>@@TITLE@@</title>
<meta name="viewport" content="width=device-width, initial-scale=1">
<style>
  html, body { margin: 0; height: 100%; overflow: hidden; background: #1d2430;
               font: 13px system-ui, sans-serif; color: #dde; }
  #view { position: absolute; inset: 0; }
  #ui { position: absolute; left: 0; right: 0; bottom: 0; padding: 6px 10px;
        background: rgba(10, 14, 20, 0.72); display: flex; gap: 10px; align-items: center; }
  #ui input[type=range] { flex: 1; }
  #ui button { min-width: 64px; }
  #title { position: absolute; left: 10px; top: 8px; font-weight: 600; }
  #legend { position: absolute; right: 10px; top: 8px; }
  #legend span.sw { display: inline-block; width: 10px; height: 10px; margin: 0 4px 0 10px;
                    border-radius: 2px; }
  #acting { position: absolute; left: 10px; top: 30px; font-weight: 600; }
  #acting span.sw { display: inline-block; width: 12px; height: 12px; margin-right: 6px;
                    border-radius: 6px; vertical-align: -1px; }
  #msg { position: absolute; left: 10px; top: 52px; color: #f99; }
  #help { position: absolute; left: 10px; bottom: 40px; opacity: 0.6; font-size: 11px; }
</style>
</head>
<body>
<div id="view"></div>
<div id="title"></div>
<div id="legend"></div>
<div id="acting"></div>
<div id="msg"></div>
<div id="help">drag: rotate &middot; right-drag / shift-drag: pan &middot; wheel: zoom &middot; space: play/pause</div>
<div id="ui">
  <button id="play">Pause</button>
  <input id="slider" type="range" min="0" max="0" value="0" step="1">
  <span id="label">0</span>
  <label>speed <select id="speed">
    <option value="0.1">0.1&times;</option><option value="0.25">0.25&times;</option>
    <option value="0.5">0.5&times;</option><option value="1" selected>1&times;</option>
    <option value="2">2&times;</option></select></label>
  <label><input id="ghost" type="checkbox" checked> reference ghost</label>
  <label><input id="follow" type="checkbox" checked> follow</label>
</div>
<script type="application/json" id="replay-data">@@DATA@@</script>
<script>
@@THREE@@
</script>
<script>
@@APP@@
</script>
</body>
</html>
"""

_APP_JS = r"""
(function () {
  "use strict";
  const D = JSON.parse(document.getElementById("replay-data").textContent);
  const msg = (s) => { document.getElementById("msg").textContent = s; };
  document.getElementById("title").textContent = D.title;
  const leg = document.getElementById("legend");
  for (const [name, c] of Object.entries(D.legend)) {
    const sw = document.createElement("span");
    sw.className = "sw";
    sw.style.background = `rgb(${c[0] * 255},${c[1] * 255},${c[2] * 255})`;
    leg.appendChild(sw);
    leg.appendChild(document.createTextNode(name));
  }
  const f32 = (s) => {
    if (!s) return null;
    const bin = atob(s), u8 = new Uint8Array(bin.length);
    for (let i = 0; i < bin.length; i++) u8[i] = bin.charCodeAt(i);
    return new Float32Array(u8.buffer);
  };
  const simPos = f32(D.simPos), simQuat = f32(D.simQuat);
  const refPos = f32(D.refPos), refQuat = f32(D.refQuat);
  const T = D.T, NB = D.nb;

  let renderer;
  try {
    renderer = new THREE.WebGLRenderer({antialias: true});
  } catch (e) {
    msg("WebGL is not available in this browser: " + e.message);
    window.__replay = {ready: false, error: String(e)};
    return;
  }
  const view = document.getElementById("view");
  renderer.setPixelRatio(window.devicePixelRatio || 1);
  renderer.shadowMap.enabled = true;
  view.appendChild(renderer.domElement);

  const scene = new THREE.Scene();
  scene.background = new THREE.Color(0x1d2430);
  const camera = new THREE.PerspectiveCamera(45, 1, 0.02, 200);
  camera.up.set(0, 0, 1);  // MuJoCo world: z up

  scene.add(new THREE.HemisphereLight(0xdde6ff, 0x303030, 1.6));
  const sun = new THREE.DirectionalLight(0xffffff, 2.0);
  sun.castShadow = true;
  sun.shadow.mapSize.set(1024, 1024);
  Object.assign(sun.shadow.camera, {left: -3, right: 3, top: 3, bottom: -3, near: 0.1, far: 20});
  scene.add(sun, sun.target);

  // Floor: a 200 m plane in the xy plane with a 1 m grid drawn into a repeating texture (a
  // texture rather than GridHelper lines: software WebGL drops lines that cross the near plane).
  const cv = document.createElement("canvas");
  cv.width = cv.height = 256;
  const cx = cv.getContext("2d");
  cx.fillStyle = "#2b3546"; cx.fillRect(0, 0, 256, 256);
  cx.fillStyle = "#323d50"; cx.fillRect(0, 0, 128, 128); cx.fillRect(128, 128, 128, 128);
  cx.strokeStyle = "#7f93b3"; cx.lineWidth = 4;
  cx.strokeRect(0, 0, 256, 256); cx.beginPath();
  cx.moveTo(128, 0); cx.lineTo(128, 256); cx.moveTo(0, 128); cx.lineTo(256, 128); cx.stroke();
  const tex = new THREE.CanvasTexture(cv);
  tex.wrapS = tex.wrapT = THREE.RepeatWrapping;
  tex.repeat.set(100, 100);  // 2 m per texture tile = 1 m cells
  tex.anisotropy = renderer.capabilities.getMaxAnisotropy();
  tex.colorSpace = THREE.SRGBColorSpace;
  const floor = new THREE.Mesh(new THREE.PlaneGeometry(200, 200),
                               new THREE.MeshStandardMaterial({map: tex, roughness: 1}));
  floor.receiveShadow = true;
  scene.add(floor);

  // Characters: one Group per link, its geoms as children in the body frame.
  const up = new THREE.Vector3(0, 1, 0);
  function geomMesh(g, material) {
    let geo;
    const s = g.size;
    if (g.type === "sphere") geo = new THREE.SphereGeometry(s[0], 20, 14);
    else if (g.type === "capsule") geo = new THREE.CapsuleGeometry(s[0], 2 * s[1], 6, 16);
    else if (g.type === "cylinder") geo = new THREE.CylinderGeometry(s[0], s[0], 2 * s[1], 24);
    else if (g.type === "box") geo = new THREE.BoxGeometry(2 * s[0], 2 * s[1], 2 * s[2]);
    else return null;
    if (g.type === "capsule" || g.type === "cylinder") geo.rotateX(Math.PI / 2);  // y axis -> z
    const m = new THREE.Mesh(geo, material);
    m.position.set(g.pos[0], g.pos[1], g.pos[2]);
    m.quaternion.set(g.quat[1], g.quat[2], g.quat[3], g.quat[0]);
    return m;
  }
  function makeCharacter(ghost) {
    const root = new THREE.Group();
    const links = [];
    for (let b = 0; b < NB; b++) { const l = new THREE.Group(); links.push(l); root.add(l); }
    for (const g of D.geoms) {
      const c = ghost ? [0.85, 0.9, 1.0, 0.3] : g.rgba;
      const mat = new THREE.MeshStandardMaterial({
        color: new THREE.Color(c[0], c[1], c[2]), roughness: 0.6, metalness: 0.0,
        transparent: ghost || c[3] < 1, opacity: c[3], depthWrite: !ghost});
      const m = geomMesh(g, mat);
      if (!m) continue;
      m.castShadow = !ghost;
      links[g.body].add(m);
    }
    scene.add(root);
    return {root, links};
  }
  const sim = makeCharacter(false);
  const ref = refPos ? makeCharacter(true) : null;
  if (ref) ref.root.renderOrder = 1;

  // Task markers and the acting policy's sphere, as render.py's video: a zero-length segment is
  // a sphere, any other an arrow (shaft + cone built along +y, turned onto the segment); a
  // non-finite one is hidden on that frame.
  const markers = D.markers.map((m) => {
    const c = m.rgba;
    const mat = new THREE.MeshStandardMaterial({color: new THREE.Color(c[0], c[1], c[2]), roughness: 0.5,
                                                transparent: c[3] < 1, opacity: c[3]});
    const ball = new THREE.Mesh(new THREE.SphereGeometry(m.radius, 20, 14), mat);
    const shaft = new THREE.Mesh(new THREE.CylinderGeometry(0.02, 0.02, 1, 12), mat);
    const tip = new THREE.Mesh(new THREE.ConeGeometry(0.04, 1, 16), mat);
    const arrow = new THREE.Group();
    arrow.add(shaft, tip);
    scene.add(ball, arrow);
    return {name: m.name, seg: f32(m.seg), ball, arrow, shaft, tip};
  });
  const segA = new THREE.Vector3(), segD = new THREE.Vector3();
  function showMarkers(f) {
    for (const m of markers) {
      const S = m.seg, i = f * 6;
      segA.set(S[i], S[i + 1], S[i + 2]);
      segD.set(S[i + 3] - S[i], S[i + 4] - S[i + 1], S[i + 5] - S[i + 2]);
      const len = segD.length();
      const shown = Number.isFinite(len) && Number.isFinite(segA.lengthSq());
      m.ball.visible = shown && len < 1e-6;
      m.arrow.visible = shown && len >= 1e-6;
      if (m.ball.visible) m.ball.position.copy(segA);
      if (m.arrow.visible) {
        const h = Math.min(0.1, 0.5 * len);  // the cone's length
        m.arrow.position.copy(segA);
        m.arrow.quaternion.setFromUnitVectors(up, segD.divideScalar(len));
        m.shaft.scale.set(1, len - h, 1); m.shaft.position.set(0, (len - h) / 2, 0);
        m.tip.scale.set(1, h, 1); m.tip.position.set(0, len - h / 2, 0);
      }
    }
  }
  // Policy switching: the acting run's name and colour, per frame.
  const actingDiv = document.getElementById("acting");
  let actingShown = -1;
  function showActing(f) {
    if (!D.acting || D.policies.length < 2 || D.acting[f] === actingShown) return;
    actingShown = D.acting[f];
    const p = D.policies[actingShown], c = p.rgba;
    actingDiv.textContent = "";
    const sw = document.createElement("span");
    sw.className = "sw";
    sw.style.background = `rgb(${c[0] * 255},${c[1] * 255},${c[2] * 255})`;
    actingDiv.appendChild(sw);
    actingDiv.appendChild(document.createTextNode(`acting: ${p.name}`));
  }

  function pose(ch, P, Q, f) {
    for (let b = 0; b < NB; b++) {
      const i3 = (f * NB + b) * 3, i4 = (f * NB + b) * 4;
      ch.links[b].position.set(P[i3], P[i3 + 1], P[i3 + 2]);
      ch.links[b].quaternion.set(Q[i4 + 1], Q[i4 + 2], Q[i4 + 3], Q[i4]);
    }
  }

  // A small orbit camera around a target, z up.
  // Initial view as render.py's video: from the front-right, 15 degrees above the horizon.
  const orbit = {target: new THREE.Vector3(simPos[0], simPos[1], 0.9), dist: 4.0,
                 az: -Math.PI / 4, el: 0.26};
  function placeCamera() {
    const ce = Math.cos(orbit.el);
    camera.position.set(orbit.target.x + orbit.dist * ce * Math.cos(orbit.az),
                        orbit.target.y + orbit.dist * ce * Math.sin(orbit.az),
                        orbit.target.z + orbit.dist * Math.sin(orbit.el));
    camera.lookAt(orbit.target);
    sun.position.set(orbit.target.x + 2, orbit.target.y - 1, orbit.target.z + 5);
    sun.target.position.copy(orbit.target);
  }
  let drag = null;
  const el = renderer.domElement;
  el.addEventListener("contextmenu", (e) => e.preventDefault());
  el.addEventListener("pointerdown", (e) => {
    drag = {x: e.clientX, y: e.clientY, pan: e.button !== 0 || e.shiftKey};
    el.setPointerCapture(e.pointerId);
  });
  el.addEventListener("pointerup", (e) => { drag = null; el.releasePointerCapture(e.pointerId); });
  el.addEventListener("pointermove", (e) => {
    if (!drag) return;
    const dx = e.clientX - drag.x, dy = e.clientY - drag.y;
    drag.x = e.clientX; drag.y = e.clientY;
    if (drag.pan) {
      const k = orbit.dist * 0.0015;
      const right = new THREE.Vector3().setFromMatrixColumn(camera.matrixWorld, 0);
      const camUp = new THREE.Vector3().setFromMatrixColumn(camera.matrixWorld, 1);
      orbit.target.addScaledVector(right, -dx * k).addScaledVector(camUp, dy * k);
      followBox.checked = false;
    } else {
      orbit.az -= dx * 0.008;
      orbit.el = Math.min(1.5, Math.max(-0.2, orbit.el + dy * 0.008));
    }
  });
  el.addEventListener("wheel", (e) => {
    e.preventDefault();
    orbit.dist = Math.min(60, Math.max(0.5, orbit.dist * Math.exp(e.deltaY * 0.001)));
  }, {passive: false});

  // Controls.
  const playBtn = document.getElementById("play"), slider = document.getElementById("slider");
  const label = document.getElementById("label"), speedSel = document.getElementById("speed");
  const ghostBox = document.getElementById("ghost"), followBox = document.getElementById("follow");
  slider.max = String(T - 1);
  if (!ref) { ghostBox.checked = false; ghostBox.disabled = true; }
  let playing = true, t = 0, frame = 0;
  const setPlaying = (p) => { playing = p; playBtn.textContent = p ? "Pause" : "Play"; };
  playBtn.onclick = () => setPlaying(!playing);
  window.addEventListener("keydown", (e) => {
    if (e.code === "Space") { e.preventDefault(); setPlaying(!playing); }
  });
  slider.oninput = () => { setPlaying(false); t = Number(slider.value) / D.fps; };

  function resize() {
    const w = view.clientWidth || window.innerWidth, h = view.clientHeight || window.innerHeight;
    renderer.setSize(w, h, false);
    renderer.domElement.style.width = "100%";
    renderer.domElement.style.height = "100%";
    camera.aspect = w / Math.max(h, 1);
    camera.updateProjectionMatrix();
  }
  window.addEventListener("resize", resize);
  resize();

  function show(f) {
    frame = f;
    pose(sim, simPos, simQuat, f);
    if (ref) { pose(ref, refPos, refQuat, f); ref.root.visible = ghostBox.checked; }
    showMarkers(f);
    showActing(f);
    if (followBox.checked) {
      const i = f * NB * 3, k = 0.15;
      orbit.target.x += k * (simPos[i] - orbit.target.x);
      orbit.target.y += k * (simPos[i + 1] - orbit.target.y);
    }
    slider.value = String(f);
    label.textContent = `${f} / ${T - 1}  (${(f / D.fps).toFixed(2)} s)`;
    placeCamera();
    renderer.render(scene, camera);
  }
  let last = performance.now();
  function loop(now) {
    const dt = Math.min(0.1, Math.max(0, (now - last) / 1000));  // rAF time may precede `last`
    last = now;
    if (playing) t = (t + dt * Number(speedSel.value)) % (T / D.fps);
    show(Math.max(0, Math.min(T - 1, Math.floor(t * D.fps + 1e-6))));
    requestAnimationFrame(loop);
  }
  show(0);
  window.__replay = {ready: true, frames: T,
                     setFrame: (f) => { setPlaying(false); t = f / D.fps; show(f); },
                     setPlaying, three: {scene, camera, renderer},
                     acting: () => actingDiv.textContent, markers};
  requestAnimationFrame(loop);
})();
"""


def write_rollout_html(learner, ro: Mapping[str, np.ndarray], path: str | os.PathLike,
                       episode: int = 0, group: int = 0, title: str | None = None,
                       policies: Sequence[str] = ()) -> Path:
    """The replay page of one episode of ``eval.rollout``'s output (alive frames only), with
    ``group``'s reference clip as the ghost (``eval.reference_sequence``, moved rigidly in xy +
    yaw onto the simulation's first root frame as ``eval.world_aligned`` does) and the task's
    markers. ``policies``: names of the runs that took turns (``ro["acting"]`` indexes them); with
    two or more, the page names the acting one per frame and draws the video's sphere over the
    head in its colour."""
    from jaxmotion.envs.reference import reference_sequence
    from jaxmotion.viz.render import (GROUP_PALETTE, align_pose, align_to_start, learner_group_colors, marker_style,
                                  policy_rgba, rollout_markers)
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
    markers = [{"name": k, "seg": v, "rgba": marker_style(k)[0], "radius": marker_style(k)[1]}
               for k, v in rollout_markers(learner, ro, episode, n, len(policies)).items()]
    switched = len(policies) > 1 and ro.get("acting") is not None
    return write_html(path, ch.body_names, ch.parents, sp, sq, rp, rq, 1.0 / learner.env.dt,
                      character_geoms(ch.sword_shield, colors, racket=learner.env.cfg.physics.racket),
                      title=title or f"jaxmotion replay (ghost: {ref_name} reference)", legend=legend,
                      markers=markers, acting=np.asarray(ro["acting"])[:n, episode] if switched else None,
                      policies=[(name, policy_rgba(i)) for i, name in enumerate(policies)] if switched else ())
