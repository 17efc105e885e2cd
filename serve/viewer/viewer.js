// mimic web viewer: the avatar of `mimic serve`, moving with the vest.
//
// GET /api/avatar gives the rest mesh once (schemas/serve-avatar.schema.json)
// and its parts; GET /api/avatar.glb the same avatar with its look (one mesh
// per part, in order, with its materials, textures and UVs); the WebSocket
// /ws then sends the avatar's vertex positions for every frame the service's
// real-time loop publishes (schemas/serve-ws-frame.md). This page draws the
// GLB's meshes with three.js (embedded in the mimic binary), or, when the GLB
// cannot be had, the plain mesh of the JSON; for each binary frame it copies
// each part's slice of the positions into its mesh, draws the tracked
// landmarks and shows the stream's state in an overlay. A service drives many vests,
// each a session with its own avatar: ?session=NAME on the page's URL picks
// one (the list comes from GET /api/sessions), else the service's first.

// What the page has seen, for people (the overlay) and for tests
// (tests/viewer_test.mjs reads window.mimicViewer). Always the same object.
const state = {
  session: '',        // the session streamed (its hello says), and the ones the service has:
  sessions: [],       // names, from GET /api/sessions
  connected: false,   // the socket is open
  frames: 0,          // binary frames decoded since the page loaded
  lastFrameNumber: 0, // the header's frame number of the latest frame
  templateId: 0,      // template id of the latest key frame (0: none yet)
  poseLabel: '',      // its recognised pose class
  keyFrame: false,    // the latest frame was a key frame (else a morph frame)
  computeMs: 0,       // the server's latency for the latest frame: vest bytes' arrival to frame ready
  fps: 0,             // frames received per second, measured here
  dropped: 0,         // frames the server skipped for us (frame number gaps)
  format: 'f32',      // the position encoding the server says it sends
  keyInterval: 0,      // vest frames per key frame
  landmarkCount: 0,    // landmarks in the latest frame
  landmarksTracked: 0, // of which the vest tracks (the others are NaN)
  vertices: 0,        // of the avatar drawn (GET /api/avatar; every frame must have as many)
  faces: 0,           // its triangles
  parts: 0,           // meshes drawn: the GLB's parts, or 1 (the plain mesh of the JSON)
  glb: false,         // the avatar is drawn from GET /api/avatar.glb (its look), not plain
  glbError: '',       // why not, when not
  textured: 0,        // 1 when a material drawn has a texture map loaded
  errors: [],         // one line each: bad frames, server error messages
};
window.mimicViewer = state;

const HEADER = 112; // bytes before the positions
const LITTLE_ENDIAN = new Uint8Array(new Uint16Array([1]).buffer)[0] === 1; // as the wire
const $ = (id) => document.getElementById(id);
const asked = new URLSearchParams(location.search).get('session') || '';
const sessionQuery = asked ? `?session=${encodeURIComponent(asked)}` : '';

function report(msg) {
  state.errors.push(msg);
  if (state.errors.length > 50) state.errors.shift();
  $('o-error').textContent = msg;
  console.warn('mimic viewer: ' + msg);
}

// ---- three.js, or why it is missing -------------------------------------
// Imported dynamically so that a missing or placeholder three.js (a build
// without npm ci, serve/CMakeLists.txt) still lets the page explain itself.
let THREE, OrbitControls, GLTFLoader = null, gltfMissing = '';
try {
  THREE = await import('three');
  ({ OrbitControls } = await import('three/addons/controls/OrbitControls.js'));
} catch (e) {
  THREE = { MIMIC_PLACEHOLDER: 'three.js failed to load: ' + e.message };
}
// The avatar's look is optional: without GLTFLoader the avatar is drawn plain.
try {
  ({ GLTFLoader } = await import('three/addons/loaders/GLTFLoader.js'));
  if (!GLTFLoader) gltfMissing = 'three.js has no GLTFLoader in this build';
} catch (e) {
  gltfMissing = 'GLTFLoader failed to load: ' + e.message;
}
function fatal(msg) {
  $('o-conn').textContent = 'not started';
  $('o-error').textContent = msg;
  throw new Error(msg); // stop here: nothing to draw with
}
if (!THREE.WebGLRenderer || !OrbitControls) fatal(THREE.MIMIC_PLACEHOLDER || 'three.js failed to load');

// ---- the scene ------------------------------------------------------------
const canvas = $('view');
let renderer;
try {
  renderer = new THREE.WebGLRenderer({ canvas, antialias: true });
} catch (e) {
  fatal('this browser gives the page no WebGL: ' + e.message);
}
renderer.setPixelRatio(window.devicePixelRatio);
const scene = new THREE.Scene();
scene.background = new THREE.Color(0x20242b);
const camera = new THREE.PerspectiveCamera(35, 1, 0.01, 100);
const controls = new OrbitControls(camera, canvas);
controls.enableDamping = true;

// A sky/ground fill, a key light from the front-left-above and a rim light
// from behind, so the body reads as a solid from any side.
scene.add(new THREE.HemisphereLight(0xdde6f0, 0x3a3430, 1.2));
const key = new THREE.DirectionalLight(0xffffff, 2.6);
key.position.set(-2, 3, 3);
scene.add(key);
const rim = new THREE.DirectionalLight(0xb8c8ff, 1.0);
rim.position.set(2, 2, -3);
scene.add(rim);

function resize() {
  const w = canvas.clientWidth, h = canvas.clientHeight;
  renderer.setSize(w, h, false);
  camera.aspect = w / Math.max(h, 1);
  camera.updateProjectionMatrix();
}
window.addEventListener('resize', resize);
resize();

// The avatar: its meshes, each with the range of the frame's vertices it
// draws. Plain (no GLB), one mesh whose position attribute is `positions`.
let meshes = [];          // [{ mesh, first, count, whole }] (whole: the plain mesh, drawing `positions`)
let positions = null;     // a whole frame's positions (3 N), decoded in place
let vertexCount = 0;
let normalsDirty = false; // new positions since the last normal update
const landmarks = [];     // one small sphere per landmark
const landmarkGeometry = new THREE.SphereGeometry(1, 12, 8);
const landmarkMaterial = new THREE.MeshBasicMaterial({ color: 0xff8a3d, depthTest: false, transparent: true, opacity: 0.9 });

// The avatar at rest as GET /api/avatar.glb gives it, its meshes matched to
// the JSON's parts (the GLB's mesh nodes in scene order, one per part). Each
// mesh gets a position attribute of its own, rewritten with every frame.
// Returns the meshes and their root, or throws with a one-line reason.
async function loadLook(a) {
  if (!GLTFLoader) throw new Error(gltfMissing);
  if (!Array.isArray(a.parts) || !a.parts.length) throw new Error('GET /api/avatar names no parts');
  const url = (a.glb || '/api/avatar.glb') + sessionQuery;
  let gltf;
  try {
    gltf = await new GLTFLoader().loadAsync(url);
  } catch (e) {
    throw new Error(`GET ${url}: ${e.message}`);
  }
  const found = [];
  gltf.scene.traverse((o) => o.geometry && o.geometry.attributes.position && found.push(o));
  if (found.length !== a.parts.length) throw new Error(`the GLB has ${found.length} meshes, the avatar ${a.parts.length} parts`);
  const seen = new Set(), out = [];
  for (let k = 0; k < found.length; k++) {
    const mesh = found[k], p = a.parts[k];
    if (mesh.geometry.attributes.position.count !== p.vertices)
      throw new Error(`the GLB's mesh ${k} has ${mesh.geometry.attributes.position.count} vertices, part ${k} ("${p.name}") ${p.vertices}`);
    if (p.first_vertex < 0 || p.first_vertex + p.vertices > vertexCount)
      throw new Error(`part ${k} ("${p.name}") lies outside the avatar's ${vertexCount} vertices`);
    if (seen.has(mesh.geometry)) mesh.geometry = mesh.geometry.clone(); // the loader may share one
    seen.add(mesh.geometry);
    // a plain float attribute of its own (the loader's may be a view of the
    // file, interleaved or quantised), starting at the rest pose
    const attr = new THREE.BufferAttribute(positions.slice(3 * p.first_vertex, 3 * (p.first_vertex + p.vertices)), 3);
    attr.setUsage(THREE.DynamicDrawUsage); // rewritten every frame
    mesh.geometry.setAttribute('position', attr);
    mesh.geometry.computeBoundingSphere();
    if (p.material < 0 && mesh.isMesh) mesh.material = plainMaterial; // none of the author's: as the plain avatar
    out.push({ mesh, first: p.first_vertex, count: p.vertices });
  }
  let textured = 0;
  for (const { mesh } of out)
    for (const m of Array.isArray(mesh.material) ? mesh.material : [mesh.material])
      if (m && m.map && m.map.image) textured = 1;
  return { root: gltf.scene, parts: out, textured };
}

// The plain avatar: one grey mesh of the JSON's positions and triangles.
const plainMaterial = new THREE.MeshStandardMaterial({ color: 0xc9b4a2, roughness: 0.65, metalness: 0.0 });
function plainMesh(a) {
  const geometry = new THREE.BufferGeometry();
  const attr = new THREE.BufferAttribute(positions, 3);
  attr.setUsage(THREE.DynamicDrawUsage); // rewritten every frame
  geometry.setAttribute('position', attr);
  geometry.setIndex(new THREE.BufferAttribute(vertexCount > 65535 ? new Uint32Array(a.indices) : new Uint16Array(a.indices), 1));
  geometry.computeVertexNormals();
  geometry.computeBoundingSphere();
  return new THREE.Mesh(geometry, plainMaterial);
}

// Builds the avatar from GET /api/avatar (and its GLB, if it can be had)
// and points the camera at it.
async function buildAvatar(a) {
  vertexCount = a.vertices;
  positions = new Float32Array(a.positions);
  state.vertices = positions.length / 3;
  state.faces = a.indices.length / 3;
  try {
    const look = await loadLook(a);
    scene.add(look.root);
    meshes = look.parts;
    state.glb = true;
    state.textured = look.textured;
  } catch (e) {
    state.glbError = e.message;
    console.warn(`mimic viewer: the avatar is drawn plain: ${e.message}`);
    const mesh = plainMesh(a);
    scene.add(mesh);
    meshes = [{ mesh, first: 0, count: vertexCount, whole: true }];
  }
  state.parts = meshes.length;

  // Frame the body from the front (+z) with room for its poses: hands
  // raised above the head (a third of the height more) and arms spread as
  // wide as it is tall. From the JSON's positions, however it is drawn.
  const box = new THREE.Box3().setFromArray(positions), size = new THREE.Vector3(), mid = new THREE.Vector3();
  box.getSize(size);
  box.getCenter(mid);
  const bottom = box.min.y - 0.1 * size.y, top = box.max.y + 0.35 * size.y;
  const extent = Math.max(top - bottom, Math.max(size.x, size.y) / camera.aspect);
  const dist = extent / 0.92 / (2 * Math.tan(THREE.MathUtils.degToRad(camera.fov / 2))) + size.z / 2;
  const target = new THREE.Vector3(mid.x, (bottom + top) / 2, mid.z);
  camera.position.set(target.x, target.y + 0.08 * size.y, target.z + dist);
  controls.target.copy(target);
  controls.update();

  // The floor, under the feet.
  const grid = new THREE.GridHelper(4, 16, 0x59606b, 0x3a404a);
  grid.position.set(mid.x, box.min.y, mid.z);
  scene.add(grid);
}

function setLandmarkCount(n, radius) {
  while (landmarks.length < n) {
    const s = new THREE.Mesh(landmarkGeometry, landmarkMaterial);
    s.scale.setScalar(radius);
    s.renderOrder = 1; // drawn over the body
    s.visible = false;
    scene.add(s);
    landmarks.push(s);
  }
}

// ---- decoding a binary frame (schemas/serve-ws-frame.md) ------------------
const labelDecoder = new TextDecoder();

// Decodes one frame into `positions` (in place) and the landmark spheres.
// Returns the header fields, or throws with a one-line reason.
function decodeFrame(buf) {
  if (buf.byteLength < HEADER) throw new Error(`frame of ${buf.byteLength} bytes: shorter than its header`);
  const dv = new DataView(buf), bytes = new Uint8Array(buf);
  if (labelDecoder.decode(bytes.subarray(0, 4)) !== 'MIMF') throw new Error('frame without the MIMF magic');
  const version = dv.getUint16(4, true);
  if (version !== 1) throw new Error(`frame version ${version} (this page reads 1)`);
  const flags = dv.getUint16(6, true);
  const h = {
    key: (flags & 1) !== 0,
    i16: (flags & 2) !== 0,
    frame: Number(dv.getBigUint64(8, true)),
    templateId: Number(dv.getBigUint64(24, true)),
    n: dv.getUint32(32, true),
    l: dv.getUint32(36, true),
    computeUs: dv.getUint32(40, true),
    keyInterval: dv.getUint32(44, true),
  };
  const label = bytes.subarray(56, 88), nul = label.indexOf(0);
  h.label = labelDecoder.decode(nul < 0 ? label : label.subarray(0, nul));
  const lo = [0, 1, 2].map((i) => dv.getFloat32(88 + 4 * i, true));
  const hi = [0, 1, 2].map((i) => dv.getFloat32(100 + 4 * i, true));

  const posBytes = h.i16 ? 6 * h.n + (h.n % 2 ? 2 : 0) : 12 * h.n;
  const want = HEADER + posBytes + 12 * h.l;
  if (buf.byteLength !== want) throw new Error(`frame ${h.frame}: ${buf.byteLength} bytes, expected ${want}`);
  if (h.n !== vertexCount) throw new Error(`frame ${h.frame}: ${h.n} vertices, the avatar has ${vertexCount}`);

  if (h.i16) {
    // q = round((x - min) / (max - min) * 65535) - 32768, per axis
    const scale = [0, 1, 2].map((a) => (hi[a] - lo[a]) / 65535);
    for (let i = 0, off = HEADER; i < 3 * h.n; i++, off += 2) {
      const a = i % 3;
      positions[i] = lo[a] + (dv.getInt16(off, true) + 32768) * scale[a];
    }
  } else if (LITTLE_ENDIAN) {
    positions.set(new Float32Array(buf, HEADER, 3 * h.n)); // the wire's order: one copy
  } else {
    for (let i = 0, off = HEADER; i < 3 * h.n; i++, off += 4) positions[i] = dv.getFloat32(off, true);
  }

  // Landmarks: x y z float32 each, NaN when the vest lost it.
  setLandmarkCount(h.l, 0.012 * Math.max(hi[1] - lo[1], 0.5));
  let tracked = 0;
  for (let j = 0, off = HEADER + posBytes; j < landmarks.length; j++, off += 12) {
    const s = landmarks[j];
    if (j >= h.l) { s.visible = false; continue; }
    const x = dv.getFloat32(off, true), y = dv.getFloat32(off + 4, true), z = dv.getFloat32(off + 8, true);
    s.visible = Number.isFinite(x) && Number.isFinite(y) && Number.isFinite(z);
    if (s.visible) { s.position.set(x, y, z); tracked++; }
  }
  h.tracked = tracked;
  return h;
}

function onFrame(buf) {
  if (!meshes.length) return; // the avatar is not built yet: nothing to update
  let h;
  try {
    h = decodeFrame(buf);
  } catch (e) {
    report(e.message);
    return;
  }
  for (const { mesh, first, count, whole } of meshes) {
    const attr = mesh.geometry.attributes.position;
    if (!whole) attr.array.set(positions.subarray(3 * first, 3 * (first + count))); // the plain mesh draws `positions` itself
    attr.needsUpdate = true;
    mesh.geometry.computeBoundingSphere();
  }
  normalsDirty = true;
  // A gap in frame numbers is frames the server dropped for this client.
  // The first frame of a connection, or a restarted server, is a new start.
  if (state.lastFrameNumber && h.frame > state.lastFrameNumber + 1) state.dropped += h.frame - state.lastFrameNumber - 1;
  state.lastFrameNumber = h.frame;
  state.frames++;
  state.templateId = h.templateId;
  state.poseLabel = h.label;
  state.keyFrame = h.key;
  state.keyInterval = h.keyInterval;
  state.computeMs = h.computeUs / 1000;
  state.landmarksTracked = h.tracked;
  state.landmarkCount = h.l;
}

function onText(text) {
  let m;
  try {
    m = JSON.parse(text);
  } catch {
    report('a text message that is not JSON');
    return;
  }
  if (m.type === 'hello') {
    state.format = m.format;
    state.session = m.session || '';
    showSessions();
    if (vertexCount && m.vertices !== vertexCount) report(`the stream has ${m.vertices} vertices, the avatar ${vertexCount}`);
  } else if (m.type === 'format') {
    state.format = m.format;
  } else if (m.type === 'error') {
    report('server: ' + m.error);
  }
}

// ---- the socket, reconnecting with backoff --------------------------------
let ws = null;
let retryMs = 500;
const i16Box = $('o-i16');
const wanted = () => (i16Box.checked ? 'i16' : 'f32');

function connect() {
  const url = `${location.protocol === 'https:' ? 'wss' : 'ws'}://${location.host}/ws${sessionQuery}`;
  setConnection('connecting');
  ws = new WebSocket(url);
  ws.binaryType = 'arraybuffer';
  ws.onopen = () => {
    state.connected = true;
    state.lastFrameNumber = 0; // joining mid-stream is not a drop
    retryMs = 500;
    setConnection('connected');
    if (wanted() !== 'f32') ws.send(JSON.stringify({ format: wanted() }));
  };
  ws.onmessage = (ev) => (typeof ev.data === 'string' ? onText(ev.data) : onFrame(ev.data));
  ws.onclose = () => {
    state.connected = false;
    setConnection(`closed, retrying in ${(retryMs / 1000).toFixed(1)} s`);
    setTimeout(connect, retryMs);
    retryMs = Math.min(retryMs * 2, 10000);
  };
}

i16Box.addEventListener('change', () => {
  if (ws && ws.readyState === WebSocket.OPEN) ws.send(JSON.stringify({ format: wanted() }));
});

// ---- the session picker: choosing one loads the page for it ---------------
const picker = $('o-session');
function showSessions() {
  const names = state.sessions.length ? state.sessions : [state.session];
  picker.replaceChildren(...names.filter((n) => n).map((n) => new Option(n, n, false, n === state.session)));
}
async function listSessions() {
  try {
    const r = await fetch('/api/sessions');
    if (!r.ok) return;
    state.sessions = (await r.json()).sessions.map((s) => s.name);
    showSessions();
  } catch {
    // the socket's own retry says the service is away
  }
}
picker.addEventListener('change', () => {
  location.search = `?session=${encodeURIComponent(picker.value)}`;
});
setInterval(listSessions, 5000); // sessions come and go while the page is open

function setConnection(text) {
  const el = $('o-conn');
  el.textContent = text;
  el.className = state.connected ? 'up' : 'down';
}

// ---- the overlay: the received rate once a second, the rest with each drawn frame
let fpsFrames = 0, fpsTime = performance.now();
setInterval(() => {
  const now = performance.now();
  state.fps = ((state.frames - fpsFrames) * 1000) / (now - fpsTime);
  fpsFrames = state.frames;
  fpsTime = now;
}, 1000);

function updateOverlay() {
  $('o-template').textContent = state.templateId ? String(state.templateId) : 'none yet';
  $('o-pose').textContent = state.poseLabel || '-';
  $('o-frame').textContent = `#${state.lastFrameNumber} ${state.keyFrame ? 'key' : 'morph'}`;
  $('o-interval').textContent = state.keyInterval === 1 ? 'every frame' : `1 frame in ${state.keyInterval}`;
  $('o-latency').textContent = `${state.computeMs.toFixed(2)} ms`;
  $('o-fps').textContent = `${state.fps.toFixed(1)} frames/s, ${state.format}`;
  $('o-dropped').textContent = String(state.dropped);
  $('o-landmarks').textContent = `${state.landmarksTracked} of ${state.landmarkCount} tracked`;
}

// ---- start ----------------------------------------------------------------
function render() {
  if (normalsDirty) { // at most once per displayed frame, however many arrived
    for (const { mesh } of meshes) if (mesh.isMesh) mesh.geometry.computeVertexNormals();
    normalsDirty = false;
    updateOverlay();
  }
  controls.update();
  renderer.render(scene, camera);
  requestAnimationFrame(render);
}

async function loadAvatar() {
  for (let wait = 500; ; wait = Math.min(wait * 2, 10000)) {
    try {
      const r = await fetch('/api/avatar' + sessionQuery);
      if (!r.ok) throw new Error(`GET /api/avatar: HTTP ${r.status}`);
      return await r.json();
    } catch (e) {
      $('o-conn').textContent = `${e.message}; retrying`;
      await new Promise((ok) => setTimeout(ok, wait));
    }
  }
}

await buildAvatar(await loadAvatar());
requestAnimationFrame(render);
listSessions();
connect();
