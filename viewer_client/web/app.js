// The vdeform web viewer: meshes and status from vdeform-web over one WebSocket (protocol in
// viewer_client/include/vd/viewer/web_protocol.h), Draco decoded here by three.js' DRACOLoader.
import * as THREE from 'three';
import { OrbitControls } from 'three/addons/controls/OrbitControls.js';
import { DRACOLoader } from 'three/addons/loaders/DRACOLoader.js';
import uPlot from './vendor/uplot/dist/uPlot.esm.js';

// What tests and scripts read: mirrored into #vd-stats as data-* attributes. connectToMeshMs: from
// the socket's opening to the first mesh shown on it (a late tab, a reconnect), -1 until then.
// colouring: what the view is coloured by right now (canonical, vertex, grey).
const stats = { meshes: 0, lastSeq: -1, vertices: 0, triangles: 0, state: '', stream: '', connectToMeshMs: -1,
  colouring: '' };
window.vdeformStats = stats;
const statsElement = document.getElementById('vd-stats');
function publishStats() {
  statsElement.dataset.meshes = String(stats.meshes);
  statsElement.dataset.lastSeq = String(stats.lastSeq);
  statsElement.dataset.vertices = String(stats.vertices);
  statsElement.dataset.triangles = String(stats.triangles);
  statsElement.dataset.state = stats.state;
  statsElement.dataset.stream = stats.stream;
}

// ---- the 3D view -------------------------------------------------------------------------------
const view = document.getElementById('view');
const renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
renderer.setPixelRatio(window.devicePixelRatio);
view.appendChild(renderer.domElement);
const scene = new THREE.Scene();
scene.background = new THREE.Color(0x20232a);
const camera = new THREE.PerspectiveCamera(50, 1, 0.01, 100);
const controls = new OrbitControls(camera, renderer.domElement);
controls.enableDamping = true;
scene.add(new THREE.HemisphereLight(0xffffff, 0x404050, 1.2));
const headLight = new THREE.DirectionalLight(0xffffff, 1.6);
camera.add(headLight);
scene.add(camera);
// Meshes come in the camera's coordinates (x right, y down, z forward); three.js looks down -z
// with y up, so turn the model half a turn about x.
const model = new THREE.Group();
model.rotation.x = Math.PI;
scene.add(model);
const material = new THREE.MeshLambertMaterial({ vertexColors: true, side: THREE.DoubleSide });
let mesh = null;
let viewFitted = false;

function resize() {
  const w = Math.max(1, view.clientWidth), h = Math.max(1, view.clientHeight);
  renderer.setSize(w, h);
  camera.aspect = w / h;
  camera.updateProjectionMatrix();
}
window.addEventListener('resize', resize);
resize();

function fitView(geometry) {
  geometry.computeBoundingSphere();
  const sphere = geometry.boundingSphere.clone().applyMatrix4(model.matrixWorld);
  const distance = sphere.radius / Math.sin(THREE.MathUtils.degToRad(camera.fov / 2));
  // The sensor's own viewpoint: from the origin's side of the model, looking at it.
  const from = sphere.center.clone().normalize().multiplyScalar(-distance).add(sphere.center);
  camera.position.copy(sphere.center.lengthSq() > 0 ? from : new THREE.Vector3(0, 0, distance));
  controls.target.copy(sphere.center);
  camera.near = Math.max(distance / 100, 1e-4);
  camera.far = distance * 100;
  camera.updateProjectionMatrix();
  controls.update();
}

function animate() {
  controls.update();
  renderer.render(scene, camera);
  requestAnimationFrame(animate);
}
requestAnimationFrame(animate);

// ---- colouring ---------------------------------------------------------------------------------
const colorSelect = document.getElementById('color');
const colorNote = document.getElementById('color-note');
// The canonical mesh of the shown live frame (same seq, same vertex order), when it came.
let canonical = null; // { seq, geometry }
let live = null; // { seq, geometry }

// Fig. 8 of VolumeDeform: each vertex coloured by where it sits in the canonical pose, its
// coordinates normalised to the canonical bounding box (as the native viewer's CanonicalColors).
function canonicalColors(positions) {
  const n = positions.count;
  const min = [Infinity, Infinity, Infinity], max = [-Infinity, -Infinity, -Infinity];
  for (let i = 0; i < n; ++i)
    for (let a = 0; a < 3; ++a) {
      const v = positions.getComponent(i, a);
      if (v < min[a]) min[a] = v;
      if (v > max[a]) max[a] = v;
    }
  const rgb = new Float32Array(3 * n);
  for (let i = 0; i < n; ++i)
    for (let a = 0; a < 3; ++a) {
      const extent = max[a] - min[a];
      rgb[3 * i + a] = extent > 0 ? (positions.getComponent(i, a) - min[a]) / extent : 0.5;
    }
  return new THREE.BufferAttribute(rgb, 3);
}

function applyColors() {
  if (!live) return;
  const geometry = live.geometry;
  const vertices = geometry.getAttribute('position') ? geometry.getAttribute('position').count : 0;
  const mode = colorSelect.value;
  let shown = null;
  if (mode === 'canonical') {
    // The canonical position inside the live mesh (a per-frame attribute), else the canonical
    // mesh of the same frame, else the mesh's own colour (as the native viewer does).
    if (!live.canonicalColors) {
      const own = geometry.getAttribute('canonical');
      const other = canonical && canonical.seq === live.seq ? canonical.geometry.getAttribute('position') : null;
      if (own) live.canonicalColors = canonicalColors(own);
      else if (other && other.count === vertices) live.canonicalColors = canonicalColors(other);
    }
    shown = live.canonicalColors;
  }
  let used = shown ? mode : 'vertex';
  if (!shown && mode !== 'grey') shown = live.vertexColors;
  if (!shown) used = 'grey';
  // three.js reads vertex colours from the attribute named "color".
  if (shown) geometry.setAttribute('color', shown);
  material.vertexColors = used !== 'grey';
  material.color.set(used === 'grey' ? 0xb4b4b4 : 0xffffff);
  material.needsUpdate = true;
  colorNote.textContent = used === mode ? '' : `(${mode} not available for this frame: ${used})`;
  stats.colouring = used;
}
colorSelect.addEventListener('change', applyColors);

// ---- decoding: one mesh at a time, and only the newest waiting one after it -------------------
const draco = new DRACOLoader();
draco.setDecoderPath('./vendor/three/examples/jsm/libs/draco/');
let decoding = false;
const waiting = { live: null, canonical: null };

// vdeform's meshes carry their attributes under fixed Draco unique ids: position 0, colour 1, and
// in live meshes the canonical positions 3 (common/src/draco_codec.cpp). A mesh without one of them
// (an older server, no colour) fails that decode and is decoded by attribute type instead.
const ids = { position: 0, color: 1, canonical: 3 };
const types = { position: 'Float32Array', color: 'Float32Array', canonical: 'Float32Array' };
function decode(bytes) {
  // The worker takes the buffer it is given: hand it a copy, the fallback needs the bytes.
  return new Promise((resolve, reject) => draco.decodeDracoFile(
    bytes.slice(0), resolve, ids, types, THREE.SRGBColorSpace, () => draco.parse(bytes, resolve, reject)));
}

async function decodeNext() {
  if (decoding) return;
  const kind = waiting.canonical ? 'canonical' : waiting.live ? 'live' : null;
  if (!kind) return;
  const item = waiting[kind];
  waiting[kind] = null;
  decoding = true;
  try {
    const geometry = item.draco.byteLength > 0 ? await decode(item.draco) : new THREE.BufferGeometry();
    if (item.header.stream === stats.stream) show(kind, item.header, geometry);
    else geometry.dispose();
  } catch (error) {
    console.error('vdeform: cannot decode mesh', item.header.seq, error);
  }
  decoding = false;
  decodeNext();
}

function show(kind, header, geometry) {
  if (kind === 'canonical') {
    if (canonical) canonical.geometry.dispose();
    canonical = { seq: header.seq, geometry };
    if (live && live.seq === header.seq) {
      live.canonicalColors = null;
      applyColors();
    }
    return;
  }
  const color = geometry.getAttribute('color');
  // Colours are bytes; read them as 0..1 whatever the file says.
  if (color && color.array instanceof Uint8Array) color.normalized = true;
  if (geometry.getAttribute('position')) geometry.computeVertexNormals();
  if (mesh) {
    model.remove(mesh);
    mesh.geometry.dispose();
  }
  live = { seq: header.seq, geometry, vertexColors: color || null, canonicalColors: null };
  mesh = new THREE.Mesh(geometry, material);
  model.add(mesh);
  model.updateMatrixWorld(true);
  applyColors();
  const vertices = geometry.getAttribute('position') ? geometry.getAttribute('position').count : 0;
  if (!viewFitted && vertices > 0) {
    fitView(geometry);
    viewFitted = true;
  }
  stats.meshes += 1;
  if (stats.connectToMeshMs < 0) stats.connectToMeshMs = Math.round(performance.now() - openedAt);
  stats.lastSeq = header.seq;
  stats.vertices = vertices;
  stats.triangles = geometry.index ? geometry.index.count / 3 : 0;
  publishStats();
}

// ---- status panel and plots --------------------------------------------------------------------
const statusBody = document.querySelector('#status tbody');
const connElement = document.getElementById('conn');
const streamSelect = document.getElementById('stream');
const plotSeconds = 300;
const fpsData = [[], []];
let stageNames = [];
let stageData = [[]];
let fpsPlot = null, stagePlot = null;

function plotOptions(series, element) {
  return {
    width: Math.min(element.clientWidth || 330, 330), height: 140, legend: { show: true },
    scales: { x: { time: true } },
    series: [{}, ...series.map((label, i) => ({ label, stroke: `hsl(${(i * 67) % 360} 70% 42%)`, width: 1.5 }))],
  };
}

function trim(data) {
  const cutoff = data[0][data[0].length - 1] - plotSeconds;
  let drop = 0;
  while (drop < data[0].length && data[0][drop] < cutoff) ++drop;
  if (drop) data.forEach(column => column.splice(0, drop));
}

function updatePlots(status) {
  const t = status.utime / 1e6;
  fpsData[0].push(t);
  fpsData[1].push(status.fps);
  trim(fpsData);
  const fpsElement = document.getElementById('plot-fps');
  if (!fpsPlot) fpsPlot = new uPlot(plotOptions(['fps'], fpsElement), fpsData, fpsElement);
  else fpsPlot.setData(fpsData);

  const names = status.stages.map(s => s.name);
  const stageElement = document.getElementById('plot-stages');
  if (names.join('|') !== stageNames.join('|')) {
    stageNames = names;
    stageData = [[], ...names.map(() => [])];
    if (stagePlot) stagePlot.destroy();
    stagePlot = names.length ? new uPlot(plotOptions(names, stageElement), stageData, stageElement) : null;
  }
  if (!stagePlot) return;
  stageData[0].push(t);
  status.stages.forEach((s, i) => stageData[i + 1].push(s.last_ms));
  trim(stageData);
  stagePlot.setData(stageData);
}

function row(name, value) {
  const tr = document.createElement('tr');
  const a = document.createElement('td'), b = document.createElement('td');
  a.textContent = name;
  b.textContent = value;
  tr.append(a, b);
  return tr;
}

function showStatus(status) {
  stats.state = status.state;
  publishStats();
  const fixed = (x, d) => (x == null ? '-' : Number(x).toFixed(d));
  const rejected = Object.entries(status.reject_reasons).map(([k, v]) => `${k} ${v}`).join(', ');
  statusBody.replaceChildren(
    row('state', status.state),
    row('server', status.message || '-'),
    row('frames', `${status.frames_processed} processed, ${status.frames_received} received`),
    row('fps', fixed(status.fps, 1)),
    row('dropped', String(status.frames_dropped)),
    row('rejected', status.frames_rejected + (rejected ? ` (${rejected})` : '')),
    row('lost', String(status.frames_lost)),
    row('latency', status.latency_ms_p50 > 0
      ? `${fixed(status.latency_ms_p50, 0)} ms p50, ${fixed(status.latency_ms_p95, 0)} ms p95` : '-'),
    row('last frame', String(status.last_processed_seq)),
    row('mesh', stats.lastSeq >= 0 ? `seq ${stats.lastSeq}: ${stats.vertices} vertices, ${stats.triangles} triangles` : '-'),
    row('memory', `${(status.resident_memory_bytes / 1048576).toFixed(0)} MB`),
  );
  updatePlots(status);
}

function showStreams(streams) {
  const options = streams.map(name => {
    const option = document.createElement('option');
    option.value = name;
    option.textContent = name || 'default';
    return option;
  });
  streamSelect.replaceChildren(...options);
  if (!streams.includes(stats.stream) && streams.length) stats.stream = streams[0];
  streamSelect.value = stats.stream;
  publishStats();
}

// ---- the connection ----------------------------------------------------------------------------
let socket = null;
let retryMs = 250;
let openedAt = 0;
const chosen = new URLSearchParams(location.search).get('stream');
if (chosen !== null) stats.stream = chosen;

function send(text) {
  if (socket && socket.readyState === WebSocket.OPEN) socket.send(text);
}

streamSelect.addEventListener('change', () => {
  stats.stream = streamSelect.value;
  viewFitted = false;
  canonical = null;
  send(`stream ${stats.stream}`);
  publishStats();
});

function onMessage(event) {
  if (typeof event.data === 'string') {
    const message = JSON.parse(event.data);
    if (message.type === 'status' && message.stream === stats.stream) showStatus(message);
    else if (message.type === 'streams') showStreams(message.streams);
    return;
  }
  const bytes = event.data;
  const head = new DataView(bytes, 0, 8);
  if (new TextDecoder().decode(new Uint8Array(bytes, 0, 4)) !== 'VDM1') return;
  const length = head.getUint32(4, true);
  const header = JSON.parse(new TextDecoder().decode(new Uint8Array(bytes, 8, length)));
  if (header.stream !== stats.stream) return;
  waiting[header.kind] = { header, draco: bytes.slice(8 + length) };
  decodeNext();
}

function connect() {
  const url = new URL('ws', location.href);
  url.protocol = location.protocol === 'https:' ? 'wss:' : 'ws:';
  const token = new URLSearchParams(location.search).get('token');
  url.search = '';
  if (token) url.searchParams.set('token', token);
  if (chosen !== null) url.searchParams.set('stream', chosen);
  socket = new WebSocket(url);
  socket.binaryType = 'arraybuffer';
  socket.onopen = () => {
    retryMs = 250;
    openedAt = performance.now();
    stats.connectToMeshMs = -1;
    connElement.textContent = 'live';
    connElement.className = 'ok';
    if (stats.stream) send(`stream ${stats.stream}`);
  };
  socket.onmessage = onMessage;
  socket.onclose = () => {
    connElement.textContent = 'reconnecting';
    connElement.className = 'bad';
    // The bridge restarted or the network blinked: try again, backing off up to 2 s.
    setTimeout(connect, retryMs);
    retryMs = Math.min(2000, retryMs * 2);
  };
}
publishStats();
connect();
