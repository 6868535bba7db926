// kdtrace's page: renders progressively over the websocket of `kdtrace serve` (protocol in the
// README), moves the camera with the mouse and draws replayed paths over the image.
"use strict";

const $ = (id) => document.getElementById(id);
const image = $("image");
const overlay = $("overlay");
const ctx = image.getContext("2d");
const octx = overlay.getContext("2d");

let socket = null;
let hello = null;
// The camera and image the page asks for, and what the newest frame was rendered with.
let camera = null;
let shown = null;
let lastPath = null;
let sendQueued = false;
let decoding = false;
let pendingFrame = null;
let pendingProgress = null;

// Vector helpers on [x, y, z] arrays.
const sub = (a, b) => [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
const add = (a, b) => [a[0] + b[0], a[1] + b[1], a[2] + b[2]];
const mul = (a, k) => [a[0] * k, a[1] * k, a[2] * k];
const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
const cross = (a, b) => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
const len = (a) => Math.sqrt(dot(a, a));
const norm = (a) => mul(a, 1 / len(a));
// Rodrigues' rotation of v about the unit axis k by angle a.
const rotate = (v, k, a) => add(add(mul(v, Math.cos(a)), mul(cross(k, v), Math.sin(a))), mul(k, dot(k, v) * (1 - Math.cos(a))));

function status(text) { $("status").textContent = text || ""; }

function connect() {
  const url = (location.protocol === "https:" ? "wss://" : "ws://") + location.host + "/ws";
  socket = new WebSocket(url);
  socket.binaryType = "blob";
  socket.onmessage = (e) => (typeof e.data === "string" ? onText(JSON.parse(e.data)) : onFrame(e.data));
  socket.onclose = () => { status("disconnected; reconnecting…"); setTimeout(connect, 1000); };
  socket.onopen = () => status("");
}

function onText(m) {
  switch (m.type) {
    case "hello": onHello(m); break;
    case "progress": pendingProgress = m; break;
    case "done": showProgress(m, true); break;
    case "path": onPath(m); break;
    case "error": status(m.message); break;
  }
}

function onHello(m) {
  hello = m;
  const scenes = $("scene");
  scenes.innerHTML = "";
  for (const s of m.scenes) scenes.add(new Option(`${s.name} (${s.triangles.toLocaleString()} triangles)`, s.index));
  const devices = $("device");
  devices.innerHTML = "";
  for (const d of m.devices) devices.add(new Option(d, d));
  devices.value = m.device;
  chooseScene(0);
}

// The scene's own settings and camera.
function chooseScene(i) {
  const s = hello.scenes[i];
  $("scene").value = i;
  $("spp").value = s.spp;
  $("bounces").value = s.bounces;
  $("width").value = s.width;
  $("height").value = s.height;
  camera = { eye: s.camera.eye.slice(), target: s.camera.target.slice(), up: s.camera.up.slice(), fov: s.camera.fov };
  $("fov").value = camera.fov;
  $("stat-scene").textContent = `${s.nodes.toLocaleString()} k-d nodes, depth ${s.tree_depth}, ${s.lights} light triangles`;
  // What loading found amiss, and a scene that nothing lights: said once, beside the image.
  $("warnings").textContent = s.warnings.map((w) => `warning: ${w}`).join("\n");
  clearPath();
  render();
}

function request() {
  return {
    type: "render",
    scene: Number($("scene").value),
    device: $("device").value,
    aov: $("aov").value,
    spp: Number($("spp").value),
    bounces: Number($("bounces").value),
    width: Number($("width").value),
    height: Number($("height").value),
    camera: { eye: camera.eye, target: camera.target, up: camera.up, fov: camera.fov },
  };
}

// At most one render request per animation frame: dragging sends the newest camera only.
function render() {
  $("fov-value").textContent = Number(camera.fov).toFixed(1);
  if (sendQueued) return;
  sendQueued = true;
  requestAnimationFrame(() => {
    sendQueued = false;
    if (!socket || socket.readyState !== WebSocket.OPEN) return;
    const r = request();
    shown = r;
    socket.send(JSON.stringify(r));
  });
}

// Frames are decoded one at a time; one that arrives meanwhile replaces the waiting one.
function onFrame(blob) {
  pendingFrame = { blob, progress: pendingProgress };
  if (!decoding) drawNext();
}

async function drawNext() {
  const f = pendingFrame;
  if (!f) return;
  pendingFrame = null;
  decoding = true;
  try {
    const bitmap = await createImageBitmap(f.blob);
    if (image.width !== bitmap.width || image.height !== bitmap.height) {
      image.width = overlay.width = bitmap.width;
      image.height = overlay.height = bitmap.height;
      drawPath();
    }
    ctx.drawImage(bitmap, 0, 0);
    bitmap.close();
    if (f.progress) showProgress(f.progress, false);
    image.dataset.frames = String(Number(image.dataset.frames || 0) + 1);
  } finally {
    decoding = false;
    if (pendingFrame) drawNext();
  }
}

function showProgress(p, done) {
  $("stat-spp").textContent = `${p.spp} / ${p.target} spp${done ? " ✓" : ""}`;
  $("stat-rate").textContent = `${(p.samples_per_s / 1e6).toFixed(2)} Msamples/s`;
  $("stat-time").textContent = `${p.elapsed_s.toFixed(1)} s`;
  $("stat-device").textContent = p.device;
}

// --- Camera controls -------------------------------------------------------------------------

let drag = null;

image.addEventListener("contextmenu", (e) => e.preventDefault());
image.addEventListener("mousedown", (e) => {
  drag = { x: e.clientX, y: e.clientY, moved: false, pan: e.button === 2 || e.shiftKey, start: structuredClone(camera) };
});
window.addEventListener("mousemove", (e) => {
  if (!drag || !camera) return;
  const dx = e.clientX - drag.x;
  const dy = e.clientY - drag.y;
  if (!drag.moved && Math.hypot(dx, dy) < 3) return;
  drag.moved = true;
  const c = drag.start;
  const forward = sub(c.target, c.eye);
  const dist = len(forward);
  const right = norm(cross(forward, c.up));
  const up = norm(cross(right, forward));
  if (drag.pan) {
    // The point under the cursor stays under it: a pixel spans 2·tan(fov/2)·dist / height.
    const perPixel = (2 * Math.tan((c.fov * Math.PI) / 360) * dist) / image.clientHeight;
    const move = add(mul(right, -dx * perPixel), mul(up, dy * perPixel));
    camera = { ...c, eye: add(c.eye, move), target: add(c.target, move) };
  } else {
    // Orbit about the target: yaw about the up vector, pitch about the camera's right.
    let offset = sub(c.eye, c.target);
    const worldUp = norm(c.up);
    offset = rotate(offset, worldUp, -dx * 0.01);
    const r2 = norm(cross(mul(offset, -1), worldUp));
    const pitched = rotate(offset, r2, -dy * 0.01);
    // Stop short of the poles, where up and the view direction would align.
    if (Math.abs(dot(norm(pitched), worldUp)) < 0.995) offset = pitched;
    camera = { ...c, eye: add(c.target, offset) };
  }
  clearPath();
  render();
});
window.addEventListener("mouseup", (e) => {
  if (drag && !drag.moved && e.button === 0) pickPixel(e);
  drag = null;
});
image.addEventListener("wheel", (e) => {
  e.preventDefault();
  if (!camera) return;
  const k = Math.exp(e.deltaY * 0.001);
  camera = { ...camera, eye: add(camera.target, mul(sub(camera.eye, camera.target), k)) };
  clearPath();
  render();
}, { passive: false });

$("fov").addEventListener("input", (e) => { camera.fov = Number(e.target.value); clearPath(); render(); });
$("scene").addEventListener("change", (e) => chooseScene(Number(e.target.value)));
for (const id of ["device", "aov", "spp", "bounces", "width", "height"]) $(id).addEventListener("change", () => { clearPath(); render(); });
$("reset").addEventListener("click", () => chooseScene(Number($("scene").value)));
$("stop").addEventListener("click", () => socket.send(JSON.stringify({ type: "stop" })));

// --- The debugger ----------------------------------------------------------------------------

function pickPixel(e) {
  if (!shown) return;
  const rect = image.getBoundingClientRect();
  const x = Math.floor(((e.clientX - rect.left) / rect.width) * shown.width);
  const y = Math.floor(((e.clientY - rect.top) / rect.height) * shown.height);
  const sample = Number($("sample").value) || 0;
  socket.send(JSON.stringify({ type: "pixel", x, y, sample }));
}

// Where a world point lands in the shown image (the renderer's pinhole camera), or null.
function project(p) {
  if (!shown) return null;
  const c = shown.camera;
  const forward = norm(sub(c.target, c.eye));
  const right = norm(cross(forward, c.up));
  const up = cross(right, forward);
  const d = sub(p, c.eye);
  const z = dot(d, forward);
  if (!(z > 0)) return null;
  const t = Math.tan((c.fov * Math.PI) / 360);
  const aspect = shown.width / shown.height;
  const sx = dot(d, right) / (z * t * aspect);
  const sy = dot(d, up) / (z * t);
  return [((sx + 1) / 2) * shown.width, ((1 - sy) / 2) * shown.height];
}

function onPath(m) {
  lastPath = m;
  const r = m.radiance.map((v) => v.toPrecision(4)).join(", ");
  $("pixel-info").textContent =
    `Pixel (${m.x}, ${m.y}), sample ${m.sample}, seed ${m.seed}: radiance (${r}), ${m.vertices.length} vertices, ended: ${m.end}`;
  const body = $("vertices").tBodies[0];
  body.innerHTML = "";
  m.vertices.forEach((v, i) => {
    const row = body.insertRow();
    row.className = "vertex";
    const cell = (lines, cls) => { const c = row.insertCell(); c.textContent = lines.filter(Boolean).join("\n"); if (cls) c.className = cls; };
    cell([String(i + 1)]);
    cell([
      `${v.material_kind} (material ${v.material}), triangle ${v.triangle}, ${v.front ? "front" : "back"}`,
      `at ${fmt(v.position)}, t ${num(v.t)}`,
      `normal ${fmt(v.geometric_normal)}`,
      `shading ${fmt(v.shading_normal)}`,
      v.emission ? `emits ${fmt(v.emission.emitted)} × mis ${num(v.emission.mis_weight)}` : "",
    ]);
    const l = v.light;
    const k = v.connection;
    cell(l ? [
      `${l.status}${l.light !== null ? `: light ${l.light}, triangle ${l.triangle}` : ""}`,
      l.status !== "delta" ? `pdf ${num(l.light_pdf)}, bsdf pdf ${num(l.bsdf_pdf)}` : "",
      l.status !== "delta" ? `mis ${num(l.mis_weight)}, adds ${fmt(l.contribution)}` : "",
      k ? `connection: ${k.status}${k.status === "unblocked" ? `, adds ${fmt(k.contribution)}` : ""}` : "",
    ] : ["—"], l ? (l.blocked ? "blocked" : l.status === "unblocked" ? "lit" : "") : "");
    cell([
      v.bsdf ? `wi ${fmt(v.bsdf.wi)}, pdf ${v.bsdf.delta ? "δ" : num(v.bsdf.pdf)}${v.bsdf.valid ? "" : " (ends)"}` : "no BSDF sample (last vertex)",
      v.bsdf ? `weight ${fmt(v.bsdf.weight)}` : "",
      `throughput ${fmt(v.throughput)}`,
      v.roulette ? `roulette: p ${num(v.roulette.survival)}, u ${num(v.roulette.uniform)}, ${v.roulette.survived ? "kept" : "ended"}` : "",
    ]);
    cell([
      `${v.nodes} nodes, ${v.tests} triangle tests${v.restarts ? `, ${v.restarts} restarts` : ""}`,
      l && l.shadow_ray ? `shadow ray: ${l.shadow_ray.nodes} nodes, ${l.shadow_ray.tests} tests` : "",
      k && k.shadow_ray ? `connection's ray: ${k.shadow_ray.nodes} nodes, ${k.shadow_ray.tests} tests` : "",
    ]);
  });
  drawPath();
}

function fmt(a) { return a ? "(" + a.map((x) => Number(x).toPrecision(3)).join(", ") + ")" : "—"; }
function num(x) { return x === undefined || x === null ? "—" : Number(x).toPrecision(3); }

function clearPath() {
  lastPath = null;
  octx.clearRect(0, 0, overlay.width, overlay.height);
}

function drawPath() {
  octx.clearRect(0, 0, overlay.width, overlay.height);
  const m = lastPath;
  if (!m) return;
  const s = overlay.width / 512;
  octx.lineWidth = Math.max(1.5, 2 * s);
  const points = [[m.x + 0.5, m.y + 0.5]];
  for (const v of m.vertices) points.push(v.pixel || project(v.position));
  // Shadow rays, dashed.
  octx.setLineDash([4 * s, 4 * s]);
  m.vertices.forEach((v, i) => {
    const from = points[i + 1];
    const to = v.light && v.light.point ? (v.light.pixel || project(v.light.point)) : null;
    if (!from || !to) return;
    // Green: the light was reached; red: blocked; grey: no shadow ray (the sample was invalid).
    octx.strokeStyle = v.light.blocked ? "#ff7b72" : v.light.status === "unblocked" ? "#7ee787" : "#777";
    octx.beginPath(); octx.moveTo(...from); octx.lineTo(...to); octx.stroke();
  });
  // Connections to light subpaths, dotted: blue where the light vertex was reached, red where
  // blocked.
  octx.setLineDash([1.5 * s, 3 * s]);
  m.vertices.forEach((v, i) => {
    const from = points[i + 1];
    const k = v.connection;
    const to = k && k.point ? (k.pixel || project(k.point)) : null;
    if (!from || !to) return;
    octx.strokeStyle = k.status === "blocked" ? "#ff7b72" : "#79c0ff";
    octx.beginPath(); octx.moveTo(...from); octx.lineTo(...to); octx.stroke();
  });
  octx.setLineDash([]);
  octx.strokeStyle = "#ffb347";
  octx.beginPath();
  let drawing = false;
  for (const p of points) {
    if (!p) { drawing = false; continue; }
    if (drawing) octx.lineTo(...p); else octx.moveTo(...p);
    drawing = true;
  }
  octx.stroke();
  // The ray that left the scene: toward where it goes, as far as the scene is wide.
  const last = points[points.length - 1];
  if (m.escaped && last && m.vertices.length > 0) {
    const s0 = hello.scenes[shown.scene];
    const far = len(sub(s0.bounds_max, s0.bounds_min));
    const to = project(add(m.escaped.ray_origin, mul(m.escaped.ray_direction, far)));
    if (to) {
      octx.setLineDash([2 * s, 3 * s]);
      octx.beginPath(); octx.moveTo(...last); octx.lineTo(...to); octx.stroke();
      octx.setLineDash([]);
    }
  }
  octx.fillStyle = "#ffb347";
  octx.font = `${Math.round(12 * s)}px system-ui`;
  points.slice(1).forEach((p, i) => {
    if (!p) return;
    octx.beginPath(); octx.arc(p[0], p[1], 3.5 * s, 0, 2 * Math.PI); octx.fill();
    octx.fillText(String(i + 1), p[0] + 5 * s, p[1] - 5 * s);
  });
  overlay.dataset.vertices = String(points.length - 1);
}

connect();
