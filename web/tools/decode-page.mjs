// Decode a page written by Anatomesh the way the browser does (src/data.js + meshoptimizer's
// decoder), without a browser: prints, per level and geometry, vertex and triangle counts, the
// bounding box and the surface area (mm²) — the tests compare them with the Python meshes.
//   node tools/decode-page.mjs PAGE_DIR
import { readFileSync } from 'node:fs';
import { join } from 'node:path';
import { MeshoptDecoder } from 'meshoptimizer/decoder';
import { decodeLevel, inflate, z85ToBytes } from '../src/data.js';

const dir = process.argv[2];
const sceneText = readFileSync(join(dir, 'scene.js'), 'utf8');
const scene = JSON.parse(sceneText.slice(sceneText.indexOf('{'), sceneText.lastIndexOf('}') + 1));

function area(p, idx) {
  let s = 0;
  for (let k = 0; k < idx.length; k += 3) {
    const [a, b, c] = [idx[k], idx[k + 1], idx[k + 2]].map((i) => [p[3 * i], p[3 * i + 1], p[3 * i + 2]]);
    const u = b.map((x, j) => x - a[j]);
    const v = c.map((x, j) => x - a[j]);
    const n = [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]];
    s += Math.hypot(...n) / 2;
  }
  return s;
}

await MeshoptDecoder.ready;
const out = [];
for (const [k, level] of scene.levels.entries()) {
  const js = readFileSync(join(dir, level.file), 'utf8');
  const m = /^anatomeshLevel\((\d+),"([^"]*)",(\d+)\);\s*$/.exec(js);
  if (!m || +m[1] !== k) throw new Error(`${level.file}: not the script of level ${k}`);
  const decoded = decodeLevel(scene, k, inflate(z85ToBytes(m[2], +m[3])), MeshoptDecoder);
  const geometries = {};
  for (const [id, g] of decoded) {
    const lo = [Infinity, Infinity, Infinity];
    const hi = [-Infinity, -Infinity, -Infinity];
    for (let i = 0; i < g.positions.length; i++) {
      lo[i % 3] = Math.min(lo[i % 3], g.positions[i]);
      hi[i % 3] = Math.max(hi[i % 3], g.positions[i]);
    }
    geometries[id] = { v: g.positions.length / 3, t: g.indices.length / 3, min: lo, max: hi,
      area: area(g.positions, g.indices), colors: g.colors ? g.colors.length / 3 : 0 };
  }
  out.push(geometries);
}
console.log(JSON.stringify(out));
