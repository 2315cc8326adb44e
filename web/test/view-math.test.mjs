import assert from 'node:assert/strict';
import { test } from 'node:test';
import { choosePick, clipPlane, drawOrder, orientedAlpha, scaleBar, volumeText } from '../src/view-math.js';

test('scale bar: a round length near the wanted width', () => {
  assert.deepEqual(scaleBar(2, 100), { mm: 50, px: 100, label: '50 mm' });
  assert.equal(scaleBar(2.5, 100).mm, 20);           // 40 mm wanted → 20
  assert.equal(scaleBar(0.3, 100).mm, 200);          // 333 mm wanted → 200
  assert.equal(scaleBar(120, 100).label, '0.5 mm');  // 0.83 mm wanted → 0.5
  for (const ppm of [0.01, 0.7, 3, 17, 999]) {
    const b = scaleBar(ppm, 100);
    assert.ok(b.px > 40 && b.px <= 100, `${ppm}: ${b.px}`);
    assert.ok([1, 2, 5].includes(Math.round(b.mm / 10 ** Math.floor(Math.log10(b.mm) + 1e-9))));
  }
  assert.equal(scaleBar(0).px, 0);
});

test('draw order: nested shells outer back, inner back, inner front, outer front', () => {
  const order = drawOrder([{ depth: 10, radius: 5 }, { depth: 10, radius: 1 }]);
  assert.deepEqual(order, [{ index: 0, side: 'back' }, { index: 1, side: 'back' },
    { index: 1, side: 'front' }, { index: 0, side: 'front' }]);
});

test('draw order: separate objects back to front, each back then front', () => {
  const order = drawOrder([{ depth: 5, radius: 1 }, { depth: 20, radius: 1 }, { depth: 12, radius: 1 }]);
  assert.deepEqual(order.map((o) => `${o.index}${o.side[0]}`), ['1b', '1f', '2b', '2f', '0b', '0f']);
});

test('oriented transparency: face-on keeps the opacity, silhouettes opaque', () => {
  assert.equal(orientedAlpha(0.3, 1), 0.3);
  assert.equal(orientedAlpha(0.3, -1), 0.3);
  assert.equal(orientedAlpha(0.3, 0), 1);
  const a = [1, 0.8, 0.5, 0.2].map((c) => orientedAlpha(0.2, c));
  assert.ok(a.every((x, i) => i === 0 || x > a[i - 1]));  // more opaque toward the rim
  assert.equal(orientedAlpha(1, 0.4), 1);
});

test('picking: the nearest mostly opaque hit, through see-through skins', () => {
  const hits = [{ id: 'skin', opacity: 0.2 }, { id: 'liver', opacity: 1 }, { id: 'spine', opacity: 1 }];
  assert.equal(choosePick(hits).id, 'liver');
  assert.equal(choosePick([{ id: 'skin', opacity: 0.2 }, { id: 'lung', opacity: 0.3 }]).id, 'skin');
  assert.equal(choosePick([]), null);
});

test('volumes in mL above 1 mL', () => {
  assert.equal(volumeText(1523400), '1523 mL');
  assert.equal(volumeText(15234), '15.2 mL');
  assert.equal(volumeText(-15234), '15.2 mL');
  assert.equal(volumeText(512.4), '512 mm³');
  assert.equal(volumeText(undefined), '');
});

test('clipping plane keeps one side of an axis position', () => {
  const box = { min: [0, -100, 10], max: [50, 100, 30] };
  const keep = (p, pl) => pl.normal.reduce((s, n, k) => s + n * p[k], 0) + pl.constant >= 0;
  const pl = clipPlane('y', 0.25, box);   // y = -50
  assert.ok(keep([0, -60, 0], pl) && !keep([0, -40, 0], pl));
  const fl = clipPlane('y', 0.25, box, true);
  assert.ok(!keep([0, -60, 0], fl) && keep([0, -40, 0], fl));
  const z = clipPlane('z', 1, box);
  assert.ok(keep([0, 0, 29.9], z) && !keep([0, 0, 30.1], z));
});
