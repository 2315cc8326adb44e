// The page: reads scene.js (window.ANATOMESH_SCENE), shows the levels of detail coarse to fine
// (each data/lodK.js calls window.anatomeshLevel) and wires the side panel to the 3D view.
// Works from file:// (classic scripts only: no fetch, no modules) and from any static server.
//
// The coarsest level is a script of index.html; the finer ones are requested as the page starts,
// so the page's load event waits for them. Each level is decoded and drawn in the task its script
// runs in (a coarser one arriving after a finer one is dropped), so the load event comes after
// the full detail is drawn: a plain screenshot (taken at the load event) shows it.
import { MeshoptDecoder } from 'meshoptimizer/decoder';
import { decodeLevel, inflate, z85ToBytes } from './data.js';
import { wireMeasure } from './measure-panel.js';
import { buildTree, cssColor, groupBySystem } from './tree.js';
import { wireUrlState } from './url-sync.js';
import { volumeText } from './view-math.js';
import { Viewer } from './viewer.js';

const $ = (id) => document.getElementById(id);
const texts = new Map();     // level → [Z85 text, bytes] of a level script arrived, not yet shown
/** What tests (and curious users, from the console) can read: timings, readiness (`done`: the
 *  full detail is drawn; also <html data-anatomesh="full">), the viewer, the URL state (`url`)
 *  and the measuring tool (`measure`). */
const api = { firstFrameMs: null, levels: [], errors: [], warnings: [], done: false };
window.anatomesh = api;
let decoderReady = false;
let onFirstLevel = () => {};
MeshoptDecoder.ready.then(() => { decoderReady = true; showArrived(); });
window.anatomeshLevel = (level, text, bytes) => {
  texts.set(level, [text, bytes]);
  showArrived();
};

/** A level script that did not load (its onerror). */
window.anatomeshMissing = (script) => {
  fail(new Error(`cannot load ${script.getAttribute('src')}: keep the page's folder together`));
};

function requestLevelScript(file) {
  const s = document.createElement('script');
  s.src = file;
  s.onerror = () => window.anatomeshMissing(s);
  document.head.append(s);
}

/** 1234567 → "1,234,567". */
function thousands(n) { return String(n).replace(/\B(?=(\d{3})+$)/g, ','); }

function setStatus(text) { $('status').textContent = text; }

function fail(err) {
  api.errors.push(String(err.message || err));
  setStatus(String(err.message || err));
  console.error(err);
}

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

/** The tooltip follows what is shown: it names what is under the pointer (or the structure
 *  clicked) now, so a structure hidden or clipped away loses its tooltip. */
function tooltip(viewer) {
  let pointer = null;
  let pinned = null;
  let timer = null;
  const refresh = () => {
    const under = pointer && viewer.pick(pointer.x, pointer.y);
    const held = pinned && viewer.pick(pinned.x, pinned.y);
    showInfo((under || held || {}).s || null, viewer);
  };
  const canvas = viewer.renderer.domElement;
  canvas.addEventListener('pointermove', (e) => {
    pointer = { x: e.offsetX, y: e.offsetY };
    clearTimeout(timer);
    timer = setTimeout(refresh, 60);
  });
  canvas.addEventListener('pointerleave', () => { pointer = null; refresh(); });
  canvas.addEventListener('click', (e) => {
    pinned = viewer.pick(e.offsetX, e.offsetY) ? { x: e.offsetX, y: e.offsetY } : null;
    refresh();
  });
  return { refresh, hover: (s) => showInfo(s, viewer) };
}

function wireModel(viewer, m, on) {
  viewer.setModel(m);
  const model = viewer.model;
  const tree = buildTree(document, $('tree'), model.structures,
    groupBySystem(model.structures, viewer.data.systems), viewer.items, {
      visible: (i, v) => { viewer.items[i].visible = v; on.change(); },
      opacity: (i, a) => { viewer.items[i].opacity = a; on.change(); },
      hover: (i) => on.hover(i == null || !viewer.items[i].front.visible ? null : model.structures[i]),
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

function wirePanel(viewer, on) {
  const scene = viewer.data;
  $('title').textContent = scene.title;
  document.title = `${scene.title} — Anatomesh`;
  $('oriented').addEventListener('change', () => {
    viewer.uniforms.uOriented.value = $('oriented').checked ? 1 : 0;
    viewer.requestRender();
  });
  $('show-distance').addEventListener('change', () => {
    viewer.showDistance = $('show-distance').checked;
    viewer.refreshMaterials();
  });
  const clip = () => {
    const plane = $('clip-axis').value;
    viewer.clipping = plane ? { plane, fraction: +$('clip-at').value, flip: $('clip-flip').checked,
      outline: $('clip-outline').checked } : null;
    on.change();
  };
  for (const id of ['clip-axis', 'clip-at', 'clip-flip', 'clip-outline']) $(id).addEventListener('input', clip);
}

/** Draw the finest level arrived so far, now (once the viewer and the decoder are ready). */
function showArrived() {
  const viewer = api.viewer;
  if (!viewer || !decoderReady || !texts.size) return;
  const k = Math.max(...texts.keys());
  const [text, bytes] = texts.get(k);
  texts.clear();
  if (k <= viewer.level) return;
  performance.mark(`anatomesh:lod${k}-loaded`);
  try { showLevel(k, inflate(z85ToBytes(text, bytes))); } catch (err) { fail(err); }
}

/** Decode level `k` from its inflated bytes and draw it now. */
function showLevel(k, blob) {
  const viewer = api.viewer;
  const scene = viewer.data;
  performance.mark(`anatomesh:lod${k}-inflated`);
  viewer.addLevel(k, decodeLevel(scene, k, blob, MeshoptDecoder));
  performance.mark(`anatomesh:lod${k}-decoded`);
  const first = api.levels.length === 0;
  if (first) onFirstLevel();
  viewer.renderNow();
  performance.mark(`anatomesh:lod${k}-shown`);
  const level = scene.levels[k];
  api.levels.push({ level: k, triangles: level.triangles, bytes: level.bytes, ms: performance.now() });
  if (first) requestAnimationFrame(() => { api.firstFrameMs = performance.now(); });
  const finest = k === scene.levels.length - 1;
  setStatus(`${finest ? 'full detail' : 'coarse preview'}: ${thousands(level.triangles)} triangles`
    + (finest ? '' : ', loading finer…'));
  if (finest) {
    api.measure.refresh();  // distances to the nearest structure over the full-detail triangles
    api.done = true;
    document.documentElement.dataset.anatomesh = 'full';
  }
}

function start() {
  performance.mark('anatomesh:start');
  const scene = window.ANATOMESH_SCENE;
  if (!scene) { setStatus('scene.js is missing: keep the page\'s folder together'); return; }
  if (scene.format !== 'anatomesh-web/2') { setStatus(`unknown scene format ${scene.format}`); return; }
  const viewer = new Viewer($('view'), scene, () => updateScale(viewer));
  api.viewer = viewer;
  api.screenBox = (name) => viewer.screenBox(name);
  api.pixels = () => {  // the canvas's pixels as base64 RGBA, rows bottom up (for tests)
    const { width, height, rgba } = viewer.readPixels();
    let bin = '';
    for (let i = 0; i < rgba.length; i += 0x8000) bin += String.fromCharCode(...rgba.subarray(i, i + 0x8000));
    return { width, height, data: btoa(bin) };
  };
  const tip = tooltip(viewer);
  let url = null;
  const on = {
    change: () => { viewer.refreshMaterials(); tip.refresh(); if (url) url.changed(); },
    hover: (s) => tip.hover(s),
  };
  wirePanel(viewer, on);
  let tree = wireModel(viewer, 0, on);
  const measure = wireMeasure(viewer, () => url && url.changed());
  url = wireUrlState(viewer, { sync: () => tree.sync(), measure, refresh: () => on.change() });
  api.url = url;
  api.measure = measure;
  if (scene.models.length > 1) {
    $('model').hidden = false;
    $('model').replaceChildren(...scene.models.map((m, k) => new Option(m.name, k)));
    $('model').addEventListener('change', () => { tree = wireModel(viewer, +$('model').value, on); url.apply(); });
  }
  $('reset').addEventListener('click', () => url.reset());
  onFirstLevel = () => url.apply();  // the view in the URL, once there is something to see
  for (const level of scene.levels.slice(1)) requestLevelScript(level.file);  // before the load event
  showArrived();  // the coarsest level, if the decoder is ready
}

window.addEventListener('error', (e) => api.errors.push(String(e.message)));
// after the parser ran index.html's scripts, the coarsest level's included
document.addEventListener('DOMContentLoaded', () => {
  try { start(); } catch (err) { fail(err); }
});
