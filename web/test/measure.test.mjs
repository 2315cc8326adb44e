import assert from 'node:assert/strict';
import { test } from 'node:test';
import { closestOnTriangle, distance, nearestOnMesh, nearestStructure } from '../src/measure.js';

const A = [0, 0, 0]; const B = [4, 0, 0]; const C = [0, 3, 0];
const close = (a, b) => a.every((x, k) => Math.abs(x - b[k]) < 1e-12);

test('distance between points (mm)', () => {
  assert.equal(distance([1, 2, 3], [4, 6, 3]), 5);
});

test('closest point on a triangle in each Voronoi region', () => {
  assert.ok(close(closestOnTriangle([1, 1, 5], A, B, C), [1, 1, 0]));    // face
  assert.ok(close(closestOnTriangle([-1, -1, 2], A, B, C), A));           // vertex A
  assert.ok(close(closestOnTriangle([6, -1, 0], A, B, C), B));            // vertex B
  assert.ok(close(closestOnTriangle([-1, 5, 0], A, B, C), C));            // vertex C
  assert.ok(close(closestOnTriangle([2, -3, 1], A, B, C), [2, 0, 0]));    // edge AB
  assert.ok(close(closestOnTriangle([-2, 1, 0], A, B, C), [0, 1, 0]));    // edge AC
  const q = closestOnTriangle([4, 3, 0], A, B, C);                        // edge BC: (4,3) − t·n
  assert.ok(Math.abs(3 * q[0] + 4 * q[1] - 12) < 1e-12 && close(q, [2.56, 1.08, 0]));
});

function cube(c, h) {  // closed axis-aligned cube of half size h at c: 8 vertices, 12 triangles
  const p = [];
  for (let k = 0; k < 8; k++) p.push(c[0] + (k & 1 ? h : -h), c[1] + (k & 2 ? h : -h), c[2] + (k & 4 ? h : -h));
  const t = [0, 2, 1, 1, 2, 3, 4, 5, 6, 5, 7, 6, 0, 1, 4, 1, 5, 4, 2, 6, 3, 3, 6, 7, 0, 4, 2, 2, 4, 6, 1, 3, 5, 3, 7, 5];
  const box = { min: c.map((x) => x - h), max: c.map((x) => x + h) };
  return { positions: new Float32Array(p), indices: new Uint32Array(t), box };
}

test('nearest point of a mesh and nearest structure, exact', () => {
  const a = cube([0, 0, 0], 1);
  const hit = nearestOnMesh([3, 0.5, 0.25], a.positions, a.indices);
  assert.equal(hit.distance, 2);
  assert.ok(close(hit.point, [1, 0.5, 0.25]));
  const b = { name: 'b', ...cube([10, 0, 0], 1) };
  const c = { name: 'c', ...cube([0, 7, 0], 2) };
  const corner = nearestStructure([1, 4, 0], [b, c]);               // c's face y = 5: 1 mm
  assert.equal(corner.name, 'c');
  assert.equal(corner.distance, 1);
  const far = nearestStructure([12, 2, 2], [b, c]);                   // b's corner (11, 1, 1)
  assert.equal(far.name, 'b');
  assert.ok(Math.abs(far.distance - Math.sqrt(3)) < 1e-12);
  assert.equal(nearestStructure([0, 0, 0], []), null);
});
