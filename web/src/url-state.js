// The page's view as text in the URL's fragment, so a view can be bookmarked and shared:
//
//   #hide=NAME,…&opacity=NAME:A,…&clip=axial|coronal|sagittal:F[:flip][:outline]
//    &view=anterior|posterior|left|right|superior|inferior&camera=TX,TY,TZ;DX,DY,DZ;UX,UY,UZ;ZOOM
//    &measure=X,Y,Z[;X,Y,Z]
//
// Names are the structure names of the page, URL-encoded. F is the plane's place along the axis,
// 0..1 of the model's extent; `flip` keeps the other side, `outline` outlines each structure on
// the cut. The camera is its target T (mm), the
// direction D from the target to the eye, the screen's up U and the zoom (orthographic view).
// Measured points are in mm, the page's display frame (+x patient left, +y superior, +z
// anterior). Pure functions: tested with node's test runner.

/** Clipping axes by anatomical plane: the display frame's axis normal to the plane. */
export const CLIP_AXES = { sagittal: 'x', axial: 'y', coronal: 'z' };

/** Named views: direction from the target to the eye and the screen's up (display frame). */
export const VIEWS = {
  anterior: { dir: [0, 0, 1], up: [0, 1, 0] },
  posterior: { dir: [0, 0, -1], up: [0, 1, 0] },
  left: { dir: [1, 0, 0], up: [0, 1, 0] },
  right: { dir: [-1, 0, 0], up: [0, 1, 0] },
  superior: { dir: [0, 1, 0], up: [0, 0, 1] },
  inferior: { dir: [0, -1, 0], up: [0, 0, 1] },
};

/** The state of a page with nothing set (every structure at its default). */
export function emptyState() {
  return { hide: [], opacity: {}, clip: null, view: null, camera: null, measure: [] };
}

const num = (x, digits) => String(+x.toFixed(digits));  // shortest text of a rounded number
const vec = (v, digits) => v.map((x) => num(x, digits)).join(',');

function numbers(text, count) {
  const v = text.split(',').map(Number);
  if (v.length !== count || v.some((x) => !Number.isFinite(x)) || text.trim() === '') {
    throw new Error(`expected ${count} numbers, got "${text}"`);
  }
  return v;
}

/** The state as a fragment (without '#'); keys in a fixed order, names sorted, default values
 *  left out: one text per state. */
export function formatState(state) {
  const parts = [];
  const enc = encodeURIComponent;
  if (state.hide.length) parts.push(`hide=${[...state.hide].sort().map(enc).join(',')}`);
  const op = Object.entries(state.opacity).sort(([a], [b]) => (a < b ? -1 : a > b ? 1 : 0));
  if (op.length) parts.push(`opacity=${op.map(([n, a]) => `${enc(n)}:${num(a, 2)}`).join(',')}`);
  if (state.clip) {
    const c = state.clip;
    parts.push(`clip=${c.plane}:${num(c.fraction, 3)}${c.flip ? ':flip' : ''}${c.outline ? ':outline' : ''}`);
  }
  if (state.view) parts.push(`view=${state.view}`);
  if (state.camera) {
    const c = state.camera;
    parts.push(`camera=${vec(c.target, 2)};${vec(c.dir, 4)};${vec(c.up, 4)};${num(c.zoom, 4)}`);
  }
  if (state.measure.length) parts.push(`measure=${state.measure.map((p) => vec(p, 3)).join(';')}`);
  return parts.join('&');
}

/** A fragment ('#…' or without '#') as a state; throws Error naming the first bad key. Unknown
 *  keys are errors too (a mistyped key would otherwise be silently ignored). */
export function parseState(fragment) {
  const state = emptyState();
  const text = fragment.replace(/^#/, '');
  if (!text) return state;
  for (const part of text.split('&')) {
    if (!part) continue;
    const eq = part.indexOf('=');
    const key = eq < 0 ? part : part.slice(0, eq);
    const value = eq < 0 ? '' : part.slice(eq + 1);
    try {
      readKey(state, key, value);
    } catch (err) {
      throw new Error(`view "${key}": ${err.message}`);
    }
  }
  return state;
}

const dec = decodeURIComponent;

function readKey(state, key, value) {
  if (key === 'hide') {
    state.hide = value.split(',').filter(Boolean).map(dec);
  } else if (key === 'opacity') {
    for (const item of value.split(',').filter(Boolean)) {
      const k = item.lastIndexOf(':');
      const a = Number(item.slice(k + 1));
      if (k < 1 || !(a >= 0 && a <= 1) || item.slice(k + 1) === '') throw new Error(`NAME:A with A in 0..1, got "${item}"`);
      state.opacity[dec(item.slice(0, k))] = a;
    }
  } else if (key === 'clip') {
    const [plane, f, ...flags] = value.split(':');
    const fraction = Number(f);
    const known = ['flip', 'outline'].filter((x) => flags.includes(x));
    if (!(plane in CLIP_AXES) || f === undefined || f === '' || !(fraction >= 0 && fraction <= 1)
        || known.join(':') !== flags.join(':')) {
      throw new Error(`axial|coronal|sagittal:F with F in 0..1 (then optional :flip, :outline), got "${value}"`);
    }
    state.clip = { plane, fraction, flip: flags.includes('flip'), outline: flags.includes('outline') };
  } else if (key === 'view') {
    if (!(value in VIEWS)) throw new Error(`one of ${Object.keys(VIEWS).join(', ')}, got "${value}"`);
    state.view = value;
  } else if (key === 'camera') {
    const p = value.split(';');
    if (p.length !== 4) throw new Error(`TX,TY,TZ;DX,DY,DZ;UX,UY,UZ;ZOOM, got "${value}"`);
    const zoom = Number(p[3]);
    if (!(zoom > 0)) throw new Error(`zoom must be > 0, got "${p[3]}"`);
    state.camera = { target: numbers(p[0], 3), dir: numbers(p[1], 3), up: numbers(p[2], 3), zoom };
  } else if (key === 'measure') {
    state.measure = value.split(';').filter(Boolean).map((p) => numbers(p, 3));
    if (state.measure.length > 2) throw new Error('at most two points');
  } else {
    throw new Error('unknown key (hide, opacity, clip, view, camera, measure)');
  }
}
