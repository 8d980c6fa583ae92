// ShapeFlow Studio front end: three.js view of the session the server holds (protocol: studio/server.py).
import * as THREE from "three";
import { OrbitControls } from "/static/vendor/three/OrbitControls.js";

const $ = (id) => document.getElementById(id);
const view = $("view");
// a software renderer (SwiftShader, llvmpipe: no GPU) draws 2.2x faster without multisampling
const softwareGL = (() => {
  const gl = document.createElement("canvas").getContext("webgl2");
  const info = gl && gl.getExtension("WEBGL_debug_renderer_info");
  return info ? /swiftshader|llvmpipe|software/i.test(gl.getParameter(info.UNMASKED_RENDERER_WEBGL)) : false;
})();
const renderer = new THREE.WebGLRenderer({ antialias: !softwareGL });
renderer.setPixelRatio(window.devicePixelRatio);
view.appendChild(renderer.domElement);
const scene = new THREE.Scene();
scene.background = new THREE.Color(0x26272b);
const camera = new THREE.PerspectiveCamera(35, 1, 0.01, 1000);
const controls = new OrbitControls(camera, renderer.domElement);
scene.add(new THREE.HemisphereLight(0xffffff, 0x444455, 1.6));
const sun = new THREE.DirectionalLight(0xffffff, 1.4);
scene.add(sun);

const studio = { ready: false, lam: 0, version: 0, family: null, lams: [], frames: 0, error: null,
                 pending: 0 };
window.studio = studio;
// frames are drawn when something changed (positions, colours, the camera, the view's options),
// not continuously: an edit's answer is drawn at once instead of after the frame in progress, and
// an idle page leaves the processor to the solver.  ?continuous=1 draws every frame (benchmarks).
studio.continuous = new URLSearchParams(location.search).get("continuous") === "1";
let dirty = true;
const redraw = () => { dirty = true; };
studio.redraw = redraw;
studio.softwareGL = softwareGL;
// what the page shows, for tests and scripts: the positions and weights it holds
studio.positions = () => (geometry ? Array.from(geometry.getAttribute("position").array) : []);
studio.weightList = () => (studio.weights ? Array.from(studio.weights) : []);
studio.edgeCount = () => (edges ? edges.length / 2 : 0);
studio.cameraPosition = () => camera.position.toArray();

let n = 0, tris = null, edges = null, base = null, geometry = null, surface = null, wire = null, before = null;
const weightColour = (w, out, k) => {      // 0: blue, 1: warm white
  out[k] = 0.25 + 0.72 * w; out[k + 1] = 0.35 + 0.55 * w; out[k + 2] = 0.9 - 0.2 * w;
};

function dispose() {                      // a new mesh was opened: drop what showed the old one
  for (const o of [surface, wire, before]) {
    if (o) { scene.remove(o); o.geometry.dispose(); o.material.dispose(); }
  }
  surface = wire = before = geometry = null;
}

function build(positions) {
  dispose();
  geometry = new THREE.BufferGeometry();
  geometry.setAttribute("position", new THREE.BufferAttribute(positions, 3));
  geometry.setAttribute("color", new THREE.BufferAttribute(new Float32Array(n * 3).fill(1), 3));
  geometry.setIndex(new THREE.BufferAttribute(tris, 1));
  geometry.computeVertexNormals();
  surface = new THREE.Mesh(geometry, new THREE.MeshStandardMaterial({
    vertexColors: true, roughness: 0.6, metalness: 0.0, polygonOffset: true,
    polygonOffsetFactor: 1, polygonOffsetUnits: 1 }));
  scene.add(surface);
  const wg = new THREE.BufferGeometry();
  wg.setAttribute("position", geometry.getAttribute("position"));     // shared: one update moves both
  wg.setIndex(new THREE.BufferAttribute(edges, 1));
  wire = new THREE.LineSegments(wg, new THREE.LineBasicMaterial({ color: 0x111111, transparent: true,
                                                                 opacity: 0.35 }));
  wire.visible = $("wire").checked;
  scene.add(wire);
  surface.frustumCulled = wire.frustumCulled = false;   // always in view; their bounds change with every shape
  // the split view's "before": the input as opened, drawn left of the divider
  const bg = new THREE.BufferGeometry();
  bg.setAttribute("position", new THREE.BufferAttribute(base || new Float32Array(positions), 3));
  bg.setIndex(geometry.getIndex());
  bg.computeVertexNormals();
  before = new THREE.Mesh(bg, new THREE.MeshStandardMaterial({ color: 0xb8b4aa, roughness: 0.6 }));
  before.visible = false;
  scene.add(before);
  geometry.computeBoundingSphere();
  const s = geometry.boundingSphere;
  controls.target.copy(s.center);
  camera.position.copy(s.center).add(new THREE.Vector3(0.55, 0.35, 1).normalize().multiplyScalar(3.6 * s.radius));
  camera.near = s.radius / 100; camera.far = s.radius * 100; camera.updateProjectionMatrix();
  sun.position.copy(camera.position).add(new THREE.Vector3(s.radius, 2 * s.radius, 0));
  $("radius").min = (s.radius / 100).toFixed(4); $("radius").max = (s.radius / 2).toFixed(4);
  $("radius").step = (s.radius / 200).toFixed(5); $("radius").value = (s.radius / 10).toFixed(4);
  showRadius();
  redraw();
}

function setPositions(buf) {
  const p = new Float32Array(buf, 4);
  if (!geometry) { build(new Float32Array(p)); return; }
  const attr = geometry.getAttribute("position");
  attr.array.set(p); attr.needsUpdate = true;
  positionsChanged();
}
function positionsChanged() {
  geometry.computeVertexNormals(); boundsStale = true;   // the bounds only for picking: recomputed then
  studio.positionsAt = performance.now(); redraw();
  if (studio.editAt !== null) { studio.awaitingFrame = studio.editAt; studio.editAt = null; }
}
// latency of an edit: from the pointer event to the end of the first frame drawn with its answer
studio.editAt = null; studio.awaitingFrame = null; studio.latencies = [];

function setSomePositions(buf) {          // PSUB: uint32 k, k indices, k × 3 positions
  const k = new Uint32Array(buf, 4, 1)[0];
  const idx = new Uint32Array(buf, 8, k), p = new Float32Array(buf, 8 + 4 * k, 3 * k);
  const a = geometry.getAttribute("position");
  for (let j = 0; j < k; j++) { const i = 3 * idx[j]; a.array[i] = p[3 * j]; a.array[i + 1] = p[3 * j + 1]; a.array[i + 2] = p[3 * j + 2]; }
  a.needsUpdate = true;
  positionsChanged();
}

function setWeights(buf) {
  studio.weights = new Float32Array(buf, 4);
  paintColours();
}

const diverging = (t, out, k) => {        // t in [-1, 1]: blue, white, red (coolwarm's ends)
  const a = Math.min(1, Math.abs(t));
  const end = t < 0 ? [0.23, 0.3, 0.75] : [0.71, 0.02, 0.15];
  out[k] = 0.95 + (end[0] - 0.95) * a; out[k + 1] = 0.95 + (end[1] - 0.95) * a; out[k + 2] = 0.95 + (end[2] - 0.95) * a;
};

function paintColours() {
  if (!geometry || !studio.weights) return;
  const c = geometry.getAttribute("color"), mode = $("colours").value;
  const field = studio.field && studio.field.name === mode ? studio.field.values : null;
  let scale = 1;
  if (field) {              // a robust symmetric range: the 98th percentile of |value|, from the server
    scale = studio.field.scale || 1;
    $("legend-lo").textContent = (-scale).toPrecision(3); $("legend-hi").textContent = scale.toPrecision(3);
  }
  $("legend").style.display = field ? "block" : "none";
  for (let i = 0; i < n; i++) {
    if (mode === "weights") weightColour(studio.weights[i], c.array, 3 * i);
    else if (field) diverging(field[i] / scale, c.array, 3 * i);
    else { c.array[3 * i] = 0.82; c.array[3 * i + 1] = 0.8; c.array[3 * i + 2] = 0.76; }
  }
  c.needsUpdate = true; redraw();
}
const fieldMode = () => { const m = $("colours").value; return m === "curvature" || m === "displacement" ? m : null; };
function requestField() {                  // of the shape shown: the slider's preview when it is off 0
  const mode = fieldMode();
  if (mode) send({ op: "field", name: mode, lam: studio.lam !== 0 ? studio.lam : null });
  else paintColours();
}

// --- the server connection -------------------------------------------------
// the token this page was opened with (?token=…): every request that changes something carries it
const token = new URLSearchParams(location.search).get("token") || "";
const authed = { "X-Shapeflow-Token": token };
const ws = new WebSocket(`ws://${location.host}/ws?token=${encodeURIComponent(token)}`);
ws.binaryType = "arraybuffer";
const send = (msg) => { studio.pending++; ws.send(JSON.stringify(msg)); };
studio.send = send;
function receive(ev) {
  if (typeof ev.data === "string") {
    const m = JSON.parse(ev.data);
    waiting = false;                     // an answer: the brush may send its next dab
    if (m.type === "state" || m.type === "error") studio.lamAnswered(m);
    if (m.type === "mesh") { n = m.n_vertices; dispose(); studio.ready = false; studio.field = null; studio.pending = 0;
                             studio.name = m.name; formats(m.formats || []);
                             studio.lam = 0; $("lam").value = 0; $("lam-value").textContent = 0; }
    else if (m.type === "state") {
      const changed = m.version !== studio.version;
      state(m); studio.pending = m.resync ? 0 : Math.max(0, studio.pending - 1);
      if (changed && $("colours").value !== "weights" && $("colours").value !== "none") requestField();
    }
    else if (m.type === "field") {
      studio.field = { name: m.name, version: m.version, lam: m.lam, scale: m.scale, values: studio.fieldValues };
      paintColours();
    }
    else if (m.type === "error") {
      studio.error = m.message; $("error").textContent = m.message; studio.pending = Math.max(0, studio.pending - 1);
    }
    return;
  }
  const tag = new TextDecoder().decode(new Uint8Array(ev.data, 0, 4));
  if (tag === "TRI0") tris = new Uint32Array(ev.data.slice(4));
  else if (tag === "EDG0") edges = new Uint32Array(ev.data.slice(4));
  else if (tag === "BAS0") base = new Float32Array(ev.data.slice(4));
  else if (tag === "POS0") setPositions(ev.data);
  else if (tag === "PSUB") setSomePositions(ev.data);
  else if (tag === "WGT0") setWeights(ev.data);
  else if (tag === "FLD0") studio.fieldValues = new Float32Array(ev.data.slice(4));
}
ws.onclose = () => { $("status").textContent = "disconnected: restart shapeflow studio and reload"; };

function state(m) {
  studio.version = m.version; studio.family = m.family; studio.lams = m.lams; studio.options = m.options;
  if (m.lams && m.lams.length) {
    $("lam").min = Math.min(...m.lams); $("lam").max = Math.max(...m.lams);
  }
  const f = m.family;
  const fam = f.state === "running" ? `solving the family: ${f.done}/${f.total}` :
              f.state === "done" ? `family of ${f.total} shapes ready` :
              f.state === "failed" ? `family failed: ${f.error}` : "";
  $("progress").value = f.total ? f.done / f.total : 0;
  $("progress").style.visibility = f.state === "running" ? "visible" : "hidden";
  $("status").textContent = `${studio.name ? studio.name + ": " : ""}${n.toLocaleString()} vertices\n${fam}`;
  $("undo").disabled = !m.can_undo; $("redo").disabled = !m.can_redo;
  studio.ready = geometry !== null;
}

// --- controls ----------------------------------------------------------------
// at most two λ requests in flight (the server works on the next shape while the page takes in
// the last one), the latest slider value queued: dragging faster than the answers shows the
// newest shape as soon as it can instead of a growing backlog
const lamSent = [];
let lamQueued = false;
function sendLam() {
  lamSent.push(studio.lam); lamQueued = false;
  send({ op: "lam", value: studio.lam, field: fieldMode() });   // the colours follow the preview
}
studio.lamAnswered = (m) => {
  const k = m.type === "error" ? 0 : lamSent.indexOf(m.lam);
  if (k < 0 || !lamSent.length) return;
  lamSent.splice(k, 1);
  if (lamQueued) sendLam();
};
$("lam").addEventListener("input", () => {
  studio.lam = Number($("lam").value);
  $("lam-value").textContent = studio.lam;
  if (lamSent.length < 2) sendLam(); else lamQueued = true;
});
$("apply").onclick = () => send({ op: "apply", value: Number($("lam").value) });
$("undo").onclick = () => send({ op: "undo" });
$("redo").onclick = () => send({ op: "redo" });
$("wire").onchange = () => { if (wire) wire.visible = $("wire").checked; redraw(); };
controls.addEventListener("change", redraw);
$("turntable").onchange = () => { controls.autoRotate = $("turntable").checked; };
controls.autoRotateSpeed = 4.0;                 // one turn in 15 s
// the family's options: any change solves the family again
const familyOptions = () => ({ op: "options", lam_border: Number($("lam-border").value),
  iterations: Number($("iterations").value), normalized: !$("area").checked,
  preserve_volume: $("volume").checked, compat: $("compat").value });
for (const id of ["lam-border", "iterations", "area", "volume", "compat"]) $(id).onchange = () => send(familyOptions());

// --- opening files: the dialog, drag and drop, weights ---------------------
async function upload(route, file) {
  $("error").textContent = ""; studio.error = null;
  $("status").textContent = `opening ${file.name}…`;
  studio.uploading = (studio.uploading || 0) + 1;
  try {
    const r = await fetch(`/${route}?name=${encodeURIComponent(file.name)}`, { method: "POST", body: file, headers: authed });
    if (!r.ok) { studio.error = await r.text(); $("error").textContent = studio.error; }
  } catch (err) {
    studio.error = `${file.name}: the upload failed (${err.message})`; $("error").textContent = studio.error;
  } finally { studio.uploading--; }
}
studio.upload = upload;
$("open").onclick = () => $("open-file").click();
$("open-file").onchange = () => { const f = $("open-file").files[0]; if (f) upload("open", f); $("open-file").value = ""; };
$("load-weights").onclick = () => $("weights-file").click();
$("weights-file").onchange = () => { const f = $("weights-file").files[0]; if (f) upload("weights", f); $("weights-file").value = ""; };
window.addEventListener("dragover", (e) => { e.preventDefault(); document.body.classList.add("dropping"); });
window.addEventListener("dragleave", () => document.body.classList.remove("dropping"));
window.addEventListener("drop", (e) => {
  e.preventDefault(); document.body.classList.remove("dropping");
  const f = e.dataTransfer.files[0];
  if (f) upload(/\.(npy|txt)$/i.test(f.name) ? "weights" : "open", f);
});

// --- the split view: the input left of the divider, the current shape right of it ---
studio.split = 0.5;
const divider = $("divider");
$("split").onchange = () => { divider.style.display = $("split").checked ? "block" : "none"; placeDivider(); };
function placeDivider() { divider.style.left = `${100 * studio.split}%`; redraw(); }
divider.addEventListener("pointerdown", (e) => {
  divider.setPointerCapture(e.pointerId);
  const move = (ev) => {
    const r = view.getBoundingClientRect();
    studio.split = Math.min(0.95, Math.max(0.05, (ev.clientX - r.left) / r.width)); placeDivider();
  };
  divider.addEventListener("pointermove", move);
  divider.addEventListener("pointerup", () => divider.removeEventListener("pointermove", move), { once: true });
});
$("colours").onchange = requestField;
const showRadius = () => { $("radius-value").textContent = Number($("radius").value).toPrecision(3); };
$("radius").addEventListener("input", showRadius);
$("brush-lam").addEventListener("input", () => { $("brush-lam-value").textContent = $("brush-lam").value; });
function formats(exts) {              // what the server reads and writes: the download list, the dialog's filter
  const sel = $("format"), keep = sel.value;
  if (sel.options.length !== exts.length) {
    sel.replaceChildren(...exts.map((e) => new Option(e, e)));
    if (exts.includes(keep)) sel.value = keep;
  }
  $("open-file").accept = exts.map((e) => "." + e).join(",");
}
$("download").onclick = async () => {
  const name = `${(studio.name || "shapeflow-studio").replace(/\.[^.]*$/, "")}-studio.${$("format").value}`;
  const r = await fetch(`/download/${encodeURIComponent(name)}`, { headers: authed });
  if (!r.ok) { studio.error = await r.text(); $("error").textContent = studio.error; return; }
  const a = document.createElement("a");
  a.href = URL.createObjectURL(await r.blob()); a.download = name; a.click();
  setTimeout(() => URL.revokeObjectURL(a.href), 10000);
};
window.addEventListener("keydown", (e) => {            // [ and ] change the radius, as in Blender
  const r = $("radius");
  if (e.key === "[") r.value = Number(r.value) / 1.15;
  if (e.key === "]") r.value = Number(r.value) * 1.15;
  showRadius();
});

// --- painting and sculpting on the surface ---------------------------------
const raycaster = new THREE.Raycaster();
const pointer = new THREE.Vector2();
let stroking = false, waiting = false;
let boundsStale = false;
function pick() {                          // the surface under the ray (its bounds brought up to date first)
  if (boundsStale) { geometry.computeBoundingSphere(); boundsStale = false; }
  return raycaster.intersectObject(surface, false);
}
function hit(e) {
  const r = renderer.domElement.getBoundingClientRect();
  pointer.set(((e.clientX - r.left) / r.width) * 2 - 1, -((e.clientY - r.top) / r.height) * 2 + 1);
  raycaster.setFromCamera(pointer, camera);
  const h = surface ? pick() : [];
  return h.length ? h[0].point : null;
}
function edit(e) {
  const mode = $("mode").value;
  if (mode === "view" || waiting) return;
  const p = hit(e);
  if (!p) return;
  const center = [p.x, p.y, p.z], radius = Number($("radius").value);
  waiting = true;
  studio.editAt = e.timeStamp;
  const invert = e.ctrlKey;
  if (mode === "paint" || mode === "erase") {
    send({ op: "paint", center, radius, value: (mode === "paint") !== invert ? 1.0 : 0.0, strength: 0.5 });
  } else {
    const lam = Number($("brush-lam").value) * (invert ? -1 : 1);
    send({ op: "dab", center, radius, lam, inflate: mode === "inflate" });
  }
  studio.edits = (studio.edits || 0) + 1;
}
renderer.domElement.addEventListener("pointerdown", (e) => {
  if ($("mode").value === "view" || !hit(e)) return;
  stroking = true; controls.enabled = false; edit(e);
});
// the brush circle: a ring on the surface under the pointer, its radius the brush's
const ring = new THREE.Mesh(new THREE.RingGeometry(0.94, 1.0, 64),
                            new THREE.MeshBasicMaterial({ color: 0xffcc44, side: THREE.DoubleSide, depthTest: false }));
ring.visible = false;
ring.renderOrder = 2;
scene.add(ring);
function moveRing(e) {
  const on = $("mode").value !== "view" && surface;
  const r = renderer.domElement.getBoundingClientRect();
  pointer.set(((e.clientX - r.left) / r.width) * 2 - 1, -((e.clientY - r.top) / r.height) * 2 + 1);
  raycaster.setFromCamera(pointer, camera);
  const h = on ? pick() : [];
  const was = ring.visible;
  ring.visible = h.length > 0;
  if (!ring.visible) { if (was) redraw(); return; }
  const normal = h[0].face.normal.clone().transformDirection(surface.matrixWorld);
  ring.position.copy(h[0].point);
  ring.quaternion.setFromUnitVectors(new THREE.Vector3(0, 0, 1), normal);
  ring.scale.setScalar(Number($("radius").value));
  studio.ring = { visible: true, center: ring.position.toArray() };
  // during a stroke the frame with the edit's answer shows the circle where it now is: a frame for
  // the circle alone would only hold that answer back (a software renderer takes ~100 ms a frame)
  if (!(stroking && waiting)) redraw();
}
renderer.domElement.addEventListener("pointermove", (e) => { if (stroking) edit(e); moveRing(e); });
renderer.domElement.addEventListener("pointerleave", () => { ring.visible = false; redraw(); });
window.addEventListener("pointerup", () => { stroking = false; controls.enabled = true; });
studio.work = { ms: 0, messages: 0 };        // time the page spends on messages (not drawing)
ws.onmessage = (ev) => {
  const t0 = performance.now();
  receive(ev);
  studio.work.ms += performance.now() - t0; studio.work.messages++;
};

// --- drawing -------------------------------------------------------------------
function resize() {
  const w = view.clientWidth, h = view.clientHeight;
  renderer.setSize(w, h, false); renderer.domElement.style.width = w + "px";
  renderer.domElement.style.height = h + "px"; camera.aspect = w / h; camera.updateProjectionMatrix();
  redraw();
}
window.addEventListener("resize", resize);
resize();
function draw() {
  if (!$("split").checked || !before) { renderer.render(scene, camera); return; }
  const w = view.clientWidth, h = view.clientHeight, x = Math.round(studio.split * w);
  renderer.setScissorTest(true);
  surface.visible = false; wire.visible = false; before.visible = true;      // before: the input
  renderer.setScissor(0, 0, x, h); renderer.setViewport(0, 0, w, h); renderer.render(scene, camera);
  surface.visible = true; wire.visible = $("wire").checked; before.visible = false;
  renderer.setScissor(x, 0, w - x, h); renderer.render(scene, camera);
  renderer.setScissorTest(false);
}
renderer.setAnimationLoop(() => {
  controls.update();                  // turntable and damping: moves the camera, which asks for a frame
  if (!dirty && !studio.continuous) return;
  dirty = false; draw(); studio.frames++;
  if (studio.awaitingFrame !== null) {
    renderer.getContext().finish();                 // the frame is drawn, not just queued
    studio.latencies.push(performance.now() - studio.awaitingFrame); studio.awaitingFrame = null;
  }
});
