// Small, pure pieces of the viewer's logic (tested with node's test runner, no browser needed).

/** A scale bar of a round length (1, 2 or 5 × 10^k mm) about `targetPx` pixels long, for a view
 *  showing `pxPerMm` pixels per millimetre: {mm, px, label}. */
export function scaleBar(pxPerMm, targetPx = 100) {
  if (!(pxPerMm > 0) || !Number.isFinite(pxPerMm)) return { mm: 0, px: 0, label: '' };
  const want = targetPx / pxPerMm;
  const p = Math.pow(10, Math.floor(Math.log10(want)));
  let mm = p;
  for (const f of [1, 2, 5, 10]) if (f * p <= want) mm = f * p;
  const label = mm >= 1 ? `${Math.round(mm)} mm` : `${+mm.toPrecision(2)} mm`;
  return { mm, px: mm * pxPerMm, label };
}

/** The order to draw see-through structures so nested ones look right: each structure is drawn
 *  as its back faces and then (later) its front faces, farthest first by a per-item key — a back
 *  face half at the far side of the structure's bounding sphere (depth + radius), a front half at
 *  its near side (depth − radius). Nested shells then draw outer back, inner back, inner front,
 *  outer front; separate ones back to front (painter's algorithm per object).
 *  `items`: [{depth, radius}] (depth grows away from the viewer). Returns [{index, side}] in
 *  drawing order, side 'back' or 'front'. */
export function drawOrder(items) {
  const halves = [];
  items.forEach((it, index) => {
    halves.push({ index, side: 'back', key: it.depth + it.radius });
    halves.push({ index, side: 'front', key: it.depth - it.radius });
  });
  const rank = (h) => (h.side === 'back' ? 0 : 1);
  halves.sort((a, b) => b.key - a.key || rank(a) - rank(b) || a.index - b.index);
  return halves.map(({ index, side }) => ({ index, side }));
}

/** Oriented transparency (Stalling, Zöckler & Hege 1999, after Kay & Greenberg 1979): a surface
 *  seen face-on keeps its opacity `alpha`, toward the silhouette it becomes opaque, so nested
 *  structures stay readable: alpha + (1 − alpha)(1 − |n·v|^exponent). The same formula is in
 *  the shader (viewer.js) and in the Blender material (Layer Weight "Facing", blend 0.35). */
export function orientedAlpha(alpha, cosine, exponent = 0.7) {
  const facing = 1 - Math.pow(Math.min(1, Math.abs(cosine)), exponent);
  return alpha + (1 - alpha) * facing;
}

/** The structure a click or hover means among ray hits sorted near to far ([{id, distance,
 *  opacity}]): the nearest one that is mostly opaque (opacity ≥ 0.5), so a click through a
 *  see-through skin reaches the organ inside; the nearest of all when every hit is see-through. */
export function choosePick(hits) {
  if (!hits.length) return null;
  return hits.find((h) => h.opacity >= 0.5) || hits[0];
}

/** Volume in mm³ as text: mL (= cm³) for anything over 1 mL, else mm³. */
export function volumeText(mm3) {
  if (mm3 == null || !Number.isFinite(mm3)) return '';
  const v = Math.abs(mm3);
  return v >= 1000 ? `${(v / 1000).toFixed(v >= 100000 ? 0 : 1)} mL` : `${v.toFixed(0)} mm³`;
}

/** The clipping plane for an anatomical axis ('x' left-right, 'y' head-foot, 'z' front-back of
 *  the display frame) at `fraction` (0..1) of the scene's box [min, max]: {normal, constant}
 *  such that points with normal·p + constant ≥ 0 are kept (three.js's Plane convention);
 *  `flip` keeps the other side. */
export function clipPlane(axis, fraction, box, flip = false) {
  const k = { x: 0, y: 1, z: 2 }[axis];
  const at = box.min[k] + fraction * (box.max[k] - box.min[k]);
  const s = flip ? 1 : -1;
  const normal = [0, 0, 0];
  normal[k] = s;
  return { normal, constant: -s * at };
}
