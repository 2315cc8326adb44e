// Measuring on the page: distances between picked points and from a point to the nearest
// triangle of other structures, exact in the page's display frame (mm). Pure functions on typed
// arrays (positions: Float32Array x, y, z per vertex; indices: Uint32Array, 3 per triangle).

/** Euclidean distance between two points [x, y, z] (mm). */
export function distance(a, b) {
  return Math.hypot(a[0] - b[0], a[1] - b[1], a[2] - b[2]);
}

/** The point of triangle (a, b, c) nearest to p, all [x, y, z] (Ericson 2005, "Real-Time
 *  Collision Detection", 5.1.5: Voronoi regions of the vertices, edges and face). */
export function closestOnTriangle(p, a, b, c) {
  const sub = (u, v) => [u[0] - v[0], u[1] - v[1], u[2] - v[2]];
  const dot = (u, v) => u[0] * v[0] + u[1] * v[1] + u[2] * v[2];
  const at = (u, s, v, t) => [a[0] + s * u[0] + t * v[0], a[1] + s * u[1] + t * v[1], a[2] + s * u[2] + t * v[2]];
  const ab = sub(b, a); const ac = sub(c, a); const ap = sub(p, a);
  const d1 = dot(ab, ap); const d2 = dot(ac, ap);
  if (d1 <= 0 && d2 <= 0) return a.slice();
  const bp = sub(p, b); const d3 = dot(ab, bp); const d4 = dot(ac, bp);
  if (d3 >= 0 && d4 <= d3) return b.slice();
  const vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return at(ab, d1 / (d1 - d3), ac, 0);
  const cp = sub(p, c); const d5 = dot(ab, cp); const d6 = dot(ac, cp);
  if (d6 >= 0 && d5 <= d6) return c.slice();
  const vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return at(ab, 0, ac, d2 / (d2 - d6));
  const va = d3 * d6 - d5 * d4;
  if (va <= 0 && d4 - d3 >= 0 && d5 - d6 >= 0) {
    const w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
    return [b[0] + w * (c[0] - b[0]), b[1] + w * (c[1] - b[1]), b[2] + w * (c[2] - b[2])];
  }
  const denom = 1 / (va + vb + vc);
  return at(ab, vb * denom, ac, vc * denom);
}

/** Squared distance from p to the axis-aligned box {min: [3], max: [3]} (0 inside). */
export function boxDistance2(p, box) {
  let d = 0;
  for (let k = 0; k < 3; k++) {
    const e = Math.max(box.min[k] - p[k], 0, p[k] - box.max[k]);
    d += e * e;
  }
  return d;
}

/** The nearest point of a triangle mesh to p: {distance (mm), point [x, y, z], triangle}, or
 *  null without triangles. Triangles whose bounding box is farther than the best so far are
 *  skipped (same result, fewer exact tests). */
export function nearestOnMesh(p, positions, indices, limit = Infinity) {
  let best = { distance: limit, point: null, triangle: -1 };
  let best2 = limit * limit;
  const v = (i) => [positions[3 * i], positions[3 * i + 1], positions[3 * i + 2]];
  for (let t = 0; t < indices.length; t += 3) {
    const i0 = 3 * indices[t]; const i1 = 3 * indices[t + 1]; const i2 = 3 * indices[t + 2];
    let d2 = 0;
    for (let k = 0; k < 3; k++) {
      const lo = Math.min(positions[i0 + k], positions[i1 + k], positions[i2 + k]);
      const hi = Math.max(positions[i0 + k], positions[i1 + k], positions[i2 + k]);
      const e = Math.max(lo - p[k], 0, p[k] - hi);
      d2 += e * e;
    }
    if (d2 >= best2) continue;
    const q = closestOnTriangle(p, v(indices[t]), v(indices[t + 1]), v(indices[t + 2]));
    const dq = (q[0] - p[0]) ** 2 + (q[1] - p[1]) ** 2 + (q[2] - p[2]) ** 2;
    if (dq < best2) {
      best2 = dq;
      best = { distance: Math.sqrt(dq), point: q, triangle: t / 3 };
    }
  }
  return best.point ? best : null;
}

/** The structure nearest to p among `meshes` ([{name, positions, indices, box}]), nearest box
 *  first: {name, distance (mm), point}, or null when there is none. */
export function nearestStructure(p, meshes) {
  const order = meshes.map((m) => ({ m, d2: boxDistance2(p, m.box) })).sort((x, y) => x.d2 - y.d2);
  let best = null;
  for (const { m, d2 } of order) {
    if (best && d2 >= best.distance * best.distance) break;
    const hit = nearestOnMesh(p, m.positions, m.indices, best ? best.distance : Infinity);
    if (hit && (!best || hit.distance < best.distance)) best = { name: m.name, distance: hit.distance, point: hit.point };
  }
  return best;
}
