// The page's model data: each level of detail is one script (data/lodK.js) that hands the viewer
// a base64 text; decoded, inflated (zlib) and cut into meshoptimizer-encoded buffers
// (Kapoulkine, meshoptimizer: vertex and index codecs) as scene.js's records say. Inflating is
// the browser's own (asynchronous) or fflate's (as three.js bundles it; synchronous, so the
// finest level can be drawn in the task its script runs in, before the page's load event).
//
// A record per geometry and level: {v: vertices, t: triangles, p: [offset, bytes] of the
// positions (uint16 x, y, z, 0 per vertex, quantised), i: [offset, bytes] of the triangle
// indices, c: [offset, bytes] of the sRGB colours (uint8 r, g, b, 255 per vertex) or absent}.

import { unzlibSync } from 'three/addons/libs/fflate.module.js';

/** base64 text → bytes. */
export function base64ToBytes(text) {
  const bin = atob(text);
  const out = new Uint8Array(bin.length);
  for (let i = 0; i < bin.length; i++) out[i] = bin.charCodeAt(i);
  return out;
}

/** zlib-compressed bytes (RFC 1950/1951) → bytes, by the browser's DecompressionStream. */
export async function inflate(bytes) {
  const stream = new Blob([bytes]).stream().pipeThrough(new DecompressionStream('deflate'));
  return new Uint8Array(await new Response(stream).arrayBuffer());
}

/** The same, now (fflate). */
export function inflateNow(bytes) {
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

/** One geometry of one level: {positions (Float32Array, mm), indices (Uint32Array),
 *  colors (Float32Array linear RGB) or null}. `decoder` is meshoptimizer's MeshoptDecoder
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
  return {
    positions: dequantize(new Uint16Array(q.buffer), rec.v, quant.origin, quant.step),
    indices: new Uint32Array(idx.buffer),
    colors,
  };
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
