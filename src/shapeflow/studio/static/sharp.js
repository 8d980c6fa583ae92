// Sharp features: the panel's "Keep sharp edges" (its angle, the file's marked edges) and the sharp
// edges drawn as lines on the shape shown (protocol: the "features" message, answered by a "features"
// message and an SHP0 frame of vertex pairs, u32).
import * as THREE from "three";
import { $, studio } from "./state.js";
import { onFrame, onText, send } from "./net.js";
import { mesh, redraw } from "./view.js";

studio.sharp = { on: false, angle: 30, marked: false, marked_count: 0, count: 0 };
const lines = { object: null, pairs: new Uint32Array(0) };
// how many sharp edges the view draws (0 when the setting is off), for tests and scripts
studio.sharpLines = () => (lines.object && lines.object.visible && lines.object.parent === mesh.surface
                           && mesh.surface ? lines.object.geometry.index.count / 2 : 0);

function drop() {
  if (!lines.object) return;
  lines.object.removeFromParent(); lines.object.geometry.dispose(); lines.object.material.dispose();
  lines.object = null;
}
function build(tries = 0) {
  drop();
  if (!lines.pairs.length) { redraw(); return; }
  if (!mesh.surface) {                 // the server sends the shape before its edges: this waits only in case
    if (tries < 100) setTimeout(() => build(tries + 1), 50);
    return;
  }
  const g = new THREE.BufferGeometry();
  g.setAttribute("position", mesh.geometry.getAttribute("position"));    // shared: the lines follow the shape
  g.setIndex(new THREE.BufferAttribute(lines.pairs, 1));
  // drawn after the mesh's own edges (transparent, opacity 0.35), over them where they coincide
  lines.object = new THREE.LineSegments(g, new THREE.LineBasicMaterial({ color: 0xff40c0, transparent: true }));
  lines.object.renderOrder = 1;
  lines.object.frustumCulled = false;
  lines.object.visible = studio.sharp.on;
  mesh.surface.add(lines.object);      // a child of the surface: hidden with it (the split view's "before")
  redraw();
}

function show(m, typed = false) {      // the controls as the session has them (the angle being typed kept)
  $("sharp").checked = m.on;
  if (!typed || document.activeElement !== $("sharp-angle")) $("sharp-angle").value = m.angle;
  $("sharp-marked").checked = m.marked;
  $("sharp-marked-row").style.display = m.marked_count ? "" : "none";
  $("sharp-marked-count").textContent = `(${m.marked_count.toLocaleString()})`;
  $("sharp-marked-row").title = "the edges the file marks sharp (smoothing-group borders, 't crease' tags, "
                                + "split normals), kept with the angle's";
  if (lines.object) { lines.object.visible = m.on; redraw(); }
}
onText("features", (m) => { Object.assign(studio.sharp, m); show(studio.sharp, true); });
onFrame("SHP0", (buf) => { lines.pairs = new Uint32Array(buf.slice(4)); build(); });

function sendFeatures() {
  const text = $("sharp-angle").value.trim(), angle = Number(text);
  if (text === "" || !Number.isFinite(angle)) { show(studio.sharp); return; }
  // refused (an angle outside 0..180): the error shows, the controls return to the session's setting
  send({ op: "features", on: $("sharp").checked, angle, marked: $("sharp-marked").checked },
       (ok) => { if (!ok) show(studio.sharp); });
}
for (const id of ["sharp", "sharp-angle", "sharp-marked"]) $(id).addEventListener("change", sendFeatures);
