// The page's model data: each level of detail is one script (data/lodK.js) that hands the viewer
// a Z85 text (ZeroMQ RFC 32); decoded, inflated (zlib, by fflate as three.js bundles it:
// synchronous, so a level is drawn in the task its script runs in, before the page's load event)
// and cut into meshoptimizer-encoded buffers (Kapoulkine, meshoptimizer: vertex and index
// codecs) as scene.js's records say.
//
// A record per geometry and level: {v: vertices, t: triangles, p: [offset, bytes] of the
// positions (uint16 x, y, z, 0 per vertex, quantised), i: [offset, bytes] of the triangle
// indices, c: [offset, bytes] of the sRGB colours (uint8 r, g, b, 255 per vertex) or absent}.

import { unzlibSync } from 'three/addons/libs/fflate.module.js';

const Z85 = '0123456789abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ.-:+=^!/*?&<>()[]{}@%$#';
const Z85_DIGIT = new Int8Array(128).fill(-1);
for (let d = 0; d < 85; d++) Z85_DIGIT[Z85.charCodeAt(d)] = d;

/** Z85 text (5 characters per 4 bytes, most significant digit first) → its first `length`
 *  bytes (Uint8Array). Throws on a character outside Z85's alphabet or a wrong length. */
export function z85ToBytes(text, length) {
  const words = text.length / 5;
  if (!Number.isInteger(words) || length > 4 * words || length <= 4 * words - 4) {
    throw new Error(`level data: ${text.length} characters of Z85 cannot carry ${length} bytes`);
  }
  const out = new Uint8Array(4 * words);
  for (let w = 0, i = 0; w < words; w++) {
    let v = 0;
    for (let j = 0; j < 5; j++, i++) {
      const c = text.charCodeAt(i);
      const d = c < 128 ? Z85_DIGIT[c] : -1;
      if (d < 0) throw new Error(`level data: character ${i} is not Z85`);
      v = v * 85 + d;
    }
    out[4 * w] = v >>> 24;
    out[4 * w + 1] = (v >>> 16) & 255;
    out[4 * w + 2] = (v >>> 8) & 255;
    out[4 * w + 3] = v & 255;
  }
  return out.subarray(0, length);
}

/** zlib-compressed bytes (RFC 1950/1951) → bytes. */
export function inflate(bytes) {
  return unzlibSync(bytes);
}

/** Quantised positions (uint16, 4 per vertex) → Float32Array (3 per vertex) in mm:
 *  origin + q * step. */
export function dequantize(q, count, origin, step) {
  const out = new Float32Array(count * 3);
  for (let k = 0; k < count; k++) {
    out[3 * k] = origin[0] + q[4 * k] * step;
    out[3 * k + 1] = origin[1] + q[4 * k + 1] * step;
    out[3 * k + 2] = origin[2] + q[4 * k + 2] * step;
  }
  return out;
}

const SRGB_TO_LINEAR = new Float32Array(256).map((_, i) => {
  const c = i / 255;
  return c <= 0.04045 ? c / 12.92 : Math.pow((c + 0.055) / 1.055, 2.4);
});

/** sRGB bytes (4 per vertex) → linear Float32Array (3 per vertex), as WebGL shades in linear light
 *  (IEC 61966-2-1). */
export function srgbToLinear(rgba, count) {
  const out = new Float32Array(count * 3);
  for (let k = 0; k < count; k++) {
    for (let j = 0; j < 3; j++) out[3 * k + j] = SRGB_TO_LINEAR[rgba[4 * k + j]];
  }
  return out;
}

/** Unit vertex normals (Float32Array, 3 per vertex) of a triangle mesh (positions: 3 per vertex,
 *  indices: 3 per triangle): each vertex's sum of its triangles' cross products, so larger
 *  triangles weigh more (as three.js's computeVertexNormals); a vertex of no area gets (0, 0, 0). */
export function vertexNormals(positions, indices) {
  const n = new Float32Array(positions.length);
  const p = positions;
  for (let t = 0; t < indices.length; t += 3) {
    const a = 3 * indices[t], b = 3 * indices[t + 1], c = 3 * indices[t + 2];
    const ux = p[b] - p[a], uy = p[b + 1] - p[a + 1], uz = p[b + 2] - p[a + 2];
    const vx = p[c] - p[a], vy = p[c + 1] - p[a + 1], vz = p[c + 2] - p[a + 2];
    const nx = uy * vz - uz * vy, ny = uz * vx - ux * vz, nz = ux * vy - uy * vx;
    n[a] += nx; n[a + 1] += ny; n[a + 2] += nz;
    n[b] += nx; n[b + 1] += ny; n[b + 2] += nz;
    n[c] += nx; n[c + 1] += ny; n[c + 2] += nz;
  }
  for (let k = 0; k < n.length; k += 3) {
    const length = Math.sqrt(n[k] * n[k] + n[k + 1] * n[k + 1] + n[k + 2] * n[k + 2]) || 1;
    n[k] /= length; n[k + 1] /= length; n[k + 2] /= length;
  }
  return n;
}

/** The box {min: [x, y, z], max: [x, y, z]} of positions (3 per vertex, at least one vertex) and
 *  the radius of the sphere about the box's centre that holds them all (as three.js's bounds). */
export function bounds(positions) {
  const min = [Infinity, Infinity, Infinity], max = [-Infinity, -Infinity, -Infinity];
  for (let k = 0; k < positions.length; k += 3) {
    for (let j = 0; j < 3; j++) {
      const x = positions[k + j];
      if (x < min[j]) min[j] = x;
      if (x > max[j]) max[j] = x;
    }
  }
  const centre = min.map((lo, j) => (lo + max[j]) / 2);
  let r2 = 0;
  for (let k = 0; k < positions.length; k += 3) {
    const dx = positions[k] - centre[0], dy = positions[k + 1] - centre[1], dz = positions[k + 2] - centre[2];
    r2 = Math.max(r2, dx * dx + dy * dy + dz * dz);
  }
  return { min, max, radius: Math.sqrt(r2) };
}

/** One geometry of one level: {positions (Float32Array, mm), indices (Uint32Array), normals
 *  (Float32Array, unit), bounds (bounds()), colors (Float32Array linear RGB) or null}. `decoder` is meshoptimizer's MeshoptDecoder
 *  (ready), `blob` the level's inflated bytes, `quant` = {origin: [x, y, z], step}. */
export function decodeGeometry(blob, rec, decoder, quant) {
  const part = ([offset, bytes]) => blob.subarray(offset, offset + bytes);
  const q = new Uint8Array(rec.v * 8);
  decoder.decodeVertexBuffer(q, rec.v, 8, part(rec.p));
  const idx = new Uint8Array(rec.t * 12);
  decoder.decodeIndexBuffer(idx, rec.t * 3, 4, part(rec.i));
  let colors = null;
  if (rec.c) {
    const c = new Uint8Array(rec.v * 4);
    decoder.decodeVertexBuffer(c, rec.v, 4, part(rec.c));
    colors = srgbToLinear(c, rec.v);
  }
  const positions = dequantize(new Uint16Array(q.buffer), rec.v, quant.origin, quant.step);
  const indices = new Uint32Array(idx.buffer);
  return { positions, indices, normals: vertexNormals(positions, indices), bounds: bounds(positions), colors };
}

/** Every geometry stored in level `level` of the scene, decoded from the level's inflated bytes
 *  `blob`: Map id → decodeGeometry(). `decoder` must be ready (await decoder.ready once). */
export function decodeLevel(scene, level, blob, decoder) {
  const out = new Map();
  for (const [id, rec] of Object.entries(scene.levels[level].geometries)) {
    out.set(id, decodeGeometry(blob, rec, decoder, scene.quantization));
  }
  return out;
}
