// ShapeFlow Studio front end: three.js view of the session the server holds (protocol: studio/server.py).
import * as THREE from "three";
import { OrbitControls } from "/static/vendor/three/OrbitControls.js";

const $ = (id) => document.getElementById(id);
const view = $("view");
const renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
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
// what the page shows, for tests and scripts: the positions and weights it holds
studio.positions = () => (geometry ? Array.from(geometry.getAttribute("position").array) : []);
studio.weightList = () => (studio.weights ? Array.from(studio.weights) : []);

let n = 0, tris = null, edges = null, geometry = null, surface = null, wire = null;
const weightColour = (w, out, k) => {      // 0: blue, 1: warm white
  out[k] = 0.25 + 0.72 * w; out[k + 1] = 0.35 + 0.55 * w; out[k + 2] = 0.9 - 0.2 * w;
};

function build(positions) {
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
  geometry.computeBoundingSphere();
  const s = geometry.boundingSphere;
  controls.target.copy(s.center);
  camera.position.copy(s.center).add(new THREE.Vector3(0.55, 0.35, 1).normalize().multiplyScalar(3.6 * s.radius));
  camera.near = s.radius / 100; camera.far = s.radius * 100; camera.updateProjectionMatrix();
  sun.position.copy(camera.position).add(new THREE.Vector3(s.radius, 2 * s.radius, 0));
  $("radius").min = (s.radius / 100).toFixed(4); $("radius").max = (s.radius / 2).toFixed(4);
  $("radius").step = (s.radius / 200).toFixed(5); $("radius").value = (s.radius / 10).toFixed(4);
  showRadius();
}

function setPositions(buf) {
  const p = new Float32Array(buf, 4);
  if (!geometry) { build(new Float32Array(p)); return; }
  const attr = geometry.getAttribute("position");
  attr.array.set(p); attr.needsUpdate = true;
  geometry.computeVertexNormals(); geometry.computeBoundingSphere();
}

function setWeights(buf) {
  studio.weights = new Float32Array(buf, 4);
  paintColours();
}

function paintColours() {
  if (!geometry || !studio.weights) return;
  const c = geometry.getAttribute("color");
  for (let i = 0; i < n; i++) {
    if ($("show-weights").checked) weightColour(studio.weights[i], c.array, 3 * i);
    else { c.array[3 * i] = 0.82; c.array[3 * i + 1] = 0.8; c.array[3 * i + 2] = 0.76; }
  }
  c.needsUpdate = true;
}

// --- the server connection -------------------------------------------------
const ws = new WebSocket(`ws://${location.host}/ws`);
ws.binaryType = "arraybuffer";
const send = (msg) => { studio.pending++; ws.send(JSON.stringify(msg)); };
studio.send = send;
ws.onmessage = (ev) => {
  if (typeof ev.data === "string") {
    const m = JSON.parse(ev.data);
    if (m.type === "mesh") { n = m.n_vertices; }
    else if (m.type === "state") { state(m); studio.pending = Math.max(0, studio.pending - 1); }
    else if (m.type === "error") {
      studio.error = m.message; $("error").textContent = m.message; studio.pending = Math.max(0, studio.pending - 1);
    }
    return;
  }
  const tag = new TextDecoder().decode(new Uint8Array(ev.data, 0, 4));
  if (tag === "TRI0") tris = new Uint32Array(ev.data.slice(4));
  else if (tag === "EDG0") edges = new Uint32Array(ev.data.slice(4));
  else if (tag === "POS0") setPositions(ev.data);
  else if (tag === "WGT0") setWeights(ev.data);
};
ws.onclose = () => { $("status").textContent = "disconnected: restart shapeflow studio and reload"; };

function state(m) {
  studio.version = m.version; studio.family = m.family; studio.lams = m.lams;
  if (m.lams && m.lams.length) {
    $("lam").min = Math.min(...m.lams); $("lam").max = Math.max(...m.lams);
  }
  const f = m.family;
  const fam = f.state === "running" ? `solving the family: ${f.done}/${f.total}` :
              f.state === "done" ? `family of ${f.total} shapes ready` : f.state === "failed" ? "family failed" : "";
  $("status").textContent = `${n.toLocaleString()} vertices\n${fam}`;
  $("undo").disabled = !m.can_undo; $("redo").disabled = !m.can_redo;
  studio.ready = geometry !== null;
}

// --- controls ----------------------------------------------------------------
$("lam").addEventListener("input", () => {
  studio.lam = Number($("lam").value);
  $("lam-value").textContent = studio.lam;
  send({ op: "lam", value: studio.lam });
});
$("apply").onclick = () => send({ op: "apply", value: Number($("lam").value) });
$("undo").onclick = () => send({ op: "undo" });
$("redo").onclick = () => send({ op: "redo" });
$("wire").onchange = () => { if (wire) wire.visible = $("wire").checked; };
$("show-weights").onchange = paintColours;
const showRadius = () => { $("radius-value").textContent = Number($("radius").value).toPrecision(3); };
$("radius").addEventListener("input", showRadius);
$("brush-lam").addEventListener("input", () => { $("brush-lam-value").textContent = $("brush-lam").value; });
$("download").onclick = () => { location.href = `/download/shapeflow-studio.${$("format").value}`; };
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
function hit(e) {
  const r = renderer.domElement.getBoundingClientRect();
  pointer.set(((e.clientX - r.left) / r.width) * 2 - 1, -((e.clientY - r.top) / r.height) * 2 + 1);
  raycaster.setFromCamera(pointer, camera);
  const h = surface ? raycaster.intersectObject(surface, false) : [];
  return h.length ? h[0].point : null;
}
function edit(e) {
  const mode = $("mode").value;
  if (mode === "view" || waiting) return;
  const p = hit(e);
  if (!p) return;
  const center = [p.x, p.y, p.z], radius = Number($("radius").value);
  waiting = true;
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
renderer.domElement.addEventListener("pointermove", (e) => { if (stroking) edit(e); });
window.addEventListener("pointerup", () => { stroking = false; controls.enabled = true; });
const clearWaiting = ws.onmessage;
ws.onmessage = (ev) => { clearWaiting(ev); if (typeof ev.data === "string") waiting = false; };

// --- drawing -------------------------------------------------------------------
function resize() {
  const w = view.clientWidth, h = view.clientHeight;
  renderer.setSize(w, h, false); renderer.domElement.style.width = w + "px";
  renderer.domElement.style.height = h + "px"; camera.aspect = w / h; camera.updateProjectionMatrix();
}
window.addEventListener("resize", resize);
resize();
renderer.setAnimationLoop(() => { controls.update(); renderer.render(scene, camera); studio.frames++; });
