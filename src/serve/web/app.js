// treemocap live view: raw markers, tracked tips, noise, the current tree and
// the wind, from the daemon's WebSocket /live (or, for `treemocap view`, from
// the recorded session's frames). Served by treemocap itself; three.js is
// vendored under web/three (see VENDOR.md there).
//
// The page keeps its own state in `window.treemocap`, so that a person (or a
// test) can ask what it shows: frames received, points drawn, tree version
// and triangle count, the pose the tree sways with, the last status.

import * as THREE from 'three';
import { GLTFLoader } from 'three/addons/loaders/GLTFLoader.js';
import { OrbitControls } from 'three/addons/controls/OrbitControls.js';

// ---------------------------------------------------------------- the frame codec

/** Tip states in a frame, as the server numbers them. */
const STATES = ['measured', 'filled', 'unseen'];
/** Marker classes in a frame. */
const CLASS_TIP = 1, CLASS_NOISE = 2;

/**
 * Decodes one binary frame (format "TMF1", little-endian; README, "/live"):
 * magic, reserved u32, frame i64, time f64, marker count u32, tip count u32,
 * markers as f32 x y z, one class byte per marker (padded to 4), then per tip
 * u32 marker id, u32 state, f32 x y z.
 */
export function decodeFrame(buf) {
  const v = new DataView(buf);
  const magic = String.fromCharCode(v.getUint8(0), v.getUint8(1), v.getUint8(2), v.getUint8(3));
  if (magic !== 'TMF1') throw new Error(`not a treemocap frame (magic ${JSON.stringify(magic)})`);
  const frame = Number(v.getBigInt64(8, true));
  const time = v.getFloat64(16, true);
  const m = v.getUint32(24, true), t = v.getUint32(28, true);
  let o = 32;
  const need = o + 12 * m + ((m + 3) & ~3) + 20 * t;
  if (buf.byteLength < need) throw new Error(`frame ${frame}: ${buf.byteLength} bytes, ${need} needed`);
  const markers = new Float32Array(3 * m);
  for (let i = 0; i < 3 * m; i++, o += 4) markers[i] = v.getFloat32(o, true);
  const classes = new Uint8Array(buf.slice(o, o + m));
  o += (m + 3) & ~3;
  const tips = [];
  for (let i = 0; i < t; i++, o += 20) {
    tips.push({
      marker: v.getUint32(o, true),
      state: STATES[v.getUint32(o + 4, true)] ?? 'unseen',
      p: [v.getFloat32(o + 8, true), v.getFloat32(o + 12, true), v.getFloat32(o + 16, true)],
    });
  }
  return { frame, time, markers, classes, tips };
}

// ---------------------------------------------------------------- scene

const COLORS = {
  raw: 0xe8e8e8, measured: 0x27d3ff, filled: 0xffb020, unseen: 0x6f7785,
  noise: 0xff3b6b, wind: 0x7cff8a,
};
const TRAIL = 30; // positions per tip trail (half a second at 60 messages/s)

const canvas = document.getElementById('view');
const renderer = new THREE.WebGLRenderer({ canvas, antialias: true, preserveDrawingBuffer: true });
renderer.setPixelRatio(Math.min(window.devicePixelRatio, 2));
const scene = new THREE.Scene();
scene.background = new THREE.Color(0x14171c);
const camera = new THREE.PerspectiveCamera(45, 1, 0.01, 200);
const controls = new OrbitControls(camera, canvas);
controls.enableDamping = true;
scene.add(new THREE.HemisphereLight(0xf0f4ff, 0x3a3026, 2.2));
const sun = new THREE.DirectionalLight(0xffffff, 1.6);
sun.position.set(3, 6, 4);
scene.add(sun);

/** The layers a person can switch on and off. */
const layers = {
  markers: new THREE.Group(), tips: new THREE.Group(), trails: new THREE.Group(),
  noise: new THREE.Group(), tree: new THREE.Group(), wind: new THREE.Group(),
  grid: new THREE.Group(),
};
for (const g of Object.values(layers)) scene.add(g);

/** A round dot for the points (a point is a square otherwise). */
const dot = (() => {
  const c = document.createElement('canvas');
  c.width = c.height = 64;
  const g = c.getContext('2d');
  g.fillStyle = '#fff';
  g.beginPath(); g.arc(32, 32, 30, 0, 2 * Math.PI); g.fill();
  return new THREE.CanvasTexture(c);
})();

function pointCloud(color, size, max) {
  const geom = new THREE.BufferGeometry();
  geom.setAttribute('position', new THREE.BufferAttribute(new Float32Array(3 * max), 3));
  geom.setDrawRange(0, 0);
  const mat = new THREE.PointsMaterial({ color, size, sizeAttenuation: false, map: dot, alphaTest: 0.5 });
  const pts = new THREE.Points(geom, mat);
  pts.frustumCulled = false;
  return pts;
}

/** Grows a point cloud's buffer when a frame has more points than it holds. */
function setPoints(pts, xyz, count, colors) {
  let attr = pts.geometry.getAttribute('position');
  if (attr.count < count) {
    const n = Math.max(count, 2 * attr.count);
    attr = new THREE.BufferAttribute(new Float32Array(3 * n), 3);
    pts.geometry.setAttribute('position', attr);
    if (colors) pts.geometry.setAttribute('color', new THREE.BufferAttribute(new Float32Array(3 * n), 3));
  }
  attr.array.set(xyz.subarray(0, 3 * count));
  attr.needsUpdate = true;
  if (colors) {
    const c = pts.geometry.getAttribute('color');
    c.array.set(colors.subarray(0, 3 * count));
    c.needsUpdate = true;
  }
  pts.geometry.setDrawRange(0, count);
}

const rawPoints = pointCloud(COLORS.raw, 4, 1024);
layers.markers.add(rawPoints);
const noisePoints = pointCloud(COLORS.noise, 6, 256);
layers.noise.add(noisePoints);
const tipPoints = pointCloud(0xffffff, 9, 128);
tipPoints.material.vertexColors = true;
tipPoints.geometry.setAttribute('color', new THREE.BufferAttribute(new Float32Array(3 * 128), 3));
layers.tips.add(tipPoints);
const trailLines = new THREE.LineSegments(new THREE.BufferGeometry(),
  new THREE.LineBasicMaterial({ vertexColors: true, transparent: true, opacity: 0.8 }));
trailLines.frustumCulled = false;
layers.trails.add(trailLines);

// Ground grid: 1 m squares over 10 m, finer 0.1 m squares over the central 2 m.
layers.grid.add(new THREE.GridHelper(10, 10, 0x56606e, 0x3a424e));
const fine = new THREE.GridHelper(2, 20, 0x2c333d, 0x2c333d);
fine.position.y = -0.001;
layers.grid.add(fine);
layers.grid.add(new THREE.AxesHelper(1));

let windArrow = null;
const labels = document.getElementById('labels');
/** Text pinned to points of the scene: [element, Vector3, layer]. */
const pinned = [];
function pin(text, pos, cls, layer) {
  const el = document.createElement('span');
  el.textContent = text;
  if (cls) el.className = cls;
  labels.appendChild(el);
  const p = { el, pos: pos.clone(), layer };
  pinned.push(p);
  return p;
}
for (let m = 1; m <= 4; m++) pin(`${m} m`, new THREE.Vector3(m, 0, 0.12), '', 'grid');
pin('X', new THREE.Vector3(1.1, 0, 0), 'axis', 'grid');
pin('Y ↑', new THREE.Vector3(0, 1.1, 0), 'axis', 'grid');
pin('Z', new THREE.Vector3(0, 0, 1.1), 'axis', 'grid');
const windLabel = pin('', new THREE.Vector3(), 'wind', 'wind');

// ---------------------------------------------------------------- page state

const tm = {
  mode: 'live',
  connected: false,
  connects: 0,          // WebSocket connections opened (more than one: the page reconnected)
  frames: 0,            // frames received (live) or shown (view)
  firstFrameAt: null,   // performance.now() of the first frame drawn
  last: null,           // { frame, time, markers, tips, noise, states }
  shown: { markers: 0, noise: 0, tips: 0 },
  tree: null,           // { version, triangles, loadedAt }
  treeLoads: 0,
  status: null,
  errors: [],
  session: null,        // view mode: session.json
  viewFrame: null,      // view mode: index of the frame shown
  pose: null,           // the live pose on the tree: { tree, frame, time }; null = rest pose
  poses: 0,             // pose events applied
  lastPoseFrame: null,  // frame of the last pose applied (kept after the rest pose returns)
  lastPoseSeen: null,   // { tree, frame } of the last pose event received, applied or not
  poseSkipped: null,    // { frame, tree, why } of the last pose event not applied
  swayFrames: {},       // per tree swaying ('' for a tree alone): the frame of its pose shown
  decodeFrame,
};
window.treemocap = tm;
window.addEventListener('error', (e) => tm.errors.push(String(e.message)));

// ---------------------------------------------------------------- frames

/** Per tip marker id: recent positions and states, for the trails. */
const trails = new Map();
let lastFrameNo = null;

function showFrame(f, contiguous) {
  const m = f.markers.length / 3;
  setPoints(rawPoints, f.markers, m);
  let noise = 0;
  const noiseXYZ = new Float32Array(3 * m);
  for (let i = 0; i < m; i++) {
    if (f.classes[i] === CLASS_NOISE) {
      noiseXYZ.set(f.markers.subarray(3 * i, 3 * i + 3), 3 * noise);
      noise++;
    }
  }
  setPoints(noisePoints, noiseXYZ, noise);
  const xyz = new Float32Array(3 * f.tips.length), rgb = new Float32Array(3 * f.tips.length);
  const c = new THREE.Color();
  const states = { measured: 0, filled: 0, unseen: 0 };
  f.tips.forEach((t, i) => {
    xyz.set(t.p, 3 * i);
    c.setHex(COLORS[t.state]).toArray(rgb, 3 * i);
    states[t.state]++;
  });
  setPoints(tipPoints, xyz, f.tips.length, rgb);
  if (!contiguous) trails.clear();
  const seenNow = new Set();
  for (const t of f.tips) {
    seenNow.add(t.marker);
    let tr = trails.get(t.marker);
    if (!tr) trails.set(t.marker, (tr = []));
    tr.push({ p: t.p, state: t.state });
    if (tr.length > TRAIL) tr.shift();
  }
  for (const k of trails.keys()) if (!seenNow.has(k)) trails.delete(k);
  drawTrails();
  tm.frames++;
  if (tm.firstFrameAt === null) {
    tm.firstFrameAt = performance.now();
    if (!tree) frameCamera(boundsOf(f.markers));
  }
  tm.last = { frame: f.frame, time: f.time, markers: m, tips: f.tips.length, noise, states };
  tm.shown = {
    markers: rawPoints.geometry.drawRange.count,
    noise: noisePoints.geometry.drawRange.count,
    tips: tipPoints.geometry.drawRange.count,
  };
  lastFrameNo = f.frame;
}

function drawTrails() {
  const pos = [], col = [];
  const c = new THREE.Color();
  for (const tr of trails.values()) {
    for (let i = 1; i < tr.length; i++) {
      const fade = i / tr.length;
      for (const s of [tr[i - 1], tr[i]]) {
        pos.push(...s.p);
        c.setHex(COLORS[s.state]).multiplyScalar(0.35 + 0.65 * fade).toArray(col, col.length);
      }
    }
  }
  const g = trailLines.geometry;
  g.setAttribute('position', new THREE.Float32BufferAttribute(pos, 3));
  g.setAttribute('color', new THREE.Float32BufferAttribute(col, 3));
}

function boundsOf(xyz) {
  const b = new THREE.Box3();
  const v = new THREE.Vector3();
  for (let i = 0; i + 2 < xyz.length; i += 3) b.expandByPoint(v.set(xyz[i], xyz[i + 1], xyz[i + 2]));
  return b;
}

// ---------------------------------------------------------------- the tree

let tree = null;        // the tree's scene
let treeBounds = null;  // its bounding box, for the camera and the wind arrow
let treeLoading = false, treeWanted = false;

/** Counts the triangles the page draws for an object (meshes only, not lines). */
function triangles(obj) {
  let n = 0;
  obj.traverse((o) => {
    if (!o.isMesh) return;
    const g = o.geometry;
    n += (g.index ? g.index.count : g.getAttribute('position').count) / 3;
  });
  return n;
}

/** The newest tree version announced (status or notice); each is loaded once. */
let treeAsked = 0;
function wantTree(version) {
  if (!(version > treeAsked)) return;
  treeAsked = version;
  loadTree();
}

/** Loads /tree.glb and swaps it in; the camera stays where the person put it. */
async function loadTree() {
  if (treeLoading) { treeWanted = true; return; }
  treeLoading = true;
  try {
    const res = await fetch('tree.glb', { cache: 'no-store' });
    if (res.status === 404) return; // no tree yet
    if (!res.ok) throw new Error(`GET tree.glb: HTTP ${res.status}`);
    const version = Number(res.headers.get('x-tree-version') ?? NaN);
    const gltf = await new GLTFLoader().parseAsync(await res.arrayBuffer(), '');
    const first = tree === null;
    if (tree) {
      layers.tree.remove(tree);
      tree.traverse((o) => { o.geometry?.dispose(); o.material?.dispose?.(); });
    }
    tree = gltf.scene;
    layers.tree.add(tree);
    rigTree(tree);
    treeBounds = new THREE.Box3().setFromObject(tree);
    tm.treeLoads++;
    tm.tree = { version: Number.isNaN(version) ? null : version, triangles: triangles(tree),
      loadedAt: performance.now() };
    if (first) frameCamera(treeBounds);
    placeWind();
  } catch (e) {
    tm.errors.push(String(e));
    console.warn(`treemocap: tree not loaded: ${e}`);
  } finally {
    treeLoading = false;
    if (treeWanted) { treeWanted = false; loadTree(); }
  }
}

// ---------------------------------------------------------------- the sway

/**
 * The live sway (README, "The live view"): the daemon's `pose` events carry
 * every node's displacement from its rest position (µm, node order), and
 * /tree.glb has one joint per node in the same order, nested as the
 * skeleton, each translated from its parent by its rest offset. A pose sets
 * each joint's translation to rest offset + own displacement − parent's
 * displacement, so every joint lands at rest + displacement and the skinned
 * branches follow. With several trees every tree has its own skeleton and
 * its own pose events, named as the tree (`name`; its scene node holds the
 * root joint). Only the latest pose of each tree is kept; it is applied on
 * the next animation frame, before drawing (at most one frame behind).
 */
const sway = {
  on: true,
  trees: new Map(), // per tree ('' for a tree alone): { bones, parent, rest }
  pending: new Map(), // per tree: the latest pose event not yet applied
  lastAt: 0,        // performance.now() when the last pose was applied
};
/** Without a pose for this long the stream has stopped: back to the rest pose. */
const POSE_STALE_MS = 1000;

/** The key of a tree in `sway.trees`: '' for a tree alone, else its node's name. */
const swayKey = (name) => (name === undefined ? '' : THREE.PropertyBinding.sanitizeNodeName(name));

/** Finds the joints of every tree of a freshly loaded scene (none: a still tree). */
function rigTree(scene) {
  sway.trees = new Map();
  sway.pending.clear();
  tm.pose = null;
  tm.swayFrames = {};
  const roots = new Set();
  scene.traverse((o) => {
    if (!o.isSkinnedMesh || roots.has(o.skeleton.bones[0])) return;
    const bones = o.skeleton.bones;
    roots.add(bones[0]);
    // A tree alone's root joint is `node_0`; a tree of several hangs its
    // root joint on a scene node named as the tree.
    const key = bones[0].name === 'node_0' ? '' : bones[0].parent?.name ?? '';
    const index = new Map(bones.map((b, i) => [b, i]));
    const rest = new Float64Array(3 * bones.length);
    bones.forEach((b, i) => b.position.toArray(rest, 3 * i));
    sway.trees.set(key, { bones, parent: Int32Array.from(bones, (b) => index.get(b.parent) ?? -1), rest });
  });
}

/** Puts every joint back at its rest translation. */
function restPose() {
  tm.swayFrames = {};
  for (const { bones, rest } of sway.trees.values()) bones.forEach((b, i) => b.position.fromArray(rest, 3 * i));
  tm.pose = null;
}

/** Applies a pose event to its tree, if the tree shown has it. */
function applyPose(p) {
  const t = sway.trees.get(swayKey(p.name));
  const d = p.d_um;
  const skip = !sway.on ? 'sway off' : !t ? 'no such tree' : p.tree !== tm.tree?.version ? `tree ${tm.tree?.version} shown`
    : d?.length !== 3 * t.bones.length ? `${d?.length} values for ${t.bones.length} joints` : null;
  if (skip) {
    tm.poseSkipped = { frame: p.frame, tree: p.tree, why: skip };
    return;
  }
  const { bones, parent, rest } = t;
  for (let i = 0; i < bones.length; i++) {
    const j = parent[i], k = 3 * i;
    const px = j < 0 ? 0 : d[3 * j], py = j < 0 ? 0 : d[3 * j + 1], pz = j < 0 ? 0 : d[3 * j + 2];
    bones[i].position.set(rest[k] + (d[k] - px) * 1e-6, rest[k + 1] + (d[k + 1] - py) * 1e-6,
      rest[k + 2] + (d[k + 2] - pz) * 1e-6);
  }
  sway.lastAt = performance.now();
  tm.pose = { tree: p.tree, frame: p.frame, time: p.time_s };
  if (p.name !== undefined) tm.pose.name = p.name;
  tm.swayFrames[swayKey(p.name)] = p.frame;
  tm.poses++;
  tm.lastPoseFrame = p.frame;
}

/** Once per animation frame: the latest poses, or the rest pose when the stream stopped. */
function stepSway(now) {
  for (const p of sway.pending.values()) applyPose(p);
  sway.pending.clear();
  if (tm.pose && now - sway.lastAt > POSE_STALE_MS) restPose();
}

/**
 * What the trees show now: the pose and the world position (m) of every
 * captured tip's joint (`tip_07`, unique across trees), read in one go so
 * they belong together.
 */
tm.swayProbe = () => {
  const tips = {};
  if (tree && sway.trees.size) {
    tree.updateMatrixWorld(true);
    const w = new THREE.Vector3();
    for (const { bones } of sway.trees.values()) {
      for (const b of bones) if (b.name.startsWith('tip_')) tips[b.name] = b.getWorldPosition(w).toArray();
    }
  }
  return { pose: tm.pose, frames: { ...tm.swayFrames }, tree: tm.tree?.version ?? null, tips };
};

document.getElementById('sway').addEventListener('change', (ev) => {
  sway.on = ev.currentTarget.checked;
  if (!sway.on) restPose();
});

// ---------------------------------------------------------------- camera

function frameCamera(box) {
  if (!box || box.isEmpty()) box = new THREE.Box3(new THREE.Vector3(-1, 0, -1), new THREE.Vector3(1, 2, 1));
  const c = box.getCenter(new THREE.Vector3());
  const r = Math.max(box.getSize(new THREE.Vector3()).length() / 2, 0.3);
  const d = r / Math.sin(THREE.MathUtils.degToRad(camera.fov / 2));
  controls.target.copy(c);
  camera.position.set(c.x + 0.55 * d, c.y + 0.35 * d, c.z + 0.75 * d);
  camera.near = d / 100;
  camera.far = d * 20;
  camera.updateProjectionMatrix();
  controls.update();
}

document.getElementById('reset').addEventListener('click', () => {
  frameCamera(treeBounds ?? (tm.last ? boundsOf(rawPoints.geometry.getAttribute('position').array
    .subarray(0, 3 * tm.last.markers)) : null));
});

// ---------------------------------------------------------------- wind

function placeWind() {
  const w = tm.status?.wind;
  if (windArrow) { layers.wind.remove(windArrow); windArrow.dispose(); windArrow = null; }
  if (!w) { windLabel.el.textContent = ''; return; }
  const dir = new THREE.Vector3(w.direction[0], 0, w.direction[2]);
  if (dir.lengthSq() < 1e-9) return;
  dir.normalize();
  const len = w.speed_m_s == null ? 0.8 : Math.min(0.4 + 0.15 * w.speed_m_s, 2.0);
  const base = treeBounds ? treeBounds.getCenter(new THREE.Vector3()) : new THREE.Vector3();
  base.y = 0.05;
  base.addScaledVector(dir, -len / 2);
  windArrow = new THREE.ArrowHelper(dir, base, len, COLORS.wind, 0.15, 0.08);
  layers.wind.add(windArrow);
  windLabel.pos.copy(base).addScaledVector(dir, len + 0.15);
  const speed = w.speed_m_s == null ? 'speed unknown' : `${w.speed_m_s.toFixed(1)} m/s`;
  windLabel.el.textContent = `wind (${w.source}) ${speed}`;
}

// ---------------------------------------------------------------- status panel

const fmt = {
  n: (x) => (x == null ? '–' : Number(x).toLocaleString('en')),
  hz: (x) => (x == null || !x ? '–' : `${x.toFixed(1)} Hz`),
  us: (x) => (x == null ? '–' : x >= 1000 ? `${(x / 1000).toFixed(1)} ms` : `${x} µs`),
  ms: (x) => (x == null ? '–' : `${x.toFixed(0)} ms`),
};

function trigger(reason) {
  if (!reason) return '–';
  if (typeof reason === 'string') return reason;
  const t = reason.trigger ?? '?';
  if (t === 'tips_changed') return `tips changed (+${reason.added} −${reason.removed} ~${reason.moved})`;
  if (t === 'wind_turned') return `wind turned ${reason.degrees.toFixed(0)}°`;
  return t.replaceAll('_', ' ');
}

/** Input the sources rejected: `/status` counts it by source and kind. */
function badInput(b) {
  if (b == null) return null;
  if (typeof b === 'number') return b;
  return Object.values(b).reduce((sum, v) => sum + (badInput(v) ?? 0), 0);
}

function stillLine(s) {
  const st = s.still;
  if (!st) return '–';
  if (st.still_s == null) return `waiting (needs ${st.needed_s} s)`;
  return `still for ${st.still_s.toFixed(1)} s of ${st.needed_s} s needed`;
}

function renderStatus() {
  const s = tm.status;
  if (!s) return;
  const conn = s.connection ?? {};
  const rows = [
    ['source', s.source ?? '–'],
    ['connection', conn.state ? `${conn.state}${conn.silent_s ? ` (${conn.silent_s.toFixed(1)} s)` : ''}` : '–',
      conn.state && conn.state !== 'receiving'],
  ];
  if (s.source_error) rows.push(['source error', s.source_error, true]);
  if (tm.mode === 'view') {
    rows.push(['frames', fmt.n(s.frames)], ['frame rate', fmt.hz(s.frame_rate_hz)],
      ['tips', fmt.n(s.tips)], ['tree', s.tree ? 'from the folder' : 'none (recording only)']);
  } else {
    rows.push(
      ['frame rate', fmt.hz(s.frame_rate_hz)],
      ['markers/frame', fmt.n(s.markers)],
      ['tips live', `${fmt.n(s.tips_live)} of ${fmt.n(s.tips)}`],
      ['frames', fmt.n(s.frames)],
      ['dropped', fmt.n(s.dropped), s.dropped > 0],
      ['bad input', fmt.n(badInput(s.bad_input)), badInput(s.bad_input) > 0],
      ['still phase', stillLine(s)],
      ['analyses', fmt.n(s.analyses)],
      ['trees', `${fmt.n(s.trees)}${s.tree_version ? ` (version ${s.tree_version})` : ''}`],
      ['last trigger', trigger(s.last_tree?.reason)],
      ['build time', s.last_tree ? `${fmt.ms(s.last_tree.build_ms)} (trigger → viewers ${fmt.ms(s.last_tree.trigger_to_outputs_ms)})` : '–'],
      ['latency p50/p99', `${fmt.us(s.latency_us?.p50)} / ${fmt.us(s.latency_us?.p99)}`],
      ['output errors', s.output_error ?? 'none', !!s.output_error],
    );
    if (s.config_error) rows.push(['config error', s.config_error, true]);
  }
  const w = s.wind;
  rows.push(['wind', w ? `${w.source}, towards ${w.azimuth_deg.toFixed(0)}°, ${w.speed_m_s == null ? 'speed unknown' : `${w.speed_m_s.toFixed(1)} m/s`}` : 'none yet']);
  if (tm.last) {
    const st = tm.last.states;
    rows.push(['this frame', `#${tm.last.frame}: ${tm.last.markers} markers, ${st.measured} measured, ${st.filled} filled, ${st.unseen} not seen, ${tm.last.noise} noise`]);
  }
  if (tm.tree) rows.push(['tree shown', `version ${tm.tree.version ?? '?'}, ${fmt.n(tm.tree.triangles)} triangles`]);
  if (tm.mode === 'live' && tm.tree) {
    rows.push(['sway', !sway.on ? 'off (rest pose)' : tm.pose ? `live tips of frame #${tm.pose.frame}`
      : sway.trees.size ? 'rest pose (no live pose)' : 'none (tree without joints)']);
  }
  const dl = document.getElementById('status');
  dl.replaceChildren(...rows.flatMap(([k, v, bad]) => {
    const dt = document.createElement('dt'); dt.textContent = k;
    const dd = document.createElement('dd'); dd.textContent = v;
    if (bad) dd.className = 'bad';
    return [dt, dd];
  }));
}

function setStatus(s) {
  const windChanged = JSON.stringify(s.wind) !== JSON.stringify(tm.status?.wind);
  tm.status = s;
  if (windChanged) placeWind();
  if (tm.mode === 'live') wantTree(s.tree_version);
  renderStatus();
}

// ---------------------------------------------------------------- live

const connEl = document.getElementById('conn');
function setConn(text, cls) { connEl.textContent = text; connEl.className = `pill ${cls}`; }

let pending = null; // the latest frame not yet drawn: drawing is once per animation frame
function connect() {
  const url = new URL('live', location.href);
  url.protocol = location.protocol === 'https:' ? 'wss:' : 'ws:';
  const ws = new WebSocket(url);
  ws.binaryType = 'arraybuffer';
  ws.onopen = () => { tm.connected = true; tm.connects++; setConn('connected', ''); };
  ws.onclose = () => {
    tm.connected = false;
    sway.pending.clear();
    restPose();
    setConn('disconnected: retrying', 'off');
    setTimeout(connect, 1000);
  };
  ws.onmessage = (ev) => {
    if (typeof ev.data !== 'string') {
      try { pending = decodeFrame(ev.data); } catch (e) { tm.errors.push(String(e)); }
      return;
    }
    const msg = JSON.parse(ev.data);
    if (msg.type === 'pose') {
      sway.pending.set(swayKey(msg.name), msg);
      tm.lastPoseSeen = { tree: msg.tree, frame: msg.frame };
    }
    else if (msg.type === 'status') setStatus(msg.status);
    else if (msg.type === 'tree') wantTree(msg.version);
  };
}

document.getElementById('rebuild').addEventListener('click', async (ev) => {
  const b = ev.currentTarget;
  b.disabled = true;
  try {
    const res = await fetch('rebuild', { method: 'POST' });
    if (!res.ok) throw new Error(`POST rebuild: HTTP ${res.status}`);
  } catch (e) {
    tm.errors.push(String(e));
  } finally {
    setTimeout(() => { b.disabled = false; }, 500);
  }
});

// ---------------------------------------------------------------- view (recorded session)

const scrub = document.getElementById('scrub');
const clock = document.getElementById('clock');
let viewWanted = null, viewBusy = false, playing = false;

/** Shows frame `i` of the session; while one is loading only the latest request is kept. */
async function seek(i) {
  viewWanted = i;
  if (viewBusy) return;
  viewBusy = true;
  try {
    while (viewWanted !== null) {
      const want = viewWanted;
      viewWanted = null;
      const res = await fetch(`frame/${want}`);
      if (!res.ok) throw new Error(`GET frame/${want}: HTTP ${res.status}`);
      const f = decodeFrame(await res.arrayBuffer());
      showFrame(f, tm.viewFrame !== null && want === tm.viewFrame + 1);
      tm.viewFrame = want;
      scrub.value = String(want);
      const s = tm.session;
      clock.textContent = `frame ${f.frame} · ${f.time.toFixed(2)} s of ${s.duration_s.toFixed(2)} s`;
      renderStatus();
    }
  } catch (e) {
    tm.errors.push(String(e));
  } finally {
    viewBusy = false;
  }
}
tm.seek = seek;

async function startView() {
  tm.mode = 'view';
  document.getElementById('mode').textContent = 'recorded session';
  document.getElementById('rebuild').hidden = true;
  setConn('file', '');
  const s = await (await fetch('session.json')).json();
  tm.session = s;
  if (s.tree) await loadTree();
  if (s.frames === 0) return; // an output folder without its recording: the tree only
  document.getElementById('timeline').hidden = false;
  scrub.max = String(Math.max(0, s.frames - 1));
  scrub.addEventListener('input', () => { playing = false; setPlay(); seek(Number(scrub.value)); });
  document.getElementById('play').addEventListener('click', () => { playing = !playing; setPlay(); });
  await seek(0);
}

function setPlay() { document.getElementById('play').textContent = playing ? '⏸' : '▶'; }

let playClock = null;
function stepPlay(now) {
  if (!playing || !tm.session || viewBusy) { playClock = now; return; }
  const s = tm.session;
  const dt = playClock === null ? 0 : (now - playClock) / 1000;
  const step = Math.max(1, Math.round(dt * s.frame_rate_hz));
  if (dt * s.frame_rate_hz < 1) return;
  playClock = now;
  const next = (tm.viewFrame ?? 0) + step;
  if (next >= s.frames) { playing = false; setPlay(); return; }
  seek(next);
}

// ---------------------------------------------------------------- layers, resize, loop

for (const box of document.querySelectorAll('input[data-layer]')) {
  const apply = () => {
    layers[box.dataset.layer].visible = box.checked;
    for (const p of pinned) if (p.layer === box.dataset.layer) p.el.hidden = !box.checked;
  };
  box.addEventListener('change', apply);
  apply();
}
tm.layers = () => Object.fromEntries(Object.entries(layers).map(([k, g]) => [k, g.visible]));

function resize() {
  const w = window.innerWidth, h = window.innerHeight;
  renderer.setSize(w, h, false);
  camera.aspect = w / h;
  camera.updateProjectionMatrix();
}
window.addEventListener('resize', resize);
resize();

const v = new THREE.Vector3();
function placeLabels() {
  const w = window.innerWidth, h = window.innerHeight;
  for (const p of pinned) {
    v.copy(p.pos).project(camera);
    const behind = v.z > 1;
    p.el.style.display = behind || !p.el.textContent ? 'none' : '';
    p.el.style.left = `${(v.x * 0.5 + 0.5) * w}px`;
    p.el.style.top = `${(-v.y * 0.5 + 0.5) * h}px`;
  }
}

let lastPanel = 0;
function loop(now) {
  requestAnimationFrame(loop);
  if (pending) { showFrame(pending, lastFrameNo !== null && pending.frame > lastFrameNo); pending = null; }
  stepSway(now);
  stepPlay(now);
  if (now - lastPanel > 250) { lastPanel = now; if (tm.mode === 'live') renderStatus(); }
  controls.update();
  placeLabels();
  renderer.render(scene, camera);
  tm.rendered = (tm.rendered ?? 0) + 1;
}

async function main() {
  frameCamera(null);
  requestAnimationFrame(loop);
  let s = null;
  try { s = await (await fetch('status', { cache: 'no-store' })).json(); } catch (e) { tm.errors.push(String(e)); }
  if (s?.mode === 'view') {
    tm.status = s;
    await startView();
    setStatus(s);
  } else {
    if (s) setStatus(s); // loads the tree if there is one: no request that would 404
    connect();
  }
  tm.ready = true;
}
main();
