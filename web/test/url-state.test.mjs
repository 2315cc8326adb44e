import assert from 'node:assert/strict';
import { test } from 'node:test';
import { emptyState, formatState, parseState } from '../src/url-state.js';

const FULL = 'hide=colon,lung%20left%2C%20upper&opacity=liver:0.35,stomach:0&clip=axial:0.425:flip:outline'
  + '&view=left&camera=-12.5,130,156.8;0.6,0,0.8;0,1,0;2.5&measure=1.5,-2,3;4,5.25,-6';

test('every key is read', () => {
  const s = parseState(`#${FULL}`);
  assert.deepEqual(s.hide, ['colon', 'lung left, upper']);
  assert.deepEqual(s.opacity, { liver: 0.35, stomach: 0 });
  assert.deepEqual(s.clip, { plane: 'axial', fraction: 0.425, flip: true, outline: true });
  assert.deepEqual(parseState('clip=coronal:0.5:outline').clip, { plane: 'coronal', fraction: 0.5, flip: false, outline: true });
  assert.equal(s.view, 'left');
  assert.deepEqual(s.camera, { target: [-12.5, 130, 156.8], dir: [0.6, 0, 0.8], up: [0, 1, 0], zoom: 2.5 });
  assert.deepEqual(s.measure, [[1.5, -2, 3], [4, 5.25, -6]]);
});

test('a canonical fragment round-trips as text, a state as data', () => {
  assert.equal(formatState(parseState(FULL)), FULL);
  const s = parseState(FULL);
  assert.deepEqual(parseState(formatState(s)), s);
  assert.equal(formatState(emptyState()), '');
  assert.deepEqual(parseState(''), emptyState());
});

test('names sorted and numbers rounded: one text per state', () => {
  const s = emptyState();
  s.hide = ['b', 'a'];
  s.opacity = { z: 0.123456, a: 1 / 3 };
  s.clip = { plane: 'coronal', fraction: 0.5, flip: false };
  s.measure = [[1 / 3, 2, 3]];
  assert.equal(formatState(s), 'hide=a,b&opacity=a:0.33,z:0.12&clip=coronal:0.5&measure=0.333,2,3');
});

test('bad values name their key', () => {
  for (const [frag, key] of [['clip=axial:1.5', 'clip'], ['clip=oblique:0.5', 'clip'], ['clip=axial:0.5:flop', 'clip'],
    ['clip=axial:0.5:outline:flip', 'clip'], ['clip=axial:0.5:flip:flip', 'clip'],
    ['opacity=liver:2', 'opacity'], ['opacity=liver', 'opacity'], ['view=front', 'view'],
    ['camera=1,2,3;0,0,1;0,1,0', 'camera'], ['camera=1,2;0,0,1;0,1,0;1', 'camera'], ['camera=1,2,3;0,0,1;0,1,0;0', 'camera'],
    ['measure=1,2', 'measure'], ['measure=1,2,3;4,5,6;7,8,9', 'measure'], ['zoom=2', 'zoom']]) {
    assert.throws(() => parseState(frag), new RegExp(`^Error: view "${key}"`), frag);
  }
});
