// simrun serve's dashboard: the live world in three.js (the replay page's bundle, inlined before this
// script), moved by the server's WebSocket stream; teleoperation, service calls, pause/step/reset, the
// rate, recording, laser scans drawn in the scene and camera panels. Everything comes from this server.
// window.simrunDashboard = {ready, time, poses, laserUpdates, imageUpdates, teleop, screen(body)} for scripts.
(function () {
  "use strict";
  const { THREE, GLTFLoader, OrbitControls } = globalThis.SimrunThree;
  const config = JSON.parse(document.getElementById("simrun-config").textContent);
  const catalogue = config.catalogue;
  const $ = (id) => document.getElementById(id);
  const status = $("status");
  const fail = (message) => {
    status.textContent = "error: " + message;
    document.documentElement.dataset.state = "error";
  };
  const dash = (window.simrunDashboard = {
    ready: false, time: 0, poses: {}, laserUpdates: 0, imageUpdates: 0, teleop: [0, 0], screen: () => null,
  });

  // -- access: ?token=... once, then kept for this tab ------------------------------------------------------
  const query = new URLSearchParams(location.search);
  if (query.get("token")) sessionStorage.setItem("simrun-token", query.get("token"));
  const token = config.token ? sessionStorage.getItem("simrun-token") || "" : "";
  const headers = (json) => {
    const h = {};
    if (json) h["Content-Type"] = "application/json";
    // percent-encoded: fetch sends only latin-1 header text; the server decodes it (any printable token works)
    if (token) h["Authorization"] = "Bearer " + encodeURIComponent(token);
    return h;
  };
  async function api(method, path, body) {
    const response = await fetch(path, {
      method, headers: headers(body !== undefined), body: body === undefined ? undefined : JSON.stringify(body),
    });
    const answer = await response.json().catch(() => ({ error: "HTTP " + response.status }));
    if (!response.ok) {
      const error = new Error((answer.field ? answer.field + ": " : "") + answer.error);
      error.status = response.status; // 429 / 503 come with Retry-After (seconds): the request did not run
      error.retryAfter = Number(response.headers.get("Retry-After")) || 0;
      throw error;
    }
    return answer;
  }

  // -- the 3D view (Z-up world under a Y-up root, as the replay page) ---------------------------------------
  const view = $("view");
  let renderer;
  try {
    renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
  } catch (error) {
    fail("this browser cannot start WebGL (" + error.message + ")");
    return;
  }
  renderer.setPixelRatio(window.devicePixelRatio || 1);
  renderer.outputColorSpace = THREE.SRGBColorSpace;
  view.appendChild(renderer.domElement);
  const scene = new THREE.Scene();
  scene.background = new THREE.Color("#dde4ec");
  scene.add(new THREE.HemisphereLight(0xffffff, 0x8a8a80, 1.6));
  const sun = new THREE.DirectionalLight(0xffffff, 1.8);
  sun.position.set(3, 10, 6);
  scene.add(sun);
  const camera = new THREE.PerspectiveCamera(40, 1, 0.01, 500);
  const controls = new OrbitControls(camera, renderer.domElement);
  const yUp = (p) => new THREE.Vector3(p[0], p[2], -p[1]);
  function frameOn(poses) {
    const robots = catalogue.entities.filter((e) => e.robot && poses[e.root]).map((e) => poses[e.root]);
    const points = robots.length ? robots : Object.values(poses);
    const c = [0, 0, 0];
    for (const p of points) for (let k = 0; k < 3; k++) c[k] += p[k] / Math.max(1, points.length);
    const target = yUp(c);
    const from = new THREE.Vector3(-0.45, 0.85, 1.0).normalize().multiplyScalar(2.2);
    camera.position.copy(target).add(from);
    controls.target.copy(target);
    controls.update();
  }
  function resize() {
    const w = view.clientWidth, h = view.clientHeight;
    renderer.setSize(w, h, false);
    camera.aspect = w / Math.max(1, h);
    camera.updateProjectionMatrix();
  }
  window.addEventListener("resize", resize);
  resize();

  const bodies = new Map();
  let root = null;
  const labels = [];
  function applyPoses(poses) {
    dash.poses = poses;
    for (const [name, p] of Object.entries(poses)) {
      const node = bodies.get(name);
      if (!node || node === dash.held) continue;  // dash.held: a body edit mode is dragging
      node.position.set(p[0], p[1], p[2]);
      node.quaternion.set(p[4], p[5], p[6], p[3]);
    }
  }
  const where = new THREE.Vector3();
  dash.screen = (name) => {
    const node = bodies.get(name);
    if (!node) return null;
    node.getWorldPosition(where);
    camera.updateMatrixWorld();  // before the first frame is drawn, the camera's inverse matrix is still stale
    where.project(camera);
    return [(where.x + 1) / 2 * view.clientWidth, (1 - where.y) / 2 * view.clientHeight, where.z];
  };

  // -- laser scans, drawn from the laser's mounting point in its body's plane ------------------------------
  const lasers = new Map();
  for (const s of catalogue.sensors.filter((s) => s.height !== undefined)) {
    const geometry = new THREE.BufferGeometry();
    const line = new THREE.LineSegments(geometry, new THREE.LineBasicMaterial({ color: 0xd62728 }));
    line.frustumCulled = false;
    lasers.set(s.name, { sensor: s, line, geometry });
  }
  function drawLaser(name, reading) {
    const item = lasers.get(name);
    const pose = item && dash.poses[item.sensor.entity];
    if (!pose || !reading || !reading.ranges) return;
    const q = new THREE.Quaternion(pose[4], pose[5], pose[6], pose[3]);
    const origin = new THREE.Vector3(0, 0, item.sensor.height).applyQuaternion(q).add(new THREE.Vector3(pose[0], pose[1], pose[2]));
    const points = new Float32Array(reading.ranges.length * 6);
    const ray = new THREE.Vector3();
    reading.ranges.forEach((r, k) => {
      const range = r === null ? item.sensor.max_range : r;
      const a = reading.angles[k];
      ray.set(Math.cos(a) * range, Math.sin(a) * range, 0).applyQuaternion(q).add(origin);
      points.set([origin.x, origin.y, origin.z, ray.x, ray.y, ray.z], k * 6);
    });
    item.geometry.setAttribute("position", new THREE.BufferAttribute(points, 3));
    item.geometry.computeBoundingSphere();
    dash.laserUpdates += 1;
  }

  // -- the side panel ----------------------------------------------------------------------------------------
  for (const e of catalogue.entities) {
    const li = document.createElement("li");
    li.textContent = e.name + " (" + e.type + (e.robot ? ", robot" : "") + ")";
    $("entities").appendChild(li);
  }
  const cameras = catalogue.sensors.filter((s) => s.image);
  for (const s of cameras) {
    const box = document.createElement("div");
    box.className = "camera";
    box.innerHTML = "<span></span><img alt=''>";
    box.querySelector("span").textContent = s.name;
    box.querySelector("img").id = "camera-" + s.name;
    box.querySelector("img").alt = "camera " + s.name;
    $("cameras").appendChild(box);
  }
  if (!cameras.length) $("cameras").textContent = "no camera sensors";
  const result = $("result");
  const show = (text, error) => { result.textContent = text; result.className = error ? "error" : ""; };
  const run = (promise) => promise.then((a) => { show(JSON.stringify(a, null, 1).slice(0, 2000)); return a; })
    .catch((e) => show(e.message, true));

  // for edit mode (edit_page.js, the next script): the view and this page's requests
  dash.view = { scene, camera, renderer, controls, bodies, api, headers, show, catalogue, element: view };
  let paused = false;
  $("pause").addEventListener("click", () => run(api("POST", paused ? "/api/resume" : "/api/pause", {})).then(state));
  $("step").addEventListener("click", () => run(api("POST", "/api/step", { seconds: 0.02 })).then(state));
  $("reset").addEventListener("click", () => run(api("POST", "/api/reset", {})).then(state));
  $("rate").addEventListener("change", (e) => run(api("POST", "/api/rate", { rate: parseFloat(e.target.value) })));
  $("record-start").addEventListener("click", () => run(api("POST", "/api/recording/start", {})).then(state));
  $("record-stop").addEventListener("click", () => run(api("POST", "/api/recording/stop", {})).then(state));
  function state(s) {
    if (!s || s.time === undefined) return;
    paused = s.paused;
    $("pause").textContent = s.paused ? "Resume" : "Pause";
    $("mode").textContent = s.mode + (s.paused ? ", paused" : "") + " - rate " + s.rate +
      (s.measured_rate ? " (measured " + s.measured_rate.toFixed(2) + ")" : "");
    $("rate").value = String(s.rate);
    const r = s.recording;
    $("record-state").textContent = r ? (r.active ? "recording " : "wrote ") + r.path : "";
    $("record-start").disabled = !config.recording || (r && r.active);
    $("record-stop").disabled = !(r && r.active);
    $("step").disabled = !(s.paused || s.mode === "lockstep");
    if (s.poses) applyPoses(s.poses);
  }
  setInterval(() => api("GET", "/api/state").then(state).catch(() => {}), 1000);

  // service calls: arguments from each command's schema
  const services = catalogue.services;
  services.forEach((s, k) => $("service").add(new Option(s.type + " / " + s.entity, String(k))));
  function fillCommands() {
    const s = services[parseInt($("service").value, 10)];
    $("command").innerHTML = "";
    if (s) Object.keys(s.commands).forEach((c) => $("command").add(new Option(c, c)));
    fillArgs();
  }
  function fillArgs() {
    const s = services[parseInt($("service").value, 10)];
    $("args").innerHTML = "";
    if (!s) return;
    for (const p of s.commands[$("command").value].parameters) {
      const row = document.createElement("div");
      row.className = "arg";
      const label = document.createElement("label");
      label.textContent = p.name;
      const input = document.createElement("input");
      input.dataset.name = p.name;
      input.dataset.type = p.schema.type || "string";
      if (input.dataset.type === "boolean") input.type = "checkbox";
      if (p.default !== undefined) input.value = String(p.default);
      input.placeholder = input.dataset.type === "array" ? "comma-separated numbers" : input.dataset.type;
      label.appendChild(input);
      row.appendChild(label);
      $("args").appendChild(row);
    }
  }
  $("service").addEventListener("change", fillCommands);
  $("command").addEventListener("change", fillArgs);
  $("call").addEventListener("click", () => {
    const s = services[parseInt($("service").value, 10)];
    if (!s) return;
    const args = {};
    for (const input of $("args").querySelectorAll("input")) {
      const t = input.dataset.type, v = input.value.trim();
      if (t === "boolean") args[input.dataset.name] = input.checked;
      else if (v === "") continue;
      else if (t === "number" || t === "integer") args[input.dataset.name] = Number(v);
      else if (t === "array") args[input.dataset.name] = v.split(",").map(Number);
      else args[input.dataset.name] = v;
    }
    run(api("POST", s.path + "/" + $("command").value, { args }));
  });
  fillCommands();

  // teleoperation of the robots with wheels and a DriveService (the catalogue's teleop list, from the robot
  // contract): cmd_vel, re-sent while it is not zero (it expires after 0.5 s)
  const teleop = catalogue.teleop || [];
  const drives = teleop.map((name) => services.find((s) => s.type === "DriveService" && s.entity === name));
  drives.forEach((s, k) => $("robot").add(new Option(s.entity, String(k))));
  let linear = 0, angular = 0;
  function send() {
    const s = drives[parseInt($("robot").value, 10)];
    if (!s) return;
    dash.teleop = [linear, angular];
    $("teleop-state").textContent = "v " + linear.toFixed(2) + " m/s, w " + angular.toFixed(2) + " rad/s";
    const path = s.path + (linear || angular ? "/cmd_vel" : "/all_stop");
    api("POST", path, { args: linear || angular ? [linear, angular] : [] }).catch((e) => show(e.message, true));
  }
  function drive(action) {
    if (action === "stop") { linear = 0; angular = 0; }
    else if (action === "forward") linear = Math.min(0.5, linear + 0.05);
    else if (action === "back") linear = Math.max(-0.5, linear - 0.05);
    else if (action === "left") angular = Math.min(3, angular + 0.5);
    else if (action === "right") angular = Math.max(-3, angular - 0.5);
    linear = Math.round(linear * 100) / 100;
    send();
  }
  for (const action of ["forward", "back", "left", "right", "stop"]) {
    $("pad-" + action).addEventListener("click", () => drive(action));
  }
  if (!drives.length) for (const b of $("pad").querySelectorAll("button")) b.disabled = true;
  const keys = { ArrowUp: "forward", KeyW: "forward", ArrowDown: "back", KeyS: "back", ArrowLeft: "left",
    KeyA: "left", ArrowRight: "right", KeyD: "right", Space: "stop" };
  window.addEventListener("keydown", (e) => {
    const tag = e.target && e.target.tagName;
    if (tag === "INPUT" || tag === "SELECT" || tag === "TEXTAREA" || !keys[e.code]) return;
    e.preventDefault();
    drive(keys[e.code]);
  });
  setInterval(() => { if (linear || angular) send(); }, 200);

  // -- the stream ----------------------------------------------------------------------------------------------
  function connect() {
    const q = new URLSearchParams({ poses: "1", sensors: "all", images: cameras.map((c) => c.name).join(",") });
    if (token) q.set("token", token);
    const ws = new WebSocket((location.protocol === "https:" ? "wss://" : "ws://") + location.host + "/api/stream?" + q);
    ws.onmessage = (event) => {
      const m = JSON.parse(event.data);
      if (m.type === "hello") { state(m.state); status.textContent = "connected"; }
      else if (m.type === "poses") {
        applyPoses(m.poses);
        dash.time = m.time;
        $("clock").textContent = "t = " + m.time.toFixed(3) + " s";
      } else if (m.type === "sensor" && lasers.has(m.name)) drawLaser(m.name, m.reading);
      else if (m.type === "image") {
        const img = $("camera-" + m.name);
        if (img) { img.src = "data:image/jpeg;base64," + m.data; dash.imageUpdates += 1; }
      } else if (m.type === "error") fail(m.error);
    };
    ws.onclose = () => { status.textContent = "disconnected; retrying"; setTimeout(connect, 1000); };
  }

  fetch("/api/scene.glb", { headers: headers(false) })
    .then((r) => { if (!r.ok) throw new Error("HTTP " + r.status); return r.arrayBuffer(); })
    .then((buffer) => new Promise((resolve, reject) => new GLTFLoader().parse(buffer, "", resolve, reject)))
    .then((gltf) => {
      scene.add(gltf.scene);
      gltf.scene.traverse((o) => {
        if (o.userData && o.userData.simrun_body) bodies.set(o.userData.simrun_body, o);
        if (o.name === "simrun_world") root = o;
      });
      for (const item of lasers.values()) (root || scene).add(item.line);
      for (const e of catalogue.entities.filter((e) => e.robot)) {
        const label = document.createElement("div");
        label.className = "label";
        label.textContent = e.name;
        $("labels").appendChild(label);
        labels.push({ name: e.root || e.name, label });
      }
      return api("GET", "/api/state");
    })
    .then((s) => {
      state(s);
      frameOn(s.poses);
      connect();
      dash.ready = true;
      document.documentElement.dataset.state = "ready";
      status.textContent = "ready";
      requestAnimationFrame(frame);
    })
    .catch((error) => fail("cannot load the world (" + error.message + ")"));

  function frame() {
    controls.update();
    renderer.render(scene, camera);
    for (const item of labels) {
      const at = dash.screen(item.name);
      if (!at) continue;
      item.label.style.display = at[2] < 1 ? "" : "none";
      item.label.style.transform = "translate(" + at[0].toFixed(1) + "px," + (at[1] - 14).toFixed(1) + "px) translate(-50%,-100%)";
    }
    requestAnimationFrame(frame);
  }
})();
