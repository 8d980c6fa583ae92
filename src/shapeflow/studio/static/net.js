// The connection to the studio's server: one WebSocket (protocol: studio/protocol.py), uploads and downloads.
import { studio, token } from "./state.js";

const ws = new WebSocket(`${location.protocol === "https:" ? "wss" : "ws"}://${location.host}/ws?token=`
                         + encodeURIComponent(token));
ws.binaryType = "arraybuffer";
export const authed = { "X-Shapeflow-Token": token };
const texts = {}, frames = {};
const answers = new Map();          // request id -> called with (ok, message) when this tab's request is answered
let seq = 0;

export const onText = (type, fn) => { texts[type] = fn; };
export const onFrame = (tag, fn) => { frames[tag] = fn; };

// send one message; `answered(ok, message)` when the server has handled it (its "done" or "error")
export function send(msg, answered = null) {
  if (ws.readyState !== WebSocket.OPEN) { if (answered) answered(false, { message: "not connected" }); return null; }
  const id = ++seq;
  answers.set(id, answered);
  studio.pending = answers.size;
  if (texts.sent) texts.sent(msg);
  if (studio.log) studio.log.push(msg);           // what the page sent, when a test or a script asks
  ws.send(JSON.stringify({ ...msg, id }));
  return id;
}
studio.send = (msg) => send(msg);

function answer(m) {
  if (!answers.has(m.id)) return;
  const fn = answers.get(m.id);
  answers.delete(m.id);
  studio.pending = answers.size;
  if (fn) fn(m.type === "done", m);
}

function receive(ev) {
  if (typeof ev.data === "string") {
    const m = JSON.parse(ev.data);
    if (m.type === "state" && m.resync) {        // the tab fell behind: the answers it waited for are gone
      const lost = [...answers.values()];
      answers.clear(); studio.pending = 0;
      for (const fn of lost) if (fn) fn(false, m);
    }
    if (texts[m.type]) texts[m.type](m);
    if ((m.type === "done" || m.type === "error") && m.id != null) answer(m);
    return;
  }
  const tag = new TextDecoder().decode(new Uint8Array(ev.data, 0, 4));
  if (frames[tag]) frames[tag](ev.data);
}
ws.onmessage = (ev) => {
  const t0 = performance.now();
  receive(ev);
  studio.work.ms += performance.now() - t0; studio.work.messages++;
};
ws.onclose = () => { if (texts.closed) texts.closed(); };

// POST a file to /open or /weights: null when it was taken, else the server's one-line reason
export async function post(route, file) {
  try {
    const r = await fetch(`/${route}?name=${encodeURIComponent(file.name)}`, { method: "POST", body: file,
                                                                             headers: authed });
    return r.ok ? null : (await r.text()).trim();
  } catch (err) {
    return `${file.name}: the upload failed (${err.message})`;
  }
}

// GET /download/NAME: [blob, null, what the format dropped] or [null, the reason, []]
export async function fetchFile(name) {
  try {
    const r = await fetch(`/download/${encodeURIComponent(name)}`, { headers: authed });
    if (!r.ok) return [null, (await r.text()).trim(), []];
    let lost = [];
    try { lost = JSON.parse(r.headers.get("X-Shapeflow-Warnings") || "[]"); } catch (err) { lost = []; }
    return [await r.blob(), null, lost];
  } catch (err) {
    return [null, `${name}: the download failed (${err.message})`, []];
  }
}
// GET a JSON answer (PATH without its leading "/"): the object, or {error: the reason}
export async function fetchJSON(path) {
  try {
    const r = await fetch(`/${path}`, { headers: authed });
    return r.ok ? await r.json() : { error: (await r.text()).trim() };
  } catch (err) {
    return { error: `the request failed (${err.message})` };
  }
}
