// ShapeFlow Studio's page: three.js view of the session the server holds (protocol: studio/protocol.py).
// Modules: state.js (shared state), net.js (the connection), view.js (scene, camera, drawing),
// tools.js (strokes, brush circles, radius and strength), panel.js (controls, status, keyboard).
import { studio } from "./state.js";
import { onFrame, onText } from "./net.js";
import * as panel from "./panel.js";
import * as tools from "./tools.js";
import * as view from "./view.js";
import "./sharp.js";      // the "Keep sharp edges" control and the sharp edges drawn

onText("mesh", (m) => { view.newMesh(m); panel.newMesh(m); });
onText("state", (m) => panel.state(m));
onText("field", (m) => view.setField(m));
onText("orientation", (m) => panel.orientation(m));
onText("error", (m) => panel.showError(m.message));
// a new request clears the last error and information (the λ slider's and colour requests do not: they
// follow the view)
onText("sent", (m) => {
  if (!["lam", "field", "begin", "end"].includes(m.op)) { panel.clearError(); panel.clearInfo(); }
});
onText("closed", () => panel.showError("disconnected: restart shapeflow studio and reload the page"));
onFrame("TRI0", view.setTriangles);
onFrame("EDG0", view.setEdges);
onFrame("BAS0", view.setBase);
onFrame("POS0", (buf) => {
  const first = !view.mesh.geometry;
  view.setPositions(buf);
  if (first) tools.newMesh(view.mesh.geometry.boundingSphere.radius);
});
onFrame("PSUB", view.setSomePositions);
onFrame("WGT0", view.setWeights);
onFrame("FLD0", view.setFieldValues);
tools.toolChanged();
studio.modules = ["state", "net", "view", "tools", "panel", "app"];
