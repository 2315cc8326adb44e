import assert from 'node:assert/strict';
import { test } from 'node:test';
import { cssColor, groupBySystem } from '../src/tree.js';

test('structures grouped by system, groups in the given order, members by name', () => {
  const s = [{ name: 'spleen', system: 'organs' }, { name: 'aorta', system: 'vessels' },
    { name: 'liver', system: 'organs' }, { name: 'odd', system: 'zzz' }, { name: 'rib', system: 'bones' },
    { name: 'x' }];
  const g = groupBySystem(s, ['organs', 'vessels', 'bones', 'other']);
  assert.deepEqual(g.map((x) => x.system), ['organs', 'vessels', 'bones', 'other', 'zzz']);
  assert.deepEqual(g[0].members, [2, 0]);  // liver before spleen
  assert.deepEqual(g[3].members, [5]);     // no system: other
});

test('css colours from sRGB 0..1, clamped', () => {
  assert.equal(cssColor([1, 0.5, 0]), 'rgb(255, 128, 0)');
  assert.equal(cssColor([2, -1, 0.2, 0.5]), 'rgb(255, 0, 51)');
});
