// The tools on the surface: strokes of the weight brush and the sculpt brushes (pointer down to up is one
// stroke, one undo step), the brush circles, X symmetry, and the brush's radius and strength (sliders,
// [ ] and Shift+[ ], F and Shift+F as in Blender).
import { $, studio } from "./state.js";
import { send } from "./net.js";
import * as view from "./view.js";

// --- the brush's size and strength ------------------------------------------------
// strength 0..1 per tool (each tool keeps its own, as Blender's brushes do)
const strengths = { paint: 0.5, erase: 0.5, sculpt: 0.67, inflate: 0.5 };
export const tool = () => $("mode").value;
// the enhancement brush: λ = −10^(3 s), 1 … 1000 (a dab's effect saturates: a scale in decades)
export const brushLam = (s) => -Math.round(Math.pow(10, 3 * s) * 10) / 10;
// the inflate brush: each dab moves up to 0.2 s of the radius along the normal
const inflateStrength = (s) => 0.2 * s;
const radius = () => Number($("radius").value);
const strength = () => Number($("strength").value);

export function showRadius() { $("radius-value").textContent = radius().toPrecision(3); }
export function showStrength() {
  const s = strength(), t = tool();
  if (t in strengths) strengths[t] = s;
  $("strength-value").textContent = t === "sculpt" || t === "view" ? `${s.toFixed(2)} (λ ${brushLam(s)})` : s.toFixed(2);
}
export function setRadius(r) {
  const el = $("radius");
  el.value = Math.min(Number(el.max), Math.max(Number(el.min), r));
  showRadius();
  if (ring.visible) { ring.scale.setScalar(radius()); view.redraw(); }
}
export function setStrength(s) { $("strength").value = Math.min(1, Math.max(0, s)); showStrength(); }
export function toolChanged() {
  const t = tool();
  // View has no strength of its own: the slider shows the Enhance brush's, disabled
  $("strength").value = strengths[t in strengths ? t : "sculpt"];
  $("strength").disabled = t === "view";
  showStrength();
  if (t === "view") hideRings();
}
// a new mesh: the radius slider's range and default from its size
export function newMesh(sphereRadius) {
  const el = $("radius");
  el.min = (sphereRadius / 100).toFixed(5); el.max = (sphereRadius / 1.5).toFixed(5);
  el.step = (sphereRadius / 1000).toFixed(6); el.value = (sphereRadius * DEFAULT_RADIUS).toFixed(5);
  showRadius();
}
// the default radius as a fraction of the model's bounding sphere (docs/studio.md: "Brush strength")
export const DEFAULT_RADIUS = 0.2;

// --- the brush circles ----------------------------------------------------------------
const ring = view.makeRing(), twin = view.makeRing();
function hideRings() {
  if (ring.visible || twin.visible) { ring.visible = twin.visible = false; view.redraw(); }
  studio.ring = { visible: false };
}
function moveRings(x, y) {
  const h = tool() !== "view" ? view.pick(x, y) : null;
  if (!h) { hideRings(); return; }
  view.placeRing(ring, h.point, h.normal, radius());
  twin.visible = false;
  if ($("mirror").checked) view.placeRing(twin, view.mirrored(h.point), view.mirrored(h.normal, true), radius());
  studio.ring = { visible: true, center: ring.position.toArray(), twin: twin.visible ? twin.position.toArray() : null };
  // during a stroke the frame with the edit's answer shows the circle where it now is: a frame for
  // the circle alone would only hold that answer back (a software renderer takes ~100 ms a frame)
  if (!(stroke && waiting)) view.redraw();
}

// --- strokes: pointer down to up, one undo step ------------------------------------------
// dabs every SPACING × the radius along the pointer's path (as the library's Brush.stroke and the
// Blender add-on's Space stroke): what a stroke does depends on where the pointer went, not on how
// fast it moved or how many events the browser sent.  Between the last dab and the pointer the path
// is a straight line on the screen, each dab's centre the surface under it.  The dabs of one pointer
// move go out together; pointer moves made while they are on their way are not dropped: the newest
// waits and the stroke goes on from the last dab to it when the answers arrive
export const SPACING = 0.25;
studio.spacing = SPACING;
let stroke = null, waiting = false;
studio.dabs = 0;
function message(h, mods) {
  const center = [h.point.x, h.point.y, h.point.z], r = radius(), s = strength(), t = tool();
  const mirror = $("mirror").checked;
  if (t === "paint" || t === "erase") {
    return { op: "paint", center, radius: r, mirror, strength: s, value: (t === "paint") !== mods.ctrl ? 1.0 : 0.0 };
  }
  if (mods.shift) return { op: "dab", center, radius: r, mirror, lam: -brushLam(s) };        // smooth: +λ
  if (t === "inflate") return { op: "dab", center, radius: r, mirror, inflate: true,
                                strength: (mods.ctrl ? -1 : 1) * inflateStrength(s) };
  return { op: "dab", center, radius: r, mirror, lam: (mods.ctrl ? -1 : 1) * brushLam(s) };
}
// the dabs from the last one towards the pointer at (x, y): [{x, y, h}], none when it is nearer
// than the spacing or off the model
function dabsTowards(x, y) {
  const h = view.pick(x, y);
  if (!h) return [];
  const last = stroke.last;
  const step = studio.spacing * radius(), d = last ? h.point.distanceTo(last.h.point) : 0;
  if (!last || !(step > 0)) return [{ x, y, h }];             // the stroke's first dab; spacing 0: at every move
  const out = [];
  for (let k = 1; k * step <= d; k++) {
    const f = (k * step) / d, px = last.x + f * (x - last.x), py = last.y + f * (y - last.y);
    const hk = view.pick(px, py);
    if (hk) out.push({ x: px, y: py, h: hk });
  }
  return out;
}
function dab(x, y, t, queued) {
  const dabs = dabsTowards(x, y);
  if (!dabs.length) return false;
  waiting = true;
  studio.editAt = { t, queued };
  studio.dabs += dabs.length;
  stroke.last = dabs[dabs.length - 1];
  dabs.forEach((d, i) => send(message(d.h, stroke.mods),
                              i === dabs.length - 1 ? () => { waiting = false; next(); } : null));
  return true;
}
function next() {
  if (!stroke) return;
  if (stroke.queued) {
    const q = stroke.queued; stroke.queued = null;
    if (dab(q.x, q.y, q.t, true)) return;
  }
  if (stroke.ending) finish();
}
function finish() {
  send({ op: "end" });
  stroke = null; studio.stroking = false;
  view.controls.enabled = true;
  studio.refitIfOutgrown();
}
view.canvas.addEventListener("pointerdown", (e) => {
  if (adjusting) { e.preventDefault(); endAdjust(e.button === 0); return; }
  if (e.button !== 0 || tool() === "view" || stroke || !view.pick(e.clientX, e.clientY)) return;
  view.controls.enabled = false;
  stroke = { mods: { ctrl: e.ctrlKey || e.metaKey, shift: e.shiftKey }, queued: null, ending: false, last: null };
  studio.stroking = true;
  send({ op: "begin" });
  dab(e.clientX, e.clientY, e.timeStamp, false);
});
view.canvas.addEventListener("contextmenu", (e) => { if (adjusting) { e.preventDefault(); endAdjust(false); } });
view.canvas.addEventListener("pointermove", (e) => {
  pointer.x = e.clientX; pointer.y = e.clientY; pointer.inside = true;
  if (adjusting) { adjustTo(e.clientX, e.clientY); return; }
  if (stroke && !stroke.ending) {
    if (waiting) stroke.queued = { x: e.clientX, y: e.clientY, t: e.timeStamp };
    else dab(e.clientX, e.clientY, e.timeStamp, false);
  }
  moveRings(e.clientX, e.clientY);
});
view.canvas.addEventListener("pointerleave", () => { pointer.inside = false; if (!stroke) hideRings(); });
window.addEventListener("pointerup", () => {
  if (!stroke) return;
  stroke.ending = true;
  if (!waiting) finish();
});

// --- F and Shift+F: the radius or the strength with the pointer (Blender's radial control) ----------
// the circle's centre sits so that the pointer is on its edge; moving the pointer changes its size;
// a click or Enter sets it, Esc or a right click puts it back
const pointer = { x: 0, y: 0, inside: false };
const STRENGTH_PIXELS = 200;            // Shift+F: the circle's radius in pixels at strength 1
let adjusting = null;
export function startAdjust(kind) {
  if (tool() === "view" && kind === "strength") return;
  const box = view.canvas.getBoundingClientRect();
  const x = pointer.inside ? pointer.x : box.left + box.width / 2, y = pointer.inside ? pointer.y : box.top + box.height / 2;
  const h = view.pick(x, y);
  const ppu = view.pixelsPerUnit(h ? h.point : view.controls.target);
  const px = kind === "radius" ? radius() * ppu : strength() * STRENGTH_PIXELS;
  adjusting = { kind, cx: x - px, cy: y, ppu, start: kind === "radius" ? radius() : strength() };
  studio.adjusting = kind;
  adjustTo(x, y);
}
function adjustTo(x, y) {
  const a = adjusting, d = Math.hypot(x - a.cx, y - a.cy);
  if (a.kind === "radius") setRadius(d / a.ppu); else setStrength(d / STRENGTH_PIXELS);
  const px = a.kind === "radius" ? radius() * a.ppu : strength() * STRENGTH_PIXELS;
  const el = $("adjust"), box = $("view").getBoundingClientRect();
  Object.assign(el.style, { display: "block", left: `${a.cx - box.left}px`, top: `${a.cy - box.top}px`,
                            width: `${2 * px}px`, height: `${2 * px}px` });
  el.firstElementChild.textContent = a.kind === "radius" ? `radius ${radius().toPrecision(3)}`
                                                         : `strength ${strength().toFixed(2)}`;
}
export function endAdjust(keep) {
  if (!adjusting) return false;
  if (!keep) (adjusting.kind === "radius" ? setRadius : setStrength)(adjusting.start);
  adjusting = null; studio.adjusting = null;
  $("adjust").style.display = "none";
  return true;
}
export const isAdjusting = () => adjusting !== null;

// --- X symmetry -------------------------------------------------------------------
export function toggleMirror() {
  $("mirror").checked = !$("mirror").checked;
  if (pointer.inside) moveRings(pointer.x, pointer.y); else view.redraw();
}
$("mirror").addEventListener("change", () => { if (pointer.inside) moveRings(pointer.x, pointer.y); });
studio.brush = () => ({ radius: radius(), strength: strength(), lam: brushLam(strength()), tool: tool(),
                        mirror: $("mirror").checked, strengths: { ...strengths } });
