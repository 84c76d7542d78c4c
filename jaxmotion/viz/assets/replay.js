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
