// simrun serve's edit mode (issue 40): the entity tree; a property pane built from the entity type's schema
// (GET /api/entities/NAME: every key that can change has a field, with its unit and default), and the settings
// of the services and sensors bound to it (their current values: service_settings, sensor_settings of the same
// answer); a "new entity" dialog built from the registry (GET /api/edit: type,
// name, parent, parameters with units and defaults); click a body in the 3D view to select its entity; move and
// rotate handles (three.js TransformControls); delete; save the scene; save / load entities; undo (the server's
// POST /api/edit/undo). After an edit that rebuilds the world the page loads /api/scene.glb again, so new and
// changed entities are drawn.
// Shown only when GET /api/edit says the server allows edits (simrun serve --edit; the server refuses edits
// with 403 otherwise). Runs after page.js, which hands it the view as window.simrunDashboard.view.
// window.simrunDashboard.edit = {ready, allowed, selected, item, entities, loads, edits, error, lastMove, ...}.
(function () {
  "use strict";
  const dash = window.simrunDashboard;
  const S = globalThis.SimrunThree;
  if (!dash || !dash.view || !S || !S.TransformControls) return; // the page stopped before its view existed
  const { THREE, GLTFLoader, TransformControls } = S;
  const v = dash.view;
  const $ = (id) => document.getElementById(id);
  const ed = (dash.edit = {
    ready: false, allowed: false, selected: null, item: null, entities: [], sensors: [], loads: 0,
    edits: 0, error: "", saved: "", lastMove: null, lastChange: null, undone: null, busy: 0,
  });
  let types = { entities: [], services: [], sensors: [] };

  const style = document.createElement("style");
  style.textContent = `
    #edit .edit-bar { display: flex; flex-wrap: wrap; gap: 6px; align-items: center; margin: 3px 0; }
    #edit-tree { margin: 4px 0; padding-left: 0; max-height: 170px; overflow-y: auto; background: #fff;
                 border: 1px solid #cdd3da; list-style: none; }
    #edit-tree ul { list-style: none; padding-left: 14px; margin: 0; }
    #edit-tree button { all: unset; display: block; width: 100%; box-sizing: border-box; padding: 1px 6px; cursor: pointer; }
    #edit-tree button:hover { background: #e8eef5; }
    #edit-tree button.selected { background: #2c6fbb; color: #fff; }
    #edit-tree .type { color: #6a7888; font-size: 11px; margin-left: 6px; }
    #edit-tree button.selected .type { color: #dbe8f7; }
    #edit-props fieldset { border: 1px solid #cdd3da; margin: 3px 0; padding: 2px 6px; }
    #edit-props legend, #edit-dialog legend { font-size: 12px; color: #4a5868; }
    #edit-props details { margin: 4px 0; }
    #edit .edit-head { margin: 6px 0 2px 0; } #edit .edit-pose { font-size: 12px; color: #4a5868; font-variant-numeric: tabular-nums; }
    .edit-row { display: flex; gap: 4px; align-items: center; margin: 2px 0; }
    .edit-row label { min-width: 104px; max-width: 104px; overflow: hidden; text-overflow: ellipsis; font-size: 12px; }
    .edit-row input[type=number], .edit-row input[type=text] { flex: 1; min-width: 0; width: 40px; }
    .edit-row input.default { color: #8a96a3; }
    #edit-message { font-size: 12px; min-height: 16px; white-space: pre-wrap; word-break: break-word; }
    #edit-message.error, #edit-dialog .error { color: #b52b27; }
    #edit .edit-off { font-size: 12px; color: #4a5868; }
    #edit-dialog { width: 380px; max-height: 85vh; overflow-y: auto; font: 13px/1.4 system-ui, sans-serif; }
    #edit-dialog .edit-row label { min-width: 120px; max-width: 120px; }
    #edit fieldset .edit-row label { min-width: 92px; max-width: 92px; }
  `;
  document.head.appendChild(style);
  const section = document.createElement("section");
  section.id = "edit";
  $("mode").after(section);

  const segments = (name) => name.split("/").map(encodeURIComponent).join("/");
  const entityPath = (name) => "/api/entities/" + segments(name);
  const message = (text, error) => {
    const box = $("edit-message");
    if (error) ed.error = text;
    if (box) { box.textContent = text; box.className = error ? "error" : ""; }
  };
  // An edit the server's budget refuses (429: too many edits, or edits took their share of the loop) did not
  // run: it is sent again after the Retry-After the server gives, a few times, before the page gives up.
  const RETRIES = 15; // a recompile that took 2 s spends the 20 % share for 10 s (simrun/serve/edit_routes.py Budget)
  async function call(method, path, body) {
    ed.busy += 1;
    try {
      for (let attempt = 0; ; attempt += 1) {
        try {
          return await v.api(method, path, body);
        } catch (error) {
          if (error.status !== 429 || attempt >= RETRIES) throw error;
          message("the server is busy: sending it again in " + Math.max(1, error.retryAfter) + " s");
          await new Promise((resolve) => setTimeout(resolve, 1000 * Math.max(1, error.retryAfter)));
        }
      }
    } catch (error) {
      message(error.message, true);
      throw error;
    } finally {
      ed.busy -= 1;
    }
  }

  // -- the scene: loaded again after an edit that rebuilt the world ----------------------------------------
  const loader = new GLTFLoader();
  const gltfRoot = () => v.scene.children.find((c) => c.getObjectByName && c.getObjectByName("simrun_world"));
  function dispose(object) {
    object.traverse((o) => {
      if (o.geometry) o.geometry.dispose();
      for (const m of [].concat(o.material || [])) { if (m.map) m.map.dispose(); m.dispose(); }
    });
  }
  async function reloadScene() {
    const response = await fetch("/api/scene.glb", { headers: v.headers(false) });
    if (!response.ok) throw new Error("/api/scene.glb: HTTP " + response.status);
    const buffer = await response.arrayBuffer();
    const gltf = await new Promise((resolve, reject) => loader.parse(buffer, "", resolve, reject));
    const world = gltf.scene.getObjectByName("simrun_world") || gltf.scene;
    const old = gltfRoot();
    tc.detach();
    if (old) {
      const oldWorld = old.getObjectByName("simrun_world") || old;
      for (const c of [...oldWorld.children]) if (c.isLineSegments) world.add(c); // the laser scans
      v.scene.remove(old);
      dispose(old);
    }
    v.scene.add(gltf.scene);
    v.bodies.clear();
    gltf.scene.traverse((o) => { if (o.userData && o.userData.simrun_body) v.bodies.set(o.userData.simrun_body, o); });
    for (const [name, p] of Object.entries(dash.poses)) {
      const node = v.bodies.get(name);
      if (node) { node.position.set(p[0], p[1], p[2]); node.quaternion.set(p[4], p[5], p[6], p[3]); }
    }
    ed.loads += 1;
    attachHandles();
  }

  // -- move and rotate handles ---------------------------------------------------------------------------
  const canvas = v.renderer.domElement;
  const tc = new TransformControls(v.camera, canvas);
  tc.setSpace("local"); // the body's own axes: X red, Y green, Z (up for an upright body) blue
  tc.setSize(0.9);
  v.scene.add(tc.getHelper());
  tc.addEventListener("dragging-changed", (event) => {
    v.controls.enabled = !event.value;
    if (event.value) dash.held = tc.object;
    else finishDrag();
  });
  function attachHandles() {
    const node = ed.item && ed.item.pose && v.bodies.get(ed.item.name);
    if (node && !dash.held) tc.attach(node);
    else if (!node) tc.detach();
  }
  const matrixOf = (p) => new THREE.Matrix4().compose(
    new THREE.Vector3(p[0], p[1], p[2]), new THREE.Quaternion(p[4], p[5], p[6], p[3]), new THREE.Vector3(1, 1, 1));
  async function finishDrag() {
    const node = tc.object, item = ed.item;
    if (!node || !item) { dash.held = null; return; }
    // the node's frame is the simulation's world (Z up, metres) under the page's Y-up root
    let m = new THREE.Matrix4().compose(node.position, node.quaternion, new THREE.Vector3(1, 1, 1));
    const parentPose = item.parent && dash.poses[item.parent];
    if (parentPose) m = matrixOf(parentPose).invert().multiply(m);
    const p = new THREE.Vector3(), q = new THREE.Quaternion(), s = new THREE.Vector3();
    m.decompose(p, q, s);
    const to = { position: [p.x, p.y, p.z], orientation: [q.w, q.x, q.y, q.z] };
    try {
      const answer = await call("POST", entityPath(item.name) + "/teleport", to);
      ed.lastMove = { name: item.name, sent: to, answer };
      message((tc.mode === "rotate" ? "turned " : "moved ") + item.name);
      await edited(answer.recompiled);
    } catch (error) {
      await refresh();
    } finally {
      dash.held = null;
    }
  }

  // -- click a body to select its entity -----------------------------------------------------------------
  const raycaster = new THREE.Raycaster();
  let down = null;
  canvas.addEventListener("pointerdown", (e) => { down = { x: e.clientX, y: e.clientY, handle: tc.dragging }; });
  canvas.addEventListener("pointerup", (e) => {
    const click = down && !down.handle && Math.hypot(e.clientX - down.x, e.clientY - down.y) < 5;
    down = null;
    if (click && ed.allowed) pick(e.clientX, e.clientY);
  });
  const shown = (o) => { for (; o; o = o.parent) if (!o.visible) return false; return true; };
  function entityOf(body) {
    let best = null;
    for (const e of ed.entities) {
      if ((body === e.name || body.startsWith(e.name + "/")) && (!best || e.name.length > best.length)) best = e.name;
    }
    return best;
  }
  function pick(clientX, clientY) {
    const rect = canvas.getBoundingClientRect();
    const at = new THREE.Vector2(((clientX - rect.left) / rect.width) * 2 - 1, -((clientY - rect.top) / rect.height) * 2 + 1);
    raycaster.setFromCamera(at, v.camera);
    const root = gltfRoot();
    if (!root) return;
    for (const hit of raycaster.intersectObject(root, true)) {
      if (!hit.object.isMesh || !shown(hit.object)) continue;
      let o = hit.object;
      while (o && !(o.userData && o.userData.simrun_body)) o = o.parent;
      const name = o && entityOf(o.userData.simrun_body);
      if (name) { select(name); return; }
    }
    select(null);
  }
  // for scripts and tests: where a simulation point [x, y, z] (world, m) is on the view, in CSS pixels
  const yUpRoot = () => { const r = gltfRoot(); return r && (r.getObjectByName("simrun_world") || r); };
  ed.screenOf = (point) => {
    const root = yUpRoot();
    if (!root) return null;
    root.updateMatrixWorld();
    v.camera.updateMatrixWorld();
    const w = new THREE.Vector3(point[0], point[1], point[2]).applyMatrix4(root.matrixWorld).project(v.camera);
    return [(w.x + 1) / 2 * v.element.clientWidth, (1 - w.y) / 2 * v.element.clientHeight, w.z];
  };
  ed.bodyNames = () => [...v.bodies.keys()];
  // where the handle for `axis` ("X", "Y", "Z", "XY"...) of the current mode is on the view, in CSS px
  ed.handleAt = (axis) => {
    if (!tc.object) return null;
    v.scene.updateMatrixWorld();
    const mesh = tc._gizmo.picker[tc.mode].children.find((m) => m.name === axis);
    if (!mesh) return null;
    // move: the centre of the arrow's picker; rotate X/Y/Z: a point of the ring (r180's pickers: radius 0.5)
    mesh.geometry.computeBoundingBox();
    const local = tc.mode === "rotate"
      ? new THREE.Vector3().fromBufferAttribute(mesh.geometry.attributes.position, 0).setLength(0.5)
      : mesh.geometry.boundingBox.getCenter(new THREE.Vector3());
    const centre = local.applyMatrix4(mesh.matrixWorld).project(v.camera);
    return [(centre.x + 1) / 2 * v.element.clientWidth, (1 - centre.y) / 2 * v.element.clientHeight];
  };

  // -- forms from a schema: one field per key (units, defaults, descriptions) -------------------------------
  function inputs(key, value) {
    const t = key.type;
    const count = /^(\d+) (numbers|integers)$/.exec(t);
    const number = (x, path) => {
      const i = document.createElement("input");
      i.type = "number";
      i.step = "any";
      i.dataset.key = path;
      if (x !== null && x !== undefined) i.value = String(x);
      return i;
    };
    const finite = (text, name) => {
      const x = Number(text);
      if (text.trim() === "" || !Number.isFinite(x)) throw new Error(name + ": expected a number");
      return x;
    };
    if (t === "number" || t === "integer") {
      const i = number(value, key.name);
      if (value === null || value === undefined) i.placeholder = "default";
      return { elements: [i], read: () => (i.value.trim() === "" ? undefined : finite(i.value, key.name)) };
    }
    if (count) {
      const n = parseInt(count[1], 10);
      const list = Array.from({ length: n }, (_, k) => number(Array.isArray(value) ? value[k] : null, key.name + "[" + k + "]"));
      return { elements: list, read: () => list.map((i, k) => finite(i.value, key.name + "[" + k + "]")) };
    }
    const i = document.createElement("input");
    i.dataset.key = key.name;
    if (t === "boolean") {
      i.type = "checkbox";
      i.checked = !!value;
      return { elements: [i], read: () => i.checked };
    }
    i.type = "text";
    if (t === "string") {
      if (value !== null && value !== undefined) i.value = String(value);
      return { elements: [i], read: () => (i.value === "" ? undefined : i.value) };
    }
    // lists and tables of other shapes: JSON text
    i.value = value === null || value === undefined ? "" : JSON.stringify(value);
    i.placeholder = t + " (JSON)";
    return { elements: [i], read: () => (i.value.trim() === "" ? undefined : JSON.parse(i.value)) };
  }
  // rows for `keys` showing `current` (a scene table; a key it lacks shows its default, greyed);
  // onSet(["material", "dynamic_friction"], 0.3) when a field changes
  function form(keys, current, onSet) {
    const box = document.createElement("div");
    for (const key of keys) {
      const short = key.name.split(".").pop();
      const have = current && current[short] !== undefined && current[short] !== null;
      if (key.type === "table" && key.fields) {
        const group = document.createElement("fieldset");
        const legend = document.createElement("legend");
        legend.textContent = short;
        legend.title = key.description || "";
        group.appendChild(legend);
        const inner = have ? current[short] : (key.default && typeof key.default === "object" ? key.default : {});
        group.appendChild(form(key.fields, inner, (path, value) => onSet([short, ...path], value)));
        box.appendChild(group);
        continue;
      }
      const row = document.createElement("div");
      row.className = "edit-row";
      row.title = (key.description || "") + (key.default !== null && key.default !== undefined ? " Default: " + JSON.stringify(key.default) : "");
      const label = document.createElement("label");
      label.textContent = short + (key.unit ? " (" + key.unit + ")" : "") + (key.required ? " *" : "");
      row.appendChild(label);
      const field = inputs(key, have ? current[short] : key.default);
      for (const e of field.elements) {
        if (!have) e.classList.add("default");
        row.appendChild(e);
        e.addEventListener("change", () => {
          let value;
          try {
            value = field.read();
          } catch (error) {
            message(error.message, true);
            return;
          }
          if (value === undefined) return;
          for (const other of field.elements) other.classList.remove("default");
          onSet([short], value);
        });
      }
      box.appendChild(row);
    }
    return box;
  }
  const nested = (path, value) => path.reduceRight((inner, k) => ({ [k]: inner }), value);

  // -- undo: the server keeps the inverse of each edit (POST /api/edit/undo), whoever made it ----------------
  async function undo() {
    try {
      const answer = await call("POST", "/api/edit/undo", {});
      ed.undone = answer;
      message("undid the last edit (" + answer.undone + ")");
      await edited(true);
    } catch (error) {
      await refresh();
    }
  }

  // -- the tree, the pane ---------------------------------------------------------------------------------
  async function refresh() {
    ed.entities = await call("GET", "/api/entities");
    ed.sensors = await call("GET", "/api/sensors");
    if (ed.selected && !ed.entities.some((e) => e.name === ed.selected)) { ed.selected = null; ed.item = null; }
    renderTree();
    await renderPane();
  }
  async function edited(structural) {
    ed.edits += 1;
    if (structural) await reloadScene();
    await refresh();
  }
  function renderTree() {
    const tree = $("edit-tree");
    tree.innerHTML = "";
    const known = new Set(ed.entities.map((e) => e.name));
    const below = new Map();
    for (const e of ed.entities) {
      const up = e.parent && known.has(e.parent) ? e.parent : "";
      if (!below.has(up)) below.set(up, []);
      below.get(up).push(e);
    }
    const add = (list, parent) => {
      for (const e of below.get(parent) || []) {
        const li = document.createElement("li");
        const b = document.createElement("button");
        b.type = "button";
        b.dataset.name = e.name;
        if (e.name === ed.selected) b.className = "selected";
        b.textContent = parent ? e.name.slice(parent.length + 1) : e.name;
        const kind = document.createElement("span");
        kind.className = "type";
        kind.textContent = e.type + (e.robot ? ", robot" : "");
        b.appendChild(kind);
        b.addEventListener("click", () => select(e.name));
        li.appendChild(b);
        if (below.has(e.name)) {
          const sub = document.createElement("ul");
          add(sub, e.name);
          li.appendChild(sub);
        }
        list.appendChild(li);
      }
    };
    add(tree, "");
    $("edit-delete").disabled = !ed.selected;
    $("edit-save-selection").disabled = !ed.selected;
  }
  async function select(name) {
    ed.selected = name;
    ed.item = null;
    renderTree();
    await renderPane();
  }
  async function renderPane() {
    const pane = $("edit-props");
    const name = ed.selected;
    if (!name) { pane.innerHTML = ""; ed.item = null; attachHandles(); return; }
    const item = await call("GET", entityPath(name));
    if (ed.selected !== name) return; // another selection meanwhile
    ed.item = item;
    pane.innerHTML = "";
    const head = document.createElement("div");
    head.className = "edit-head";
    head.innerHTML = "<b></b> <span></span>";
    head.querySelector("b").textContent = item.name;
    head.querySelector("span").textContent = item.type + (item.parent ? " in " + item.parent : "") + " - " + (item.schema.summary || "");
    pane.appendChild(head);
    if (item.pose) {
      const pose = document.createElement("div");
      pose.className = "edit-pose";
      pose.textContent = "world position " + item.pose.slice(0, 3).map((x) => x.toFixed(3)).join(", ") + " m" +
        (item.parent ? " (the pose below is relative to " + item.parent + ")" : "");
      pane.appendChild(pose);
    }
    const fixed = new Set([...(item.schema.fixed || []), "name", "parent"]);
    const keys = item.schema.keys.filter((k) => !fixed.has(k.name));
    // a top-level body's pose fields show where it is now (its table keeps where it started)
    const shownValues = { ...item.values };
    const round = (list) => list.map((x) => Math.round(x * 1e6) / 1e6);
    if (!item.parent && item.pose) shownValues.pose = { position: round(item.pose.slice(0, 3)), orientation: round(item.pose.slice(3, 7)) };
    pane.appendChild(form(keys, shownValues, (path, value) => changeEntity(item, path, value)));
    const serviceNow = item.service_settings || {}, sensorNow = item.sensor_settings || {};
    for (const kind of item.services || []) {
      const schema = types.services.find((t) => t.type === kind);
      if (schema) pane.appendChild(binding("service:" + kind, "service " + kind, schema, serviceNow[kind],
        "/api/edit/services/" + kind + "/" + segments(item.name)));
    }
    for (const sensor of item.sensors || []) {
      const known = ed.sensors.find((s) => s.name === sensor);
      const schema = known && types.sensors.find((t) => t.type === known.type);
      if (schema) pane.appendChild(binding("sensor:" + sensor, "sensor " + sensor + " (" + known.type + ")", schema,
        sensorNow[sensor], "/api/edit/sensors/" + encodeURIComponent(sensor)));
    }
    attachHandles();
  }
  // a service's or sensor's settings: `current` is its table now (a key it lacks shows its default, greyed);
  // a settings box left open stays open when the pane is built again after a change
  const opened = new Set();
  function binding(id, title, schema, current, path) {
    const box = document.createElement("details");
    box.dataset.binding = id;
    box.open = opened.has(id);
    box.addEventListener("toggle", () => { if (box.open) opened.add(id); else opened.delete(id); });
    const summary = document.createElement("summary");
    summary.textContent = title;
    box.appendChild(summary);
    const fixed = new Set(schema.fixed || []);
    const keys = schema.keys.filter((k) => !fixed.has(k.name));
    box.appendChild(form(keys, current || {}, async (keyPath, value) => {
      try {
        await call("PATCH", path, nested(keyPath, value));
        message("changed " + title + " " + keyPath.join("."));
        await edited(false);
      } catch (error) {
        await renderPane(); // the refusal is shown; the fields show the values the server kept
      }
    }));
    return box;
  }
  async function changeEntity(item, path, value) {
    const name = item.name;
    try {
      const answer = await call("PATCH", entityPath(name), nested(path, value));
      message("changed " + name + " " + path.join("."));
      ed.lastChange = { name, path, value, answer };
      await edited(true);
    } catch (error) {
      await renderPane();
    }
  }

  // -- toolbar ------------------------------------------------------------------------------------------
  function download(text, file) {
    const a = document.createElement("a");
    a.href = URL.createObjectURL(new Blob([text], { type: "application/toml" }));
    a.download = file;
    document.body.appendChild(a);
    a.click();
    setTimeout(() => { URL.revokeObjectURL(a.href); a.remove(); }, 1000);
  }
  async function remove() {
    const name = ed.selected;
    if (!name) return;
    try {
      await call("DELETE", entityPath(name), {});
      message("deleted " + name);
      ed.selected = null;
      ed.item = null;
      await edited(true);
    } catch (error) { /* shown */ }
  }
  async function saveScene() {
    try {
      const answer = await call("POST", "/api/edit/save", { state: "current" });
      ed.saved = answer.toml;
      download(answer.toml, "scene.toml");
      message("saved the scene as it is now (scene.toml, " + answer.toml.split("\n").length + " lines)");
    } catch (error) { /* shown */ }
  }
  async function saveSelection() {
    if (!ed.selected) return;
    try {
      const answer = await call("POST", "/api/edit/save-entities", { names: [ed.selected] });
      ed.saved = answer.toml;
      download(answer.toml, ed.selected.replaceAll("/", "_") + ".toml");
      message("saved " + ed.selected + " and its children, services and sensors");
    } catch (error) { /* shown */ }
  }
  async function loadEntities(file) {
    try {
      const answer = await call("POST", "/api/edit/load-entities", { toml: await file.text() });
      const added = (answer.added && answer.added.entities) || [];
      message("loaded " + (added.join(", ") || "nothing"));
      await edited(true);
    } catch (error) { /* shown */ }
  }

  // -- the "new entity" dialog ------------------------------------------------------------------------------
  const dialog = document.createElement("dialog");
  dialog.id = "edit-dialog";
  dialog.innerHTML = `
    <h3 style="margin:0 0 6px 0">New entity</h3>
    <div class="edit-row"><label for="edit-new-type">type</label><select id="edit-new-type"></select></div>
    <div id="edit-new-summary" class="edit-pose"></div>
    <div class="edit-row"><label for="edit-new-name">name *</label><input id="edit-new-name" type="text"></div>
    <div class="edit-row"><label for="edit-new-parent">parent</label><select id="edit-new-parent"></select></div>
    <div id="edit-new-params"></div>
    <div id="edit-new-error" class="error"></div>
    <div class="edit-bar"><button id="edit-new-insert" type="button">Insert</button>
      <button id="edit-new-cancel" type="button">Cancel</button></div>`;
  let table = {};
  function freeName(kind) {
    const stem = kind.toLowerCase();
    for (let k = 1; ; k++) if (!ed.entities.some((e) => e.name === stem + k)) return stem + k;
  }
  function fillParams() {
    const schema = types.entities.find((t) => t.type === $("edit-new-type").value);
    const params = $("edit-new-params");
    params.innerHTML = "";
    table = {};
    if (!schema) return;
    $("edit-new-summary").textContent = schema.summary || "";
    $("edit-new-name").value = freeName(schema.type);
    const keys = schema.keys.filter((k) => k.name !== "name" && k.name !== "parent");
    if (keys.some((k) => k.name === "pose")) {
      // in front of the camera: the orbit target (the page's Y-up frame) a little above the ground
      const t = v.controls.target;
      table.pose = { position: [+t.x.toFixed(3), +(-t.z).toFixed(3), +Math.max(0.3, t.y + 0.3).toFixed(3)] };
    }
    params.appendChild(form(keys, table, (path, value) => {
      let at = table;
      for (const k of path.slice(0, -1)) at = at[k] = at[k] && typeof at[k] === "object" ? at[k] : {};
      at[path[path.length - 1]] = value;
    }));
  }
  function openDialog() {
    const kinds = $("edit-new-type");
    if (!kinds.options.length) for (const t of types.entities) kinds.add(new Option(t.type, t.type));
    const parent = $("edit-new-parent");
    parent.innerHTML = "";
    parent.add(new Option("(the world)", ""));
    for (const e of ed.entities.filter((e) => e.pose)) parent.add(new Option(e.name, e.name));
    $("edit-new-error").textContent = "";
    fillParams();
    dialog.showModal();
  }
  async function insert() {
    const entity = { type: $("edit-new-type").value, name: $("edit-new-name").value.trim(), ...table };
    const body = { entity };
    if ($("edit-new-parent").value) body.parent = $("edit-new-parent").value;
    try {
      const answer = await v.api("POST", "/api/entities", body);
      dialog.close();
      const names = answer.inserted || [];
      message("inserted " + names.join(", "));
      ed.selected = names[0] || null;
      await edited(true);
    } catch (error) {
      $("edit-new-error").textContent = error.message;
      ed.error = error.message;
    }
  }

  // -- start: only when the server allows edits --------------------------------------------------------------
  function start(info) {
    ed.allowed = !!info.allowed;
    if (!ed.allowed) {
      section.innerHTML = '<h2>Edit</h2><div class="edit-off">editing is off: start the server with <code>simrun serve --edit</code></div>';
      tc.detach();
      tc.enabled = false;
      ed.ready = true;
      return;
    }
    types = info.types;
    section.innerHTML = `
      <h2>Edit</h2>
      <div class="edit-bar">
        <button id="edit-new" type="button">New entity</button>
        <button id="edit-delete" type="button" disabled>Delete</button>
        <button id="edit-undo" type="button" title="undo the server's last edit (POST /api/edit/undo)">Undo</button>
        <button id="edit-save" type="button" title="the world as it is now, as scene TOML">Save scene</button>
      </div>
      <div class="edit-bar">
        <label><input type="radio" name="edit-mode" value="translate" checked> move</label>
        <label><input type="radio" name="edit-mode" value="rotate"> rotate</label>
        <button id="edit-save-selection" type="button" disabled title="the selected entity with its children, services and sensors">Save entity</button>
        <label title="insert the entities of a saved entities file">load <input id="edit-load" type="file" accept=".toml" style="width:92px"></label>
      </div>
      <ul id="edit-tree"></ul>
      <div id="edit-message"></div>
      <div id="edit-props"></div>`;
    document.body.appendChild(dialog);
    $("edit-new").addEventListener("click", openDialog);
    $("edit-delete").addEventListener("click", remove);
    $("edit-undo").addEventListener("click", undo);
    $("edit-save").addEventListener("click", saveScene);
    $("edit-save-selection").addEventListener("click", saveSelection);
    $("edit-load").addEventListener("change", (e) => { if (e.target.files[0]) loadEntities(e.target.files[0]); e.target.value = ""; });
    for (const r of section.querySelectorAll("input[name=edit-mode]")) r.addEventListener("change", (e) => tc.setMode(e.target.value));
    $("edit-new-type").addEventListener("change", fillParams);
    $("edit-new-insert").addEventListener("click", insert);
    $("edit-new-cancel").addEventListener("click", () => dialog.close());
    // the tree replaces the plain entity list
    const list = $("entities");
    if (list) { list.style.display = "none"; if (list.previousElementSibling) list.previousElementSibling.style.display = "none"; }
    refresh().catch(() => {}).finally(() => { ed.ready = true; });
  }
  function whenReady(tries) {
    if (!dash.ready) { setTimeout(() => whenReady(tries), 100); return; }
    v.api("GET", "/api/edit").then(start).catch((error) => {
      if (tries > 1) { setTimeout(() => whenReady(tries - 1), 500); return; } // a dropped connection: again
      section.innerHTML = "<h2>Edit</h2>";
      section.appendChild(document.createTextNode("edit mode: " + error.message));
      ed.error = error.message;
      ed.ready = true;
    });
  }
  whenReady(5);
})();
