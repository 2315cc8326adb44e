import assert from 'node:assert/strict';
import { test } from 'node:test';
import { deflateSync } from 'node:zlib';
import { MeshoptDecoder } from 'meshoptimizer/decoder';
import { MeshoptEncoder } from 'meshoptimizer/encoder';
import { base64ToBytes, decodeLevel, dequantize, inflate, inflateNow, srgbToLinear } from '../src/data.js';

test('base64 and both inflaters give the bytes back', async () => {
  const bytes = new Uint8Array(5000).map((_, i) => (i * 7919) % 251);
  assert.deepEqual(base64ToBytes(Buffer.from(bytes).toString('base64')), bytes);
  assert.deepEqual(await inflate(deflateSync(bytes, { level: 9 })), bytes);
  assert.deepEqual(inflateNow(deflateSync(bytes, { level: 9 })), bytes);
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
  const text = deflateSync(blob).toString('base64');
  const out = decodeLevel(scene, 0, await inflate(base64ToBytes(text)), MeshoptDecoder);
  const g = out.get('abc');
  assert.deepEqual([...g.positions], [100, 0, -1, 110, 0, -1, 110, 10, -1, 100, 10, -1]);
  assert.deepEqual([...g.indices], [...idx]);
  assert.deepEqual([...g.colors.slice(0, 6)], [1, 0, 0, 0, 1, 0]);
  assert.equal(out.get('noColour').colors, null);
});
