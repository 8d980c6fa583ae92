// The 3D view: three.js scene, the model's geometry and colours, the camera (the project's view rule:
// named views from the model's front, sent by the server), framing, the split view and drawing.
import * as THREE from "three";
import { OrbitControls } from "/static/vendor/three/OrbitControls.js";
import { $, studio } from "./state.js";

const host = $("view");
// a software renderer (SwiftShader, llvmpipe: no GPU) draws 2.2x faster without multisampling
const softwareGL = (() => {
  const gl = document.createElement("canvas").getContext("webgl2");
  const info = gl && gl.getExtension("WEBGL_debug_renderer_info");
  return info ? /swiftshader|llvmpipe|software/i.test(gl.getParameter(info.UNMASKED_RENDERER_WEBGL)) : false;
})();
export const renderer = new THREE.WebGLRenderer({ antialias: !softwareGL });
renderer.setPixelRatio(window.devicePixelRatio);
host.appendChild(renderer.domElement);
export const canvas = renderer.domElement;
const scene = new THREE.Scene();
scene.background = new THREE.Color(0x26272b);
export const camera = new THREE.PerspectiveCamera(35, 1, 0.01, 1000);
scene.add(new THREE.HemisphereLight(0xffffff, 0x444455, 1.6));
const sun = new THREE.DirectionalLight(0xffffff, 1.4);
scene.add(sun, sun.target);
// the light comes from above and right of the camera, wherever it goes
function placeSun() {
  const r = model.fitted ? model.fitted.radius : 1;
  sun.position.copy(new THREE.Vector3(r, 2 * r, 0).applyQuaternion(camera.quaternion)).add(camera.position);
  sun.target.position.copy(controls.target);
  sun.target.updateMatrixWorld();
}
studio.softwareGL = softwareGL;

let dirty = true;
export const redraw = () => { dirty = true; };
studio.redraw = redraw;

// --- the model's frame and the camera ------------------------------------------
// axes: right, up, front of the model; views: name -> {dir: from the model towards the camera, up}
const model = { up: new THREE.Vector3(0, 1, 0), views: {}, axes: null, fitted: null };
export let controls = null;
function makeControls(up) {
  if (controls) controls.dispose();
  camera.up.copy(up);                      // OrbitControls orbits about the camera's up, fixed when it is made
  controls = new OrbitControls(camera, canvas);
  controls.autoRotateSpeed = 4.0;          // one turn in 15 s
  controls.autoRotate = $("turntable").checked;
  controls.addEventListener("change", () => { redraw(); placeSun(); });
  controls.addEventListener("start", () => { studio.view = null; });     // orbiting leaves the named view
}
makeControls(model.up);
export function setModel(m) {            // from the "mesh" message
  const up = new THREE.Vector3(...m.axes.up);
  model.axes = { right: new THREE.Vector3(...m.axes.right), up, front: new THREE.Vector3(...m.axes.front) };
  model.views = m.views || {};
  model.mirror = m.mirror ? { origin: new THREE.Vector3(...m.mirror.origin), normal: new THREE.Vector3(...m.mirror.normal) }
                          : null;
  if (!up.equals(model.up)) { model.up = up; makeControls(up); }
  model.fitted = null;
}
studio.views = () => model.views;
studio.cameraPosition = () => camera.position.toArray();
studio.cameraTarget = () => controls.target.toArray();

// place the camera along `dir` (from the target towards the camera) so the whole shape is in view
function fit(dir) {
  if (!mesh.geometry) return;
  mesh.geometry.computeBoundingSphere();
  const s = mesh.geometry.boundingSphere, r = Math.max(s.radius, 1e-9);
  const half = THREE.MathUtils.degToRad(camera.fov) / 2;
  const halfX = Math.atan(Math.tan(half) * camera.aspect);
  const dist = 1.04 * r / Math.sin(Math.min(half, halfX));
  controls.target.copy(s.center);
  camera.position.copy(s.center).addScaledVector(dir.clone().normalize(), dist);
  camera.near = dist / 100; camera.far = dist * 100; camera.updateProjectionMatrix();
  camera.lookAt(s.center);
  controls.update();
  model.fitted = { center: s.center.clone(), radius: r };
  placeSun();
  redraw();
}
// a named view of the project's rule ("front", "back", "right", "left", "top", "bottom")
export function lookFrom(name) {
  const v = model.views[name];
  if (!v) return;
  const dir = new THREE.Vector3(...v.dir), up = new THREE.Vector3(...v.up);
  // straight along the up axis OrbitControls cannot hold the view's own up: lean a little that way
  if (Math.abs(dir.dot(model.up)) > 0.999) dir.addScaledVector(up, -0.002).normalize();
  studio.view = name;
  fit(dir);
}
// the view from the other side (Blender's numpad 9)
export function opposite() {
  const other = { front: "back", back: "front", right: "left", left: "right", top: "bottom", bottom: "top" };
  if (studio.view && other[studio.view]) { lookFrom(other[studio.view]); return; }
  fit(camera.position.clone().sub(controls.target).negate());
}
// frame the shape from where the camera looks now
export function frameModel() { fit(camera.position.clone().sub(controls.target)); }
// the shape outgrew what was framed (a preview, an apply): frame it again, from where the camera looks
function refitIfOutgrown() {
  if (!model.fitted || studio.stroking) return;
  mesh.geometry.computeBoundingSphere();
  const s = mesh.geometry.boundingSphere;
  if (s.center.distanceTo(model.fitted.center) + s.radius > 1.02 * model.fitted.radius) {
    studio.refits = (studio.refits || 0) + 1;
    frameModel();
  }
}
studio.refitIfOutgrown = () => refitIfOutgrown();

// where a point of the model is on the screen (client coordinates), for tests and scripts
studio.toScreen = (p) => {
  const v = new THREE.Vector3(...p).project(camera), r = canvas.getBoundingClientRect();
  return [r.left + (v.x + 1) / 2 * r.width, r.top + (1 - v.y) / 2 * r.height];
};
// how many of the shown vertices lie outside the picture (tests: the frame holds the shape)
studio.outside = () => {
  const a = mesh.geometry.getAttribute("position").array, v = new THREE.Vector3();
  let k = 0;
  for (let i = 0; i < a.length; i += 3) {
    v.set(a[i], a[i + 1], a[i + 2]).project(camera);
    if (Math.abs(v.x) > 1 || Math.abs(v.y) > 1) k++;
  }
  return k;
};
// pixels on screen per unit of length at the depth of `point`
export function pixelsPerUnit(point) {
  const d = camera.position.distanceTo(point);
  return (host.clientHeight / 2) / (d * Math.tan(THREE.MathUtils.degToRad(camera.fov) / 2));
}

// --- the geometry -------------------------------------------------------------------
export const mesh = { n: 0, tris: null, edges: null, base: null, geometry: null, surface: null, wire: null,
                      before: null, weights: null, field: null, fieldValues: null };
studio.positions = () => (mesh.geometry ? Array.from(mesh.geometry.getAttribute("position").array) : []);
studio.weightList = () => (mesh.weights ? Array.from(mesh.weights) : []);
studio.edgeCount = () => (mesh.edges ? mesh.edges.length / 2 : 0);
let fresh = true;                         // a new mesh: shown from the front once it is built

export function newMesh(m) {
  mesh.n = m.n_vertices; mesh.field = null; dispose(); setModel(m); fresh = true;
}
export const setTriangles = (buf) => { mesh.tris = new Uint32Array(buf.slice(4)); };
export const setEdges = (buf) => { mesh.edges = new Uint32Array(buf.slice(4)); };
export const setBase = (buf) => { mesh.base = new Float32Array(buf.slice(4)); };

function dispose() {                      // a new mesh was opened: drop what showed the old one
  for (const o of [mesh.surface, mesh.wire, mesh.before]) {
    if (o) { scene.remove(o); o.geometry.dispose(); o.material.dispose(); }
  }
  mesh.surface = mesh.wire = mesh.before = mesh.geometry = null;
}

function build(positions) {
  dispose();
  const g = mesh.geometry = new THREE.BufferGeometry();
  g.setAttribute("position", new THREE.BufferAttribute(positions, 3));
  g.setAttribute("color", new THREE.BufferAttribute(new Float32Array(mesh.n * 3).fill(1), 3));
  g.setIndex(new THREE.BufferAttribute(mesh.tris, 1));
  g.computeVertexNormals();
  mesh.surface = new THREE.Mesh(g, new THREE.MeshStandardMaterial({
    vertexColors: true, roughness: 0.6, metalness: 0.0, polygonOffset: true,
    polygonOffsetFactor: 1, polygonOffsetUnits: 1 }));
  scene.add(mesh.surface);
  const wg = new THREE.BufferGeometry();
  wg.setAttribute("position", g.getAttribute("position"));     // shared: one update moves both
  wg.setIndex(new THREE.BufferAttribute(mesh.edges, 1));
  mesh.wire = new THREE.LineSegments(wg, new THREE.LineBasicMaterial({ color: 0x111111, transparent: true,
                                                                      opacity: 0.35 }));
  mesh.wire.visible = $("wire").checked;
  scene.add(mesh.wire);
  mesh.surface.frustumCulled = mesh.wire.frustumCulled = false;   // their bounds change with every shape
  // the split view's "before": the input as opened, drawn left of the divider
  const bg = new THREE.BufferGeometry();
  bg.setAttribute("position", new THREE.BufferAttribute(mesh.base || new Float32Array(positions), 3));
  bg.setIndex(g.getIndex());
  bg.computeVertexNormals();
  // the colour of the surface with Colours: None (linear RGB, as the surface's vertex colours)
  mesh.before = new THREE.Mesh(bg, new THREE.MeshStandardMaterial({ color: new THREE.Color().setRGB(0.82, 0.8, 0.76),
                                                                    roughness: 0.6 }));
  mesh.before.visible = false;
  scene.add(mesh.before);
  if (fresh) { fresh = false; lookFrom("front"); } else refitIfOutgrown();
  paintColours();
  redraw();
}

let boundsStale = false;
function positionsChanged() {
  mesh.geometry.computeVertexNormals(); boundsStale = true;   // the bounds only for picking: recomputed then
  studio.positionsAt = performance.now(); redraw();
  if (studio.editAt !== null) { studio.awaitingFrame = studio.editAt; studio.editAt = null; }
}
export function setPositions(buf) {
  const p = new Float32Array(buf, 4);
  if (!mesh.geometry) { build(new Float32Array(p)); return; }
  const attr = mesh.geometry.getAttribute("position");
  attr.array.set(p); attr.needsUpdate = true;
  positionsChanged();
  refitIfOutgrown();
}
export function setSomePositions(buf) {          // PSUB: uint32 k, k indices, k × 3 positions
  if (!mesh.geometry) return;
  const k = new Uint32Array(buf, 4, 1)[0];
  const idx = new Uint32Array(buf, 8, k), p = new Float32Array(buf, 8 + 4 * k, 3 * k);
  const a = mesh.geometry.getAttribute("position").array;
  for (let j = 0; j < k; j++) {
    const i = 3 * idx[j];
    a[i] = p[3 * j]; a[i + 1] = p[3 * j + 1]; a[i + 2] = p[3 * j + 2];
  }
  mesh.geometry.getAttribute("position").needsUpdate = true;
  positionsChanged();
}
export function setWeights(buf) { mesh.weights = new Float32Array(buf, 4); paintColours(); }
export function setFieldValues(buf) { mesh.fieldValues = new Float32Array(buf.slice(4)); }
export function setField(m) {
  mesh.field = studio.field = { name: m.name, version: m.version, lam: m.lam, scale: m.scale,
                                values: mesh.fieldValues };
  paintColours();
}
export function dropField() { mesh.field = studio.field = null; }

// --- colours ------------------------------------------------------------------------
const weightColour = (w, out, k) => {      // 0: blue, 1: warm white
  out[k] = 0.25 + 0.72 * w; out[k + 1] = 0.35 + 0.55 * w; out[k + 2] = 0.9 - 0.2 * w;
};
const diverging = (t, out, k) => {        // t in [-1, 1]: blue, white, red (coolwarm's ends)
  const a = Math.min(1, Math.abs(t));
  const end = t < 0 ? [0.23, 0.3, 0.75] : [0.71, 0.02, 0.15];
  out[k] = 0.95 + (end[0] - 0.95) * a; out[k + 1] = 0.95 + (end[1] - 0.95) * a; out[k + 2] = 0.95 + (end[2] - 0.95) * a;
};
export function paintColours() {
  if (!mesh.geometry || !mesh.weights) return;
  const c = mesh.geometry.getAttribute("color"), mode = $("colours").value;
  const field = mesh.field && mesh.field.name === mode ? mesh.field.values : null;
  let scale = 1;
  if (field) {              // a robust symmetric range: the 98th percentile of |value|, from the server
    scale = mesh.field.scale || 1;
    $("legend-lo").textContent = (-scale).toPrecision(3); $("legend-hi").textContent = scale.toPrecision(3);
    $("legend-bar").style.background = "linear-gradient(to right, #3b4cc0, #f2f2f2, #b40426)";
  } else if (mode === "weights") {
    $("legend-lo").textContent = "weight 0"; $("legend-hi").textContent = "1";
    $("legend-bar").style.background = "linear-gradient(to right, rgb(137,160,244), rgb(251,244,218))";
  }
  $("legend").style.visibility = field || mode === "weights" ? "visible" : "hidden";
  for (let i = 0; i < mesh.n; i++) {
    if (mode === "weights") weightColour(mesh.weights[i], c.array, 3 * i);
    else if (field) diverging(field[i] / scale, c.array, 3 * i);
    else { c.array[3 * i] = 0.82; c.array[3 * i + 1] = 0.8; c.array[3 * i + 2] = 0.76; }
  }
  c.needsUpdate = true; redraw();
}
export function showEdges(on) { if (mesh.wire) mesh.wire.visible = on; redraw(); }
export function turntable(on) { controls.autoRotate = on; }

// --- picking: the surface under a point of the screen ----------------------------------
const raycaster = new THREE.Raycaster();
const ndc = new THREE.Vector2();
export function pick(clientX, clientY) {
  if (!mesh.surface) return null;
  const r = canvas.getBoundingClientRect();
  ndc.set(((clientX - r.left) / r.width) * 2 - 1, -((clientY - r.top) / r.height) * 2 + 1);
  raycaster.setFromCamera(ndc, camera);
  if (boundsStale) { mesh.geometry.computeBoundingSphere(); boundsStale = false; }
  const h = raycaster.intersectObject(mesh.surface, false);
  if (!h.length) return null;
  return { point: h[0].point, normal: h[0].face.normal.clone().transformDirection(mesh.surface.matrixWorld) };
}

// the brush circles: a ring on the surface under the pointer, and its mirror image with X symmetry
export function makeRing() {
  const ring = new THREE.Mesh(new THREE.RingGeometry(0.94, 1.0, 64),
                              new THREE.MeshBasicMaterial({ color: 0xffcc44, side: THREE.DoubleSide, depthTest: false }));
  ring.visible = false;
  ring.renderOrder = 2;
  scene.add(ring);
  return ring;
}
const zAxis = new THREE.Vector3(0, 0, 1);
export function placeRing(ring, point, normal, radius) {
  ring.position.copy(point);
  ring.quaternion.setFromUnitVectors(zAxis, normal);
  ring.scale.setScalar(radius);
  ring.visible = true;
}
// a point or a direction reflected across the model's plane of symmetry (the server's
// StudioSession.mirrored: the plane through the centre of the input's bounding box, normal to its right axis)
export function mirrored(v, isDirection = false) {
  if (!model.mirror) return v.clone();
  const d = (isDirection ? v.clone() : v.clone().sub(model.mirror.origin)).dot(model.mirror.normal);
  return v.clone().addScaledVector(model.mirror.normal, -2 * d);
}

// --- the split view: the input left of the divider, the current shape right of it ---
studio.split = 0.5;
const divider = $("divider");
export function showSplit(on) { divider.style.display = on ? "block" : "none"; placeDivider(); }
function placeDivider() { divider.style.left = `${100 * studio.split}%`; redraw(); }
divider.addEventListener("pointerdown", (e) => {
  divider.setPointerCapture(e.pointerId);
  const move = (ev) => {
    const r = host.getBoundingClientRect();
    studio.split = Math.min(0.95, Math.max(0.05, (ev.clientX - r.left) / r.width)); placeDivider();
  };
  divider.addEventListener("pointermove", move);
  divider.addEventListener("pointerup", () => divider.removeEventListener("pointermove", move), { once: true });
});

// --- drawing -------------------------------------------------------------------
function resize() {
  const w = host.clientWidth, h = host.clientHeight;
  renderer.setSize(w, h, false); canvas.style.width = w + "px";
  canvas.style.height = h + "px"; camera.aspect = w / h; camera.updateProjectionMatrix();
  redraw();
}
window.addEventListener("resize", resize);
resize();
function draw() {
  const { surface, wire, before } = mesh;
  if (!$("split").checked || !before) { renderer.render(scene, camera); return; }
  const w = host.clientWidth, h = host.clientHeight, x = Math.round(studio.split * w);
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
    const lat = performance.now() - studio.awaitingFrame.t;
    (studio.awaitingFrame.queued ? studio.queuedLatencies : studio.latencies).push(lat);
    studio.awaitingFrame = null;
  }
});
