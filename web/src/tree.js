// The structure tree of the side panel: structures grouped by body system (the system of each
// name comes with the scene, from Anatomesh's label palette), each with visibility and opacity.

/** a before b (< 0), after (> 0) or equal (0), by their lower-case characters' codes. */
function byName(a, b) {
  const [x, y] = [a.toLowerCase(), b.toLowerCase()];
  return x < y ? -1 : Number(x > y);
}

/** Structures grouped by `system`, groups in `order` (unknown systems last, alphabetically),
 *  members by name: [{system, members: [index into structures]}]. */
export function groupBySystem(structures, order = []) {
  const groups = new Map();
  structures.forEach((s, i) => {
    const key = s.system || 'other';
    if (!groups.has(key)) groups.set(key, []);
    groups.get(key).push(i);
  });
  const rank = (k) => (order.includes(k) ? order.indexOf(k) : order.length);
  return [...groups.entries()]
    .sort(([a], [b]) => rank(a) - rank(b) || byName(a, b))
    .map(([system, members]) => ({
      system,
      members: members.sort((a, b) => byName(structures[a].name, structures[b].name)),
    }));
}

/** CSS colour of an sRGB triple in 0..1. */
export function cssColor(rgb) {
  const c = rgb.slice(0, 3).map((x) => Math.round(Math.min(1, Math.max(0, x)) * 255));
  return `rgb(${c[0]}, ${c[1]}, ${c[2]})`;
}

function el(doc, tag, props = {}, children = []) {
  const e = doc.createElement(tag);
  Object.assign(e, props);
  for (const c of children) e.append(c);
  return e;
}

/** Fill `container` with the tree. `state[i]` = {visible, opacity} is read for the initial
 *  values; `on.visible(i, bool)`, `on.opacity(i, 0..1)` and `on.hover(i | null)` report the
 *  user's changes. Returns {sync()} to refresh the inputs from `state`. */
export function buildTree(doc, container, structures, groups, state, on) {
  container.replaceChildren();
  const rows = [];
  for (const g of groups) {
    const all = el(doc, 'input', { type: 'checkbox', title: `show or hide all ${g.system}` });
    all.dataset.system = g.system;
    const head = el(doc, 'summary', {}, [all, ` ${g.system} (${g.members.length})`]);
    const body = el(doc, 'div', { className: 'members' });
    for (const i of g.members) {
      const s = structures[i];
      const box = el(doc, 'input', { type: 'checkbox', checked: state[i].visible });
      box.dataset.structure = s.name;
      const alpha = el(doc, 'input', { type: 'range', min: 0, max: 1, step: 0.05,
        value: state[i].opacity, title: 'opacity' });
      alpha.dataset.opacity = s.name;
      const swatch = el(doc, 'span', { className: 'swatch' });
      swatch.style.background = cssColor(s.color);
      const label = el(doc, 'label', { className: 'name', textContent: s.name, title: s.name });
      const row = el(doc, 'div', { className: 'row' }, [box, swatch, label, alpha]);
      box.addEventListener('change', () => { on.visible(i, box.checked); syncGroup(); });
      alpha.addEventListener('input', () => on.opacity(i, +alpha.value));
      row.addEventListener('mouseenter', () => on.hover(i));
      row.addEventListener('mouseleave', () => on.hover(null));
      rows.push({ i, box, alpha });
      body.append(row);
    }
    const syncGroup = () => {
      const n = g.members.filter((i) => state[i].visible).length;
      all.checked = n === g.members.length;
      all.indeterminate = n > 0 && n < g.members.length;
    };
    all.addEventListener('change', () => {
      for (const i of g.members) on.visible(i, all.checked);
      sync();
    });
    g.sync = syncGroup;
    container.append(el(doc, 'details', { open: groups.length <= 3 }, [head, body]));
  }
  function sync() {
    for (const r of rows) {
      r.box.checked = state[r.i].visible;
      r.alpha.value = state[r.i].opacity;
    }
    for (const g of groups) g.sync();
  }
  sync();
  return { sync };
}
