// The page: reads scene.js (window.ANATOMESH_SCENE), loads the levels of detail coarse to fine
// (each data/lodK.js calls window.anatomeshLevel), and wires the side panel to the 3D view.
// Works from file:// (classic scripts only: no fetch, no modules) and from any static server.
import { MeshoptDecoder } from 'meshoptimizer/decoder';
import { decodeLevel } from './data.js';
import { buildTree, cssColor, groupBySystem } from './tree.js';
import { volumeText } from './view-math.js';
import { Viewer } from './viewer.js';

const $ = (id) => document.getElementById(id);
const pending = new Map();   // level → resolve(text) of a level script requested
const arrived = new Map();   // level → text of a level script that came first (index.html's)
/** What tests (and curious users, from the console) can read: timings and the view. */
const api = { firstFrameMs: null, levels: [], errors: [] };
window.anatomesh = api;
window.anatomeshLevel = (level, text) => {
  const resolve = pending.get(level);
  if (resolve) resolve(text);
  else arrived.set(level, text);
};

function loadLevelScript(level, file) {
  if (arrived.has(level)) return Promise.resolve(arrived.get(level));
  return new Promise((resolve, reject) => {
    pending.set(level, resolve);
    const s = document.createElement('script');
    s.src = file;
    s.onerror = () => reject(new Error(`cannot load ${file}: keep the page's folder together`));
    document.head.append(s);
  });
}

function setStatus(text) { $('status').textContent = text; }

function showInfo(s, viewer) {
  if (!s) { $('info').hidden = true; return; }
  const d = viewer.model.distance;
  const lines = [`<b>${escapeHtml(s.name)}</b>`, escapeHtml(s.system || '')];
  if (s.volume_mm3 != null) lines.push(`volume ${volumeText(s.volume_mm3)}`);
  if (d && s.min_distance_mm != null) lines.push(`${s.min_distance_mm.toFixed(1)} mm from ${escapeHtml(d.target)}`);
  $('info').innerHTML = lines.filter(Boolean).join('<br>');
  $('info').hidden = false;
}

function escapeHtml(t) {
  return String(t).replace(/[&<>"]/g, (c) => ({ '&': '&amp;', '<': '&lt;', '>': '&gt;', '"': '&quot;' })[c]);
}

function updateScale(viewer) {
  const bar = viewer.scaleBar(110);
  $('scale-bar').style.width = `${bar.px}px`;
  $('scale-label').textContent = bar.label;
}

function wireModel(viewer, m) {
  viewer.setModel(m);
  const model = viewer.model;
  const tree = buildTree(document, $('tree'), model.structures,
    groupBySystem(model.structures, viewer.data.systems), viewer.items, {
      visible: (i, on) => { viewer.items[i].visible = on; viewer.refreshMaterials(); },
      opacity: (i, a) => { viewer.items[i].opacity = a; viewer.refreshMaterials(); },
      hover: (i) => showInfo(i == null ? null : model.structures[i], viewer),
    });
  const d = model.distance;
  $('distance').hidden = !d;
  if (d) {
    $('distance-target').textContent = d.target;
    $('legend').replaceChildren(...d.margins.map((mm, k) => {
      const e = document.createElement('span');
      e.innerHTML = `<i style="background:${cssColor(d.colors[k])}"></i>≤ ${mm} mm`;
      return e;
    }));
    viewer.showDistance = $('show-distance').checked;
    viewer.refreshMaterials();
  }
  return tree;
}

function wirePanel(viewer) {
  const scene = viewer.data;
  $('title').textContent = scene.title;
  document.title = `${scene.title} — Anatomesh`;
  if (scene.models.length > 1) {
    $('model').hidden = false;
    $('model').replaceChildren(...scene.models.map((m, k) => new Option(m.name, k)));
    $('model').addEventListener('change', () => wireModel(viewer, +$('model').value));
  }
  $('reset').addEventListener('click', () => viewer.resetView());
  $('oriented').addEventListener('change', () => {
    viewer.uniforms.uOriented.value = $('oriented').checked ? 1 : 0;
    viewer.requestRender();
  });
  $('show-distance').addEventListener('change', () => {
    viewer.showDistance = $('show-distance').checked;
    viewer.refreshMaterials();
  });
  const clip = () => {
    const axis = $('clip-axis').value;
    viewer.clipping = axis ? { axis, fraction: +$('clip-at').value, flip: $('clip-flip').checked } : null;
    viewer.refreshMaterials();
  };
  for (const id of ['clip-axis', 'clip-at', 'clip-flip']) $(id).addEventListener('input', clip);
  const canvas = viewer.renderer.domElement;
  let timer = null;
  let pinned = null;
  canvas.addEventListener('pointermove', (e) => {
    clearTimeout(timer);
    timer = setTimeout(() => showInfo(viewer.pick(e.offsetX, e.offsetY) || pinned, viewer), 60);
  });
  canvas.addEventListener('click', (e) => {
    pinned = viewer.pick(e.offsetX, e.offsetY);
    showInfo(pinned, viewer);
  });
}

async function start() {
  performance.mark('anatomesh:start');
  const scene = window.ANATOMESH_SCENE;
  if (!scene) { setStatus('scene.js is missing: keep the page\'s folder together'); return; }
  if (scene.format !== 'anatomesh-web/1') { setStatus(`unknown scene format ${scene.format}`); return; }
  let firstFrame = null;
  const viewer = new Viewer($('view'), scene, () => {
    updateScale(viewer);
    if (firstFrame) { firstFrame(); firstFrame = null; }
  });
  api.viewer = viewer;
  api.screenBox = (name) => viewer.screenBox(name);
  api.pixels = () => {  // the canvas's pixels as base64 RGBA, rows bottom up (for tests)
    const { width, height, rgba } = viewer.readPixels();
    let bin = '';
    for (let i = 0; i < rgba.length; i += 0x8000) bin += String.fromCharCode(...rgba.subarray(i, i + 0x8000));
    return { width, height, data: btoa(bin) };
  };
  wirePanel(viewer);
  wireModel(viewer, 0);
  for (const [k, level] of scene.levels.entries()) {
    const text = await loadLevelScript(k, level.file);
    performance.mark(`anatomesh:lod${k}-loaded`);
    const decoded = await decodeLevel(scene, k, text, MeshoptDecoder);
    performance.mark(`anatomesh:lod${k}-decoded`);
    viewer.addLevel(k, decoded);
    performance.mark(`anatomesh:lod${k}-shown`);
    if (k === 0) {
      viewer.resetView();
      await new Promise((resolve) => { firstFrame = resolve; });
      api.firstFrameMs = performance.now();
    }
    api.levels.push({ triangles: level.triangles, bytes: level.bytes, ms: performance.now() });
    const finest = k === scene.levels.length - 1;
    setStatus(`${finest ? 'full detail' : 'coarse preview'}: ${level.triangles.toLocaleString('en')} triangles`
      + (finest ? '' : ', loading finer…'));
  }
  api.done = true;
}

window.addEventListener('error', (e) => api.errors.push(String(e.message)));
// after the parser ran index.html's scripts, the coarsest level's included
document.addEventListener('DOMContentLoaded', () => start().catch((err) => {
  api.errors.push(String(err.message || err));
  setStatus(String(err.message || err));
  console.error(err);
}));
