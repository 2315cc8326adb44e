import assert from 'node:assert/strict';
import { test } from 'node:test';
import { deflateSync } from 'node:zlib';
import { MeshoptDecoder } from 'meshoptimizer/decoder';
import { MeshoptEncoder } from 'meshoptimizer/encoder';
import { BufferAttribute, BufferGeometry } from 'three';
import { bounds, decodeLevel, dequantize, inflate, srgbToLinear, vertexNormals, z85ToBytes } from '../src/data.js';

/** bytes → Z85 (ZeroMQ RFC 32), zero-padded to whole words, for the tests. */
function z85(bytes) {
  const alphabet = '0123456789abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ.-:+=^!/*?&<>()[]{}@%$#';
  const padded = new Uint8Array(Math.ceil(bytes.length / 4) * 4);
  padded.set(bytes);
  const view = new DataView(padded.buffer);
  let out = '';
  for (let o = 0; o < padded.length; o += 4) {
    let v = view.getUint32(o);
    const digits = [];
    for (let j = 0; j < 5; j++) { digits.unshift(alphabet[v % 85]); v = Math.floor(v / 85); }
    out += digits.join('');
  }
  return out;
}

test('Z85: the RFC\'s example, any length back, bad text refused', () => {
  assert.deepEqual([...z85ToBytes('HelloWorld', 8)], [0x86, 0x4F, 0xD2, 0x6F, 0xB5, 0x59, 0xF7, 0x5B]);
  for (const n of [0, 1, 2, 3, 4, 5, 4999]) {
    const bytes = new Uint8Array(n).map((_, i) => (i * 7919 + 255) % 256);
    assert.deepEqual(z85ToBytes(z85(bytes), n), bytes);
  }
  assert.deepEqual([...z85ToBytes('%nSc0', 4)], [255, 255, 255, 255]);
  assert.throws(() => z85ToBytes('Hello"orld', 8), /character 5 is not Z85/);
  assert.throws(() => z85ToBytes('HelloWorl', 8), /cannot carry 8 bytes/);
  assert.throws(() => z85ToBytes('HelloWorld', 4), /cannot carry 4 bytes/);
});

test('inflate gives the bytes back', () => {
  const bytes = new Uint8Array(5000).map((_, i) => (i * 7919) % 251);
  assert.deepEqual(inflate(deflateSync(bytes, { level: 9 })), bytes);
});

test('vertex normals and bounds as three.js computes them', () => {
  // a bumpy strip: triangles of different areas and orientations
  const positions = new Float32Array(3 * 40);
  for (let v = 0; v < 40; v++) positions.set([v % 20, v < 20 ? 0 : 7, 3 * Math.sin(v)], 3 * v);
  const indices = [];
  for (let k = 0; k < 19; k++) indices.push(k, k + 1, k + 20, k + 1, k + 21, k + 20);
  const g = new BufferGeometry();
  g.setAttribute('position', new BufferAttribute(positions, 3));
  g.setIndex(indices);
  g.computeVertexNormals();
  g.computeBoundingBox();
  g.computeBoundingSphere();
  const n = vertexNormals(positions, new Uint32Array(indices));
  const ref = g.getAttribute('normal').array;
  assert.ok(n.every((x, i) => Math.abs(x - ref[i]) < 1e-6));
  const b = bounds(positions);
  assert.deepEqual(b.min, g.boundingBox.min.toArray());
  assert.deepEqual(b.max, g.boundingBox.max.toArray());
  assert.ok(Math.abs(b.radius - g.boundingSphere.radius) < 1e-9);
});

test('dequantize: origin + q × step per axis', () => {
  const q = new Uint16Array([0, 0, 0, 0, 16, 32, 65535, 0]);
  assert.deepEqual([...dequantize(q, 2, [10, -5, 0.5], 0.0625)], [10, -5, 0.5, 11, -3, 4096.4375]);
});

test('sRGB bytes to linear light', () => {
  const lin = srgbToLinear(new Uint8Array([0, 255, 188, 255]), 1);
  assert.equal(lin[0], 0);
  assert.equal(lin[1], 1);
  assert.ok(Math.abs(lin[2] - 0.5029) < 1e-3);  // sRGB 188 ≈ linear 0.5
});

test('a level encoded with meshoptimizer decodes to the same mesh', async () => {
  await MeshoptEncoder.ready;
  await MeshoptDecoder.ready;
  // two triangles of a square, quantised on a 0.5 mm grid, red/green vertex colours
  const pos = new Uint16Array([0, 0, 0, 0, 20, 0, 0, 0, 20, 20, 0, 0, 0, 20, 0, 0]);
  const idx = new Uint32Array([0, 1, 2, 0, 2, 3]);
  const col = new Uint8Array([255, 0, 0, 255, 0, 255, 0, 255, 255, 0, 0, 255, 0, 255, 0, 255]);
  const parts = [MeshoptEncoder.encodeVertexBuffer(new Uint8Array(pos.buffer), 4, 8),
    MeshoptEncoder.encodeIndexBuffer(new Uint8Array(idx.buffer), 6, 4),
    MeshoptEncoder.encodeVertexBuffer(col, 4, 4)];
  const offsets = [0, parts[0].length, parts[0].length + parts[1].length];
  const blob = new Uint8Array(offsets[2] + parts[2].length);
  parts.forEach((p, k) => blob.set(p, offsets[k]));
  const rec = { v: 4, t: 2, p: [offsets[0], parts[0].length], i: [offsets[1], parts[1].length],
    c: [offsets[2], parts[2].length] };
  const scene = { quantization: { origin: [100, 0, -1], step: 0.5 },
    levels: [{ geometries: { abc: rec, noColour: { ...rec, c: undefined } } }] };
  const deflated = deflateSync(blob);
  const out = decodeLevel(scene, 0, inflate(z85ToBytes(z85(deflated), deflated.length)), MeshoptDecoder);
  const g = out.get('abc');
  assert.deepEqual([...g.positions], [100, 0, -1, 110, 0, -1, 110, 10, -1, 100, 10, -1]);
  assert.deepEqual([...g.indices], [...idx]);
  assert.deepEqual([...g.colors.slice(0, 6)], [1, 0, 0, 0, 1, 0]);
  assert.equal(out.get('noColour').colors, null);
});
