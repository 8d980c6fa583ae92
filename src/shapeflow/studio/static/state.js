// What the page's modules share: the element lookup, the page's address, and its state (window.studio,
// which tests and scripts read).
export const $ = (id) => document.getElementById(id);
export const query = new URLSearchParams(location.search);
// the token this page was opened with (?token=…): every request that changes something carries it
export const token = query.get("token") || "";

export const studio = {
  ready: false, lam: 0, version: 0, family: null, lams: [], frames: 0, error: null, pending: 0,
  modified: false, previewing: false, name: "", n: 0,
  // frames are drawn when something changed, not continuously: ?continuous=1 draws every frame (benchmarks)
  continuous: query.get("continuous") === "1",
  // latency of an edit: from the pointer event to the end of the first frame drawn with its answer
  editAt: null, awaitingFrame: null, latencies: [], queuedLatencies: [],
  work: { ms: 0, messages: 0 },         // time the page spends on messages (not drawing)
};
window.studio = studio;
