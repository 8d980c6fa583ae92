// The panel: status and errors, the λ slider (its typed value and the family's range), the family's
// options, colours, undo, files, and the keyboard (every shortcut in one table, which "?" shows).
import { $, studio } from "./state.js";
import { fetchFile, fetchJSON, post, send } from "./net.js";
import * as tools from "./tools.js";
import * as view from "./view.js";

// --- status and errors ---------------------------------------------------------------
// a notice across the top of the view (× dismisses it): [show(text), clear()], its text as studio[id]
function banner(id) {
  const show = (text) => { studio[id] = text; $(id).firstElementChild.textContent = text; $(id).classList.add("shown"); };
  const clear = () => { studio[id] = null; $(id).classList.remove("shown"); };
  $(`${id}-close`).onclick = clear;
  return [show, clear];
}
// an error: the red banner; information, not a failure (a λ outside the family, what a download's
// format dropped): the blue one
export const [showError, clearError] = banner("error");
export const [showInfo, clearInfo] = banner("info");

let last = null;                      // the last state message
function showStatus() {
  const m = last;
  if (!m) return;
  const f = m.family;
  const fam = f.state === "running" ? `solving the family: ${f.done}/${f.total}` :
              f.state === "failed" ? `family failed: ${f.error}` :
              m.stale ? "family: solved anew when the slider moves" :
              f.state === "done" ? `family of ${m.lams.length} shapes ready` : "";
  $("status").textContent = `${studio.name ? studio.name + ": " : ""}${studio.n.toLocaleString()} vertices`
    + `${m.modified ? " · unsaved" : ""}\n${fam}`;
  $("status").title = $("status").textContent;
  $("progress").value = f.total ? f.done / f.total : 0;
  $("progress").style.visibility = f.state === "running" ? "visible" : "hidden";
}

// --- λ: the slider, its typed value, the family's range ------------------------------------
const fmt = (v) => String(Math.round(Math.abs(v) * 100) / 100);
function showLam(v) {
  $("lam").value = v;
  if (document.activeElement !== $("lam-num")) $("lam-num").value = v;
  $("lam-value").textContent = v === 0 ? "0 · as is" : v < 0 ? `−${fmt(v)} enhance` : `+${fmt(v)} smooth`;
}
// at most two λ requests in flight (the server works on the next shape while the page takes in the
// last), the newest value queued: dragging faster than the answers shows the newest shape as soon as
// it can instead of a growing backlog
let lamInFlight = 0, lamQueued = false;
const fieldMode = () => { const m = $("colours").value; return m === "curvature" || m === "displacement" ? m : null; };
function sendLam() {
  lamInFlight++; lamQueued = false;
  send({ op: "lam", value: studio.lam, field: fieldMode() }, () => { lamInFlight--; if (lamQueued) sendLam(); });
}
function setLam(v) {
  studio.lam = v; showLam(v);
  if (lamInFlight < 2) sendLam(); else lamQueued = true;
}
$("lam").addEventListener("input", () => setLam(Number($("lam").value)));
$("lam-num").addEventListener("change", () => {
  const v = Number($("lam-num").value), lo = Number($("lam").min), hi = Number($("lam").max);
  if ($("lam-num").value.trim() === "" || !Number.isFinite(v)) { $("lam-num").value = studio.lam; return; }
  const c = Math.min(hi, Math.max(lo, v));
  if (c !== v) showInfo(`λ ${v} is outside the family (${lo} … ${hi}): showing ${c}; widen the range to go further`);
  $("lam-num").blur();
  setLam(c);
});
// the family's range as the slider reads it: from its left end (enhancement) to its right end, unless a
// box is being edited; a range typed either way round is solved as typed (the command line's grid)
function showRange(lams) {
  if (!lams.length || ["fam-from", "fam-to", "fam-step"].some((id) => document.activeElement === $(id))) return;
  const a = Math.min(...lams), b = Math.max(...lams);
  $("fam-from").value = a; $("fam-to").value = b;
  $("fam-step").value = lams.length > 1 ? Number(((b - a) / (lams.length - 1)).toPrecision(6)) : 10;
  $("lam").min = a; $("lam").max = b;
}
function solveRange() {
  send({ op: "solve", from: Number($("fam-from").value), to: Number($("fam-to").value),
         step: Number($("fam-step").value) });
}
$("fam-solve").onclick = solveRange;
for (const id of ["fam-from", "fam-to", "fam-step"]) {
  $(id).addEventListener("keydown", (e) => { if (e.key === "Enter") { $(id).blur(); solveRange(); } });
}
$("apply").onclick = () => send({ op: "apply", value: studio.lam });
// the family's options: any change solves the family again
const familyOptions = () => ({ op: "options", lam_border: Number($("lam-border").value),
  iterations: Number($("iterations").value), normalized: !$("area").checked,
  preserve_volume: $("volume").checked, compat: $("compat").value });
for (const id of ["lam-border", "iterations", "area", "volume", "compat"]) $(id).onchange = () => send(familyOptions());

// --- what the server says -------------------------------------------------------------------
let lamsShown = "";
export function state(m) {
  const versionChanged = m.version !== studio.version;
  const solved = studio.family && studio.family.state === "running" && m.family.state === "done";
  last = m;
  Object.assign(studio, { version: m.version, family: m.family, lams: m.lams, options: m.options,
                          modified: m.modified, previewing: m.previewing, stale: m.stale });
  if (JSON.stringify(m.lams) !== lamsShown) { lamsShown = JSON.stringify(m.lams); showRange(m.lams); }
  if (lamInFlight === 0 && !lamQueued && m.lam !== studio.lam) { studio.lam = m.lam; showLam(m.lam); }
  showStatus();
  $("undo").disabled = !m.can_undo; $("redo").disabled = !m.can_redo;
  studio.ready = view.mesh.geometry !== null;
  // the colours follow the shape shown: after an edit, and when a new family's preview arrives
  if ((versionChanged || (solved && studio.lam !== 0)) && fieldMode()) requestField();
}
export function newMesh(m) {
  studio.ready = false; studio.name = m.name; studio.n = m.n_vertices; studio.lam = 0; showLam(0);
  view.dropField(); formats(m.formats || []); showFront(m); formatNote();
}
// the axis the model faces (the server's orientation message): the selector, and the views turned to it
function showFront(m) {
  studio.front = m.front || m.default_front;
  for (const o of $("front").options) o.disabled = o.value.slice(1) === m.up_axis;
  $("front").value = studio.front;
}
export function orientation(m) { showFront(m); view.setModel(m); view.lookFrom("front"); }
$("front").onchange = () => send({ op: "front", axis: $("front").value });
function requestField() {                  // of the shape shown: the slider's preview when it is off 0
  const mode = fieldMode();
  if (mode) send({ op: "field", name: mode, lam: studio.lam !== 0 ? studio.lam : null });
  else view.paintColours();
}
$("colours").onchange = requestField;
$("wire").onchange = () => view.showEdges($("wire").checked);
$("turntable").onchange = () => view.turntable($("turntable").checked);
$("split").onchange = () => view.showSplit($("split").checked);
$("view-front").onclick = () => view.lookFrom("front");
$("view-right").onclick = () => view.lookFrom("right");
$("view-top").onclick = () => view.lookFrom("top");
$("view-frame").onclick = () => view.frameModel();
const undo = () => send({ op: "undo" }), redo = () => send({ op: "redo" });
$("undo").onclick = undo;
$("redo").onclick = redo;
$("mode").onchange = () => tools.toolChanged();
$("radius").addEventListener("input", tools.showRadius);
$("strength").addEventListener("input", tools.showStrength);

// --- files: the dialog, drag and drop, weights, download -------------------------------------
// opening a file replaces the mesh: with unsaved changes (since it was opened or last downloaded) ask first
async function upload(route, file) {
  if (route === "open" && studio.modified &&
      !window.confirm(`The mesh has unsaved changes (since it was opened or last downloaded). ` +
                      `Open ${file.name} and lose them?`)) return;
  clearError();
  studio.uploading = (studio.uploading || 0) + 1;
  try {
    const why = await post(route, file);
    if (why) showError(why);
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
// what the chosen format keeps: the server runs its writer on the current mesh (GET /losses/NAME.EXT)
const downloadName = () => {
  // the opened file's stem, with what no file name may hold (studio/security.py) as "_"
  const stem = (studio.name || "shapeflow-studio").replace(/\.[^.]*$/, "")
    .replace(/[\/\\"<>:|?*\p{Cc}\p{Cf}\p{Zl}\p{Zp}\p{Co}\p{Cn}]/gu, "_") || "shapeflow-studio";
  return `${stem}-studio.${$("format").value}`;
};
let noteAsked = 0;
async function formatNote() {
  const asked = ++noteAsked, note = $("format-note");
  const answer = await fetchJSON(`losses/${encodeURIComponent(downloadName())}`);
  if (asked !== noteAsked) return;                 // the menu changed meanwhile
  const lost = answer.losses || [];
  note.textContent = answer.error ? answer.error
    : lost.length ? `⚠ ${lost.join("; ")}` : `${answer.format} keeps all this mesh holds`;
  note.classList.toggle("keeps", !answer.error && !lost.length);
  studio.formatNote = note.textContent;
}
$("format").onchange = formatNote;
function formats(exts) {              // what the server reads and writes: the download list, the dialog's filter
  const sel = $("format"), keep = sel.value;
  if (sel.options.length !== exts.length) {
    sel.replaceChildren(...exts.map((e) => new Option(e, e)));
    if (exts.includes(keep)) sel.value = keep;
  }
  $("open-file").accept = exts.map((e) => "." + e).join(",");
}
$("download").onclick = async () => {
  clearError(); clearInfo();
  const name = downloadName();
  const [blob, why, lost] = await fetchFile(name);
  if (why) { showError(why); return; }
  studio.downloadLosses = lost;                    // what the server's writer dropped (its warnings)
  if (lost.length) showInfo(`${name} downloaded; ${lost.join("; ")}`);
  const a = document.createElement("a");
  a.href = URL.createObjectURL(blob); a.download = name; a.click();
  setTimeout(() => URL.revokeObjectURL(a.href), 10000);
};

// --- the keyboard: one table, the handler and the help overlay both read it ------------------------
const ctrl = (e) => e.ctrlKey || e.metaKey;
const code = (e, ...codes) => codes.includes(e.code);
const plain = (e) => !ctrl(e) && !e.altKey && !e.shiftKey;
const helpShown = () => $("help").classList.contains("shown");
const views = [["1", "front", "back"], ["3", "right", "left"], ["7", "top", "bottom"]];
export const SHORTCUTS = [
  { keys: "Ctrl+Z", what: "undo (a stroke is one step)", when: (e) => ctrl(e) && !e.shiftKey && code(e, "KeyZ"),
    run: undo },
  { keys: "Ctrl+Shift+Z · Ctrl+Y", what: "redo",
    when: (e) => ctrl(e) && (e.shiftKey ? code(e, "KeyZ") : code(e, "KeyY")), run: redo },
  ...views.flatMap(([k, a, b]) => [
    { keys: `Numpad ${k} · ${k}`, what: `${a} view (Blender's numpad ${k})`,
      when: (e) => plain(e) && code(e, `Numpad${k}`, `Digit${k}`), run: () => view.lookFrom(a) },
    { keys: `Ctrl+Numpad ${k} · Ctrl+${k}`, what: `${b} view`,
      when: (e) => ctrl(e) && !e.shiftKey && code(e, `Numpad${k}`, `Digit${k}`), run: () => view.lookFrom(b) }]),
  { keys: "Numpad 9 · 9", what: "the view from the opposite side", when: (e) => plain(e) && code(e, "Numpad9", "Digit9"),
    run: () => view.opposite() },
  { keys: "Numpad . · Home", what: "frame the model", when: (e) => code(e, "NumpadDecimal", "Home"),
    run: () => view.frameModel() },
  { keys: "[ · ]", what: "brush radius smaller · larger", when: (e) => plain(e) && code(e, "BracketLeft", "BracketRight"),
    run: (e) => tools.setRadius(Number($("radius").value) * (e.code === "BracketRight" ? 1.15 : 1 / 1.15)) },
  { keys: "Shift+[ · Shift+]", what: "brush strength lower · higher",
    when: (e) => e.shiftKey && !ctrl(e) && code(e, "BracketLeft", "BracketRight"),
    run: (e) => tools.setStrength(Number($("strength").value) + (e.code === "BracketRight" ? 0.05 : -0.05)) },
  { keys: "F", what: "brush radius with the pointer (click or Enter sets it, Esc or right click cancels)",
    when: (e) => plain(e) && code(e, "KeyF"), run: () => tools.startAdjust("radius") },
  { keys: "Shift+F", what: "brush strength with the pointer", when: (e) => e.shiftKey && !ctrl(e) && code(e, "KeyF"),
    run: () => tools.startAdjust("strength") },
  { keys: "X", what: "X symmetry (Mirror X) on · off: every dab also across the model's middle",
    when: (e) => plain(e) && code(e, "KeyX"), run: () => tools.toggleMirror() },
  { keys: "Enter · Esc", what: "set · cancel the radius or strength being adjusted; Esc closes this help",
    when: (e) => code(e, "Enter", "NumpadEnter", "Escape") && (tools.isAdjusting() || helpShown()),
    run: (e) => { if (!tools.endAdjust(e.code !== "Escape")) toggleHelp(false); } },
  { keys: "?", what: "this help", when: (e) => e.key === "?", run: () => toggleHelp() },
];
export const HELD = [
  ["Left drag on the model", "a stroke of the tool: one undo step (off the model, or with View: orbit)"],
  ["Ctrl while stroking", "invert: erase weights, smooth instead of enhance, deflate"],
  ["Shift while stroking", "smooth: the enhancement brush at +λ"],
  ["Right drag · wheel", "pan · zoom"],
];
function toggleHelp(on = !helpShown()) {
  if (on) {
    const row = (k, w) => `<tr><td>${k.split(" · ").map((x) => `<kbd>${x}</kbd>`).join(" ")}</td><td>${w}</td></tr>`;
    $("help").innerHTML = "<h3 style='margin-top:0'>Keyboard and mouse</h3><table>"
      + SHORTCUTS.map((s) => row(s.keys, s.what)).join("") + HELD.map(([k, w]) => row(k, w)).join("")
      + "</table><p>Numbers work on the main row too (most laptops have no numpad); browsers keep some "
      + "Ctrl+digit keys for their tabs: Numpad 9 or 9 turns any view around.</p>";
  }
  $("help").classList.toggle("shown", on);
}
$("help-button").onclick = () => toggleHelp();
studio.shortcuts = SHORTCUTS.map((s) => s.keys).concat(HELD.map(([k]) => k));
window.addEventListener("keydown", (e) => {
  const t = e.target, tag = t && t.tagName;
  const typing = (tag === "INPUT" && !["range", "checkbox", "button"].includes(t.type)) || tag === "SELECT"
                 || tag === "TEXTAREA";
  if (typing && e.code !== "Escape") return;
  for (const s of SHORTCUTS) {
    if (s.when(e)) { e.preventDefault(); s.run(e); studio.lastKey = s.keys; return; }
  }
});
