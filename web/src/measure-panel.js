// The measuring tool of the panel: with "Measure" on, clicks on surfaces (or on section caps)
// place up to two points; the page shows their distance and, for each point, the distance to
// the nearest other shown structure (exact point-to-triangle, measure.js, over the full-detail
// triangles once they are loaded). Points are in mm, the page's display frame.
import { distance, nearestStructure } from './measure.js';

const $ = (id) => document.getElementById(id);
const fmt = (mm) => `${mm.toFixed(2)} mm`;

/** The shown structures' current triangles as measure.js wants them. */
function shownMeshes(viewer) {
  return viewer.items.filter((it) => it.front.visible && it.front.geometry.index).map((it) => {
    const g = it.front.geometry;
    return { name: it.s.name, positions: g.getAttribute('position').array, indices: g.index.array,
      box: { min: g.boundingBox.min.toArray(), max: g.boundingBox.max.toArray() } };
  });
}

/** For point p: the structure it lies on (the nearest) and the nearest other one,
 *  {on: {name, distance}, other: {name, distance, point} | null}, or null. */
export function nearestOther(viewer, p) {
  const meshes = shownMeshes(viewer);
  const on = nearestStructure(p, meshes);
  if (!on) return null;
  return { on, other: nearestStructure(p, meshes.filter((m) => m.name !== on.name)) };
}

/** Wire the tool; `changed()` is called when the points change. Returns {points, setPoints,
 *  refresh, report}: refresh() measures again (after a finer level arrived), report() =
 *  {distance (mm) or null, near: [nearestOther per point]}. */
export function wireMeasure(viewer, changed) {
  let points = [];
  const report = () => ({ distance: points.length === 2 ? distance(points[0], points[1]) : null,
    near: points.map((p) => nearestOther(viewer, p)) });
  function show() {
    viewer.setMarkers(points);
    const r = report();
    const lines = r.near.map((n, k) => {
      const name = 'AB'[k];
      if (!n) return `${name}: no structure shown`;
      const other = n.other ? `${fmt(n.other.distance)} to ${n.other.name}` : 'no other structure shown';
      return `${name} on ${n.on.name}: ${other}`;
    });
    if (r.distance != null) lines.unshift(`A–B: ${fmt(r.distance)}`);
    $('measure-out').textContent = lines.join('\n');
    $('measure-out').hidden = !lines.length;
  }
  viewer.renderer.domElement.addEventListener('click', (e) => {
    if (!$('measure').checked) return;
    const hit = viewer.pick(e.offsetX, e.offsetY);
    if (!hit) return;
    points = points.length >= 2 ? [hit.point] : [...points, hit.point];
    show();
    changed();
  });
  $('measure').addEventListener('change', () => {
    if (!$('measure').checked && points.length) { points = []; show(); changed(); }
  });
  return {
    points: () => points.map((p) => p.slice()),
    setPoints: (ps) => { points = ps.map((p) => p.slice()); if (ps.length) $('measure').checked = true; show(); },
    refresh: () => { if (points.length) show(); },
    report,
  };
}
