// simrun's recording player: plays the animated glTF embedded in the page with three.js (nicegui's module
// as a classic script, simrun.record.replay_html.viewer_bundle, inlined before this script). Controls:
// play/pause (also the space bar), a time slider, the clock, the playback speed; labels follow the moving
// bodies. The URL fragment picks a moment: #t=12.5 opens paused at 12.5 s, #t=12.5&play plays from there;
// none plays from the start.
// window.simrunPlayer = {ready, time(), duration, setTime(t), play(), pause(), screen(name)} for scripts.
(function () {
  "use strict";
  const { THREE, GLTFLoader, OrbitControls } = globalThis.SimrunThree;
  const config = JSON.parse(document.getElementById("simrun-config").textContent);
  const status = document.getElementById("status");
  const fail = (message) => {
    status.textContent = "error: " + message;
    document.documentElement.dataset.state = "error";
  };
  const raw = atob(document.getElementById("simrun-glb").textContent.trim());
  const bytes = new Uint8Array(raw.length);
  for (let i = 0; i < raw.length; i++) bytes[i] = raw.charCodeAt(i);

  const view = document.getElementById("view");
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
  scene.background = new THREE.Color(config.background);
  scene.add(new THREE.HemisphereLight(0xffffff, 0x8a8a80, 1.6));
  const sun = new THREE.DirectionalLight(0xffffff, 1.8);
  sun.position.set(...config.sun);
  scene.add(sun);
  const cam = config.camera;
  const camera = new THREE.PerspectiveCamera(cam.fov, 1, cam.near, cam.far);
  camera.position.set(...cam.eye);
  const controls = new OrbitControls(camera, renderer.domElement);
  controls.target.set(...cam.target);
  controls.update();

  const slider = document.getElementById("time");
  const clock = document.getElementById("clock");
  const button = document.getElementById("play");
  const labels = document.getElementById("labels");
  const start = config.start, end = config.end;
  slider.min = String(start);
  slider.max = String(end);
  slider.step = "any";
  let mixer = null, action = null, playing = false, time = start, last = null, speed = 1;
  const tracked = [];

  function show(t) {
    time = Math.min(end, Math.max(start, t));
    if (action) {
      action.time = time;
      mixer.update(0);
    }
    slider.value = String(time);
    clock.textContent = time.toFixed(2) + " s / " + end.toFixed(2) + " s";
    status.textContent = time.toFixed(3);
  }
  function setPlaying(on) {
    playing = on;
    last = null;
    button.textContent = on ? "Pause" : "Play";
    button.setAttribute("aria-pressed", on ? "true" : "false");
  }
  function resize() {
    const w = view.clientWidth, h = view.clientHeight;
    renderer.setSize(w, h, false);
    camera.aspect = w / Math.max(1, h);
    camera.updateProjectionMatrix();
  }
  const where = new THREE.Vector3();
  function screen(object, lift) {
    object.getWorldPosition(where);
    where.y += lift;
    where.project(camera);
    return [(where.x + 1) / 2 * view.clientWidth, (1 - where.y) / 2 * view.clientHeight, where.z];
  }
  function advance() {
    // the clock runs on performance.now(), also from a timer: it keeps time where frames are throttled
    if (!playing) return;
    const now = performance.now();
    if (last !== null) {
      let t = time + ((now - last) / 1000) * speed;
      if (t > end) t = start + (t - end) % Math.max(1e-9, end - start);
      show(t);
    }
    last = now;
  }
  function frame() {
    advance();
    controls.update();
    renderer.render(scene, camera);
    for (const item of tracked) {
      const [x, y, z] = screen(item.object, item.lift);
      item.label.style.display = z < 1 ? "" : "none";
      item.label.style.transform = "translate(" + x.toFixed(1) + "px," + y.toFixed(1) + "px) translate(-50%,-100%)";
    }
    requestAnimationFrame(frame);
  }

  button.addEventListener("click", () => setPlaying(!playing));
  slider.addEventListener("input", () => { setPlaying(false); show(parseFloat(slider.value)); });
  document.getElementById("speed").addEventListener("change", (e) => { advance(); speed = parseFloat(e.target.value); });
  window.addEventListener("keydown", (e) => {
    if (e.code === "Space" && e.target === document.body) { e.preventDefault(); setPlaying(!playing); }
  });
  window.addEventListener("resize", resize);
  setInterval(advance, 100);
  resize();

  const loader = new GLTFLoader();
  // Textures through an <img> (three's TextureLoader, as GLTFLoader does on Safari and older Firefox), not
  // createImageBitmap: with three r180, headless Chromium's virtual time ran out while an ImageBitmap decoded
  // (4 s of it for one PNG), so a page opened with --virtual-time-budget had not started playing.
  loader.register((parser) => {
    parser.textureLoader = new THREE.TextureLoader(parser.options.manager);
    return { name: "simrun_image_textures" };
  });
  loader.parse(bytes.buffer, "", (gltf) => {
    scene.add(gltf.scene);
    const bodies = new Map();
    gltf.scene.traverse((o) => { if (o.userData && o.userData.simrun_body) bodies.set(o.userData.simrun_body, o); });
    for (const entry of config.labels) {
      const object = bodies.get(entry.body);
      if (!object) continue;
      const label = document.createElement("div");
      label.className = entry.robot ? "label robot" : "label";
      label.textContent = entry.text;
      labels.appendChild(label);
      tracked.push({ object, label, name: entry.body, lift: entry.lift });
    }
    if (gltf.animations.length) {
      mixer = new THREE.AnimationMixer(gltf.scene);
      action = mixer.clipAction(gltf.animations[0]);
      action.play();
    }
    const params = new URLSearchParams(location.hash.slice(1));
    const at = parseFloat(params.get("t"));
    show(Number.isFinite(at) ? at : start);
    setPlaying(!params.has("t") || params.has("play"));
    window.simrunPlayer.ready = true;
    document.documentElement.dataset.state = "ready";
    requestAnimationFrame(frame);
  }, (error) => fail("cannot read the embedded glTF (" + (error && error.message) + ")"));

  window.simrunPlayer = {
    ready: false,
    duration: end - start,
    time: () => time,
    setTime: (t) => { setPlaying(false); show(t); },
    play: () => setPlaying(true),
    pause: () => setPlaying(false),
    screen: (name) => { const item = tracked.find((i) => i.name === name); return item ? screen(item.object, 0) : null; },
  };
})();
