import assert from 'node:assert/strict';
import { test } from 'node:test';
import { BoxGeometry, IcosahedronGeometry } from 'three';
import { mergeVertices } from 'three/addons/utils/BufferGeometryUtils.js';
import { planeSection } from '../src/section.js';

/** Total length (mm) of the segments. */
function length(ends) {
  let s = 0;
  for (let k = 0; k < ends.length; k += 6) {
    s += Math.hypot(ends[k + 3] - ends[k], ends[k + 4] - ends[k + 1], ends[k + 5] - ends[k + 2]);
  }
  return s;
}

const indexed = (g) => {
  const m = mergeVertices(g.deleteAttribute('normal').deleteAttribute('uv'));
  return [m.getAttribute('position').array, m.index.array];
};

test('a box cut across: its square outline, on the plane', () => {
  const [p, i] = indexed(new BoxGeometry(20, 30, 40, 3, 3, 3));
  for (const [axis, at, perimeter] of [[0, 1.5, 140], [1, -7, 120], [2, 12.25, 100]]) {
    const ends = planeSection(p, i, axis, at);
    assert.ok(Math.abs(length(ends) - perimeter) < 1e-9, `${axis}: ${length(ends)}`);
    for (let k = axis; k < ends.length; k += 3) assert.equal(ends[k], at);
  }
  assert.equal(planeSection(p, i, 2, 25).length, 0);  // beyond the box: nothing
});

test('a sphere through its centre: a circle of its radius, each crossing edge once', () => {
  const [p, i] = indexed(new IcosahedronGeometry(50, 24));
  const ends = planeSection(p, i, 1, 0.3);
  const r = Math.sqrt(50 * 50 - 0.3 * 0.3);
  assert.ok(Math.abs(length(ends) / (2 * Math.PI * r) - 1) < 2e-3);
  for (let k = 0; k < ends.length; k += 3) assert.ok(Math.abs(Math.hypot(ends[k], ends[k + 2]) - r) < 0.2);
  const points = new Set();  // a closed outline: every end shared by two segments
  for (let k = 0; k < ends.length; k += 3) {
    const key = [ends[k], ends[k + 1], ends[k + 2]].map((x) => x.toFixed(4)).join();
    points.has(key) ? points.delete(key) : points.add(key);
  }
  assert.equal(points.size, 0);
});
