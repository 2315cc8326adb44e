// The page's view kept in its URL (url-state.js): what the page shows is written to the
// fragment as it changes, a fragment set by hand, by a bookmark or by a saved view (listed in
// the panel, from scene.js `views`) is shown. history.replaceState: no history entry per change.
import { emptyState, formatState, parseState } from './url-state.js';

const $ = (id) => document.getElementById(id);

/** Wire the URL to `viewer`; `sync()` refreshes the tree's inputs, `measure` is the measuring
 *  tool (measure-panel.js), `refresh()` redraws after a change. Returns {apply, changed, write,
 *  reset, state}. */
export function wireUrlState(viewer, { sync, measure, refresh }) {
  let view = null;          // the named view shown, until the camera moves
  let cameraSet = false;    // the camera was placed by the URL or moved by the user
  let timer = null;

  function state() {
    const st = emptyState();
    for (const it of viewer.items) {
      if (!it.visible) st.hide.push(it.s.name);
      if (it.opacity !== (it.s.opacity ?? 1)) st.opacity[it.s.name] = it.opacity;
    }
    if (viewer.clipping) st.clip = { ...viewer.clipping };
    st.view = cameraSet ? null : view;
    st.camera = cameraSet ? viewer.getCamera() : null;
    st.measure = measure.points();
    return st;
  }

  function write() {
    clearTimeout(timer);
    const text = formatState(state());
    const base = location.href.split('#')[0];
    if (location.hash.replace(/^#/, '') !== text) history.replaceState(null, '', text ? `${base}#${text}` : base);
  }

  function changed() {
    clearTimeout(timer);
    timer = setTimeout(write, 150);
  }

  function warn(text) {
    window.anatomesh.warnings.push(text);
    $('status').textContent = text;
  }

  /** Show the view of the URL's fragment (unknown names and bad values: a warning, the rest
   *  still applied). */
  function apply(hash = location.hash) {
    clearTimeout(timer);  // a write still pending from an earlier change must not undo this view
    let st;
    try {
      st = parseState(hash);
    } catch (err) {
      warn(err.message);
      return;
    }
    const names = new Set(viewer.items.map((it) => it.s.name));
    const unknown = [...st.hide, ...Object.keys(st.opacity)].filter((n) => !names.has(n));
    if (unknown.length) warn(`view: no structure named ${unknown.join(', ')} on this page`);
    for (const it of viewer.items) {
      it.visible = !st.hide.includes(it.s.name);
      it.opacity = st.opacity[it.s.name] ?? it.s.opacity ?? 1;
    }
    viewer.clipping = st.clip;
    $('clip-axis').value = st.clip ? st.clip.plane : '';
    if (st.clip) {
      $('clip-at').value = st.clip.fraction;
      $('clip-flip').checked = st.clip.flip;
      $('clip-outline').checked = st.clip.outline;
    }
    view = st.view;
    cameraSet = !!st.camera;
    if (st.camera) viewer.setCamera(st.camera);
    else if (st.view) viewer.setView(st.view);
    else viewer.resetView();
    $('view-name').value = st.view || '';
    measure.setPoints(st.measure);
    sync();
    refresh();
    write();
  }

  function reset() {
    view = null;
    cameraSet = false;
    $('view-name').value = '';
    viewer.resetView();
    write();
  }

  let moving = false;  // a drag or wheel of the controls: the camera moves only if it changes
  viewer.controls.addEventListener('start', () => { moving = true; });
  viewer.controls.addEventListener('end', () => { moving = false; });
  viewer.controls.addEventListener('change', () => {
    if (moving) { cameraSet = true; view = null; $('view-name').value = ''; }
    if (cameraSet) changed();
  });
  window.addEventListener('hashchange', (e) => apply(new URL(e.newURL).hash));
  $('view-name').addEventListener('change', () => {
    view = $('view-name').value || null;
    cameraSet = false;
    if (view) viewer.setView(view); else viewer.resetView();
    write();
  });
  listSavedViews(viewer.data.views || []);
  return { apply, changed, write, reset, state };
}

/** The page's saved views (scene.js `views`: [{name, fragment}]) as links in the panel. */
function listSavedViews(views) {
  $('saved').hidden = !views.length;
  $('saved-views').replaceChildren(...views.map((v) => {
    const a = document.createElement('a');
    a.href = `#${v.fragment}`;
    a.textContent = v.name;
    a.title = v.fragment;
    return a;
  }));
}
