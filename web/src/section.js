// The section of a surface by an axis-aligned plane: the segments where its triangles cross the
// plane, which outline a structure on a cut. Pure: tested with node's test runner.

/** Whether a vertex `d` mm from the plane counts as below it (on the plane counts as above, so
 *  a triangle crossing the plane has exactly two edges that cross it). */
const below = (d) => d < 0;

/** Segments where the triangles of a mesh (positions: 3 per vertex, mm; indices: 3 per
 *  triangle) cross the plane where coordinate `axis` (0 x, 1 y, 2 z) equals `at` (mm):
 *  Float32Array of 6 numbers per segment, its two ends (mm, on the plane). */
export function planeSection(positions, indices, axis, at) {
  const p = positions;
  const crossing = [];
  for (let t = 0; t < indices.length; t += 3) {
    const n = below(p[3 * indices[t] + axis] - at) + below(p[3 * indices[t + 1] + axis] - at)
      + below(p[3 * indices[t + 2] + axis] - at);
    if (n === 1 || n === 2) crossing.push(t);
  }
  const out = new Float32Array(6 * crossing.length);
  let o = 0;
  const cut = (i, j) => {  // the point where edge (i, j), ends on opposite sides, meets the plane
    const di = p[3 * i + axis] - at;
    const s = di / (di - (p[3 * j + axis] - at));
    for (let k = 0; k < 3; k++) out[o++] = p[3 * i + k] + s * (p[3 * j + k] - p[3 * i + k]);
    out[o - 3 + axis] = at;
  };
  for (const t of crossing) {
    const v = [indices[t], indices[t + 1], indices[t + 2]];
    for (let e = 0; e < 3; e++) {
      const [i, j] = [v[e], v[(e + 1) % 3]];
      if (below(p[3 * i + axis] - at) !== below(p[3 * j + axis] - at)) cut(i, j);
    }
  }
  return out;
}
