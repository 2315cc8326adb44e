// The 3D view: three.js scene, camera, lights, the structures' meshes, progressive levels of
// detail, transparency, clipping with section caps, picking, markers, scale bar. The page's
// panel is wired in main.js.
//
// Shared interfaces: neighbouring structures own the same triangles with opposite orientation.
// Seen from either side only one of the two faces the viewer (back faces are culled), opaque
// structures have no back faces drawn (a cut is closed by its cap, caps.js), see-through ones
// draw their far side as a surface turned inside out (insideOut) and are pushed back by a
// polygon offset, so where one coincides with an opaque
// neighbour the opaque face wins every pixel: no view, opacity or cut shows z-fighting.
import {
  Box3, BufferAttribute, BufferGeometry, Color, DirectionalLight, Group,
  HemisphereLight, Line, LineBasicMaterial, Mesh, MeshStandardMaterial, OrthographicCamera, Plane,
  Points, PointsMaterial, Raycaster, Scene, Sphere, SRGBColorSpace, Vector2, Vector3, WebGLRenderer,
} from 'three';
import { OrbitControls } from 'three/addons/controls/OrbitControls.js';
import { Cap } from './caps.js';
import { CLIP_AXES, VIEWS } from './url-state.js';
import { choosePick, clipPlane, drawOrder, scaleBar } from './view-math.js';

/** Oriented transparency in the fragment shader (formula: view-math.js orientedAlpha). */
function addOrientedAlpha(material, uniforms) {
  material.onBeforeCompile = (shader) => {
    shader.uniforms.uOriented = uniforms.uOriented;
    shader.uniforms.uOrientedExponent = uniforms.uOrientedExponent;
    shader.fragmentShader = shader.fragmentShader
      .replace('#include <common>', '#include <common>\nuniform float uOriented;\nuniform float uOrientedExponent;')
      .replace('#include <opaque_fragment>', `
        vec3 viewDirection = isOrthographic ? vec3(0.0, 0.0, 1.0) : normalize(vViewPosition);
        float facing = 1.0 - pow(clamp(abs(dot(normalize(normal), viewDirection)), 0.0, 1.0), uOrientedExponent);
        diffuseColor.a = mix(diffuseColor.a, diffuseColor.a + (1.0 - diffuseColor.a) * facing, uOriented);
        #include <opaque_fragment>`);
  };
  material.customProgramCacheKey = () => 'anatomesh-oriented';
}

/** The same surface seen from inside: positions (and colours) shared, each triangle reversed and
 *  the normals negated. A see-through structure draws its far side with it, in the shader of its
 *  near side: one shader fewer to compile than a second, back-face material. */
function insideOut(g) {
  const idx = g.index.array;
  const reversed = new Uint32Array(idx.length);
  for (let t = 0; t < idx.length; t += 3) {
    reversed[t] = idx[t]; reversed[t + 1] = idx[t + 2]; reversed[t + 2] = idx[t + 1];
  }
  const out = new BufferGeometry();
  for (const [name, attr] of Object.entries(g.attributes)) out.setAttribute(name, attr);
  out.setAttribute('normal', new BufferAttribute(g.getAttribute('normal').array.map((x) => -x), 3));
  out.setIndex(new BufferAttribute(reversed, 1));
  out.boundingBox = g.boundingBox;
  out.boundingSphere = g.boundingSphere;
  return out;
}

function geometryOf(decoded) {
  const g = new BufferGeometry();
  g.setAttribute('position', new BufferAttribute(decoded.positions, 3));
  g.setIndex(new BufferAttribute(decoded.indices, 1));
  g.setAttribute('normal', new BufferAttribute(decoded.normals, 3));
  if (decoded.colors) g.setAttribute('color', new BufferAttribute(decoded.colors, 3));
  const { min, max, radius } = decoded.bounds;
  g.boundingBox = new Box3(new Vector3(...min), new Vector3(...max));
  g.boundingSphere = new Sphere(g.boundingBox.getCenter(new Vector3()), radius);
  return g;
}

export class Viewer {
  constructor(canvas, scene, onChange = () => {}) {
    this.data = scene;
    this.onChange = onChange;
    this.renderer = new WebGLRenderer({ canvas, antialias: true, stencil: true });
    this.renderer.setPixelRatio(Math.min(2, globalThis.devicePixelRatio || 1));
    this.renderer.localClippingEnabled = true;
    this.renderer.setClearColor(new Color(0x1d2026));
    this.scene = new Scene();
    this.root = new Group();
    this.scene.add(this.root);
    this.camera = new OrthographicCamera(-1, 1, 1, -1, -1e5, 1e5);
    const headlight = new DirectionalLight(0xffffff, 2.2);
    headlight.position.set(0.3, 0.5, 1);
    this.camera.add(headlight);
    this.scene.add(this.camera, new HemisphereLight(0xffffff, 0x666666, 1.3));
    this.controls = new OrbitControls(this.camera, canvas);
    this.controls.addEventListener('change', () => this.requestRender());
    this.uniforms = { uOriented: { value: 0 }, uOrientedExponent: { value: 0.7 } };
    this.plane = new Plane(new Vector3(0, 0, -1), 0);
    this.clipping = null;           // {plane: 'axial'|'coronal'|'sagittal', fraction, flip, outline} or null
    this.showDistance = false;
    this.level = -1;                // the finest level of detail shown so far
    this.geometries = new Map();    // geometry id → BufferGeometry, of that level
    this.items = [];                // per structure of the current model
    this.frameQueued = false;
    this.markers = this.makeMarkers();
    this.resize();
    new ResizeObserver(() => { if (this.sizeChanged()) this.resize(); }).observe(canvas);
  }

  /** Show model `m` of the scene (structures share geometries by id). */
  setModel(m) {
    for (const it of this.items) { this.root.remove(it.front, it.back); if (it.cap) it.cap.remove(); }
    this.model = this.data.models[m];
    this.items = this.model.structures.map((s) => this.makeItem(s));
    this.showDistance = this.showDistance && !!this.model.distance;
    this.refreshMaterials();
  }

  makeItem(s) {
    const color = new Color().setRGB(s.color[0], s.color[1], s.color[2], SRGBColorSpace);
    const make = () => {
      const mat = new MeshStandardMaterial({ color, roughness: 0.55, metalness: 0,
        polygonOffsetFactor: 2, polygonOffsetUnits: 8 });
      addOrientedAlpha(mat, this.uniforms);
      const mesh = new Mesh(this.geometries.get(s.geometry[this.level]) || new BufferGeometry(), mat);
      mesh.userData.structure = s;
      this.root.add(mesh);
      return mesh;
    };
    return { s, color, visible: s.visible !== false, opacity: s.opacity ?? 1,
      front: make(), back: make(), cap: null };  // back: insideOut, made when first seen; cap: at the first cut
  }

  /** Level `k` arrived: `decoded` maps geometry id → arrays (data.js); its geometries replace
   *  the coarser ones. */
  addLevel(k, decoded) {
    const old = this.geometries;
    this.geometries = new Map([...decoded].map(([id, arrays]) => [id, geometryOf(arrays)]));
    this.level = k;
    for (const it of this.items) {
      const g = this.geometries.get(it.s.geometry[k]);
      if (!g) continue;
      if (it.back.geometry !== it.front.geometry) it.back.geometry.dispose();
      it.front.geometry = it.back.geometry = g;
    }
    for (const g of old.values()) g.dispose();
    this.refreshMaterials();
  }

  /** The model's box (display frame, mm, full detail): {min: [x, y, z], max: [x, y, z]}. */
  bounds() {
    return this.model.box;
  }

  /** Front view of everything (patient facing the viewer, head up), whole scene in the frame. */
  resetView() {
    const b = this.bounds();
    this.fit = { w: b.max[0] - b.min[0], h: b.max[1] - b.min[1] };  // the front view's extent
    this.setCamera({ target: b.min.map((lo, k) => (lo + b.max[k]) / 2), ...VIEWS.anterior, zoom: 1 });
  }

  /** A named view (url-state.js VIEWS) of everything, centred, zoom 1. */
  setView(name) {
    const b = this.bounds();
    this.setCamera({ target: b.min.map((lo, k) => (lo + b.max[k]) / 2), ...VIEWS[name], zoom: 1 });
  }

  /** The camera as {target [3] mm, dir [3] from the target to the eye, up [3], zoom}. */
  getCamera() {
    const t = this.controls.target;
    const d = this.camera.position.clone().sub(t).divideScalar(this.eyeDistance || 1);
    return { target: t.toArray(), dir: d.toArray(), up: this.camera.up.toArray(), zoom: this.camera.zoom };
  }

  /** Set the camera from getCamera()'s form. The eye stays two model sizes from the target,
   *  depth range tight around the model (fine depth resolution). */
  setCamera({ target, dir, up, zoom }) {
    const b = this.bounds();
    const diag = Math.hypot(...b.max.map((hi, k) => hi - b.min[k])) || 1;
    this.eyeDistance = 2 * diag;
    Object.assign(this.camera, { near: diag * 0.01, far: 4 * diag, zoom });
    this.camera.up.set(...up).normalize();
    this.controls._quat.setFromUnitVectors(this.camera.up, new Vector3(0, 1, 0));  // the orbit's pole
    this.controls._quatInverse.copy(this.controls._quat).invert();
    this.controls.target.set(...target);
    this.camera.position.set(...dir).multiplyScalar(this.eyeDistance).add(this.controls.target);
    this.resize();
    this.controls.update();
  }

  /** The canvas's size on the page (CSS px), [width, height], at least 1 × 1. */
  canvasSize() {
    const canvas = this.renderer.domElement;
    return [canvas.clientWidth || 1, canvas.clientHeight || 1];
  }

  /** Whether the canvas's size differs from the drawing's (a new drawing buffer also clears it). */
  sizeChanged() {
    const [w, h] = this.canvasSize();
    const drawn = this.renderer.getSize(new Vector2());
    return drawn.x !== w || drawn.y !== h;
  }

  /** The drawing buffer and the camera's frustum to the canvas's size. */
  resize() {
    const [w, h] = this.canvasSize();
    if (this.sizeChanged()) this.renderer.setSize(w, h, false);
    const fit = this.fit || { w: 200, h: 200 };
    const e = 0.56 * Math.max(fit.h, fit.w * h / w, 1);  // half height: all in view, 12 % margin
    Object.assign(this.camera, { left: -e * w / h, right: e * w / h, top: e, bottom: -e });
    this.camera.updateProjectionMatrix();
    this.requestRender();
  }

  /** Materials after a change of visibility, opacity, clipping or colour mode. */
  refreshMaterials() {
    const planes = this.clipping ? [this.plane] : [];
    let axis = 0;
    if (this.clipping) {
      axis = { x: 0, y: 1, z: 2 }[CLIP_AXES[this.clipping.plane]];
      const p = clipPlane(CLIP_AXES[this.clipping.plane], this.clipping.fraction, this.bounds(), this.clipping.flip);
      this.plane.normal.set(...p.normal);
      this.plane.constant = p.constant;
    }
    this.items.forEach((it, i) => {
      const seeThrough = it.opacity < 1;
      const surface = it.front.geometry;
      const backNeeded = seeThrough || !!this.clipping;  // drawn, or picked through a cut
      if (backNeeded && it.back.geometry === surface && surface.index) it.back.geometry = insideOut(surface);
      const colors = this.showDistance && !!it.front.geometry.getAttribute('color');
      for (const mesh of [it.front, it.back]) {
        const m = mesh.material;
        if (m.vertexColors !== colors || m.transparent !== seeThrough) m.needsUpdate = true;
        m.vertexColors = colors;
        m.color.copy(colors ? new Color(1, 1, 1) : it.color);
        m.transparent = seeThrough;
        m.polygonOffset = seeThrough;  // behind a coincident opaque face (shared interfaces)
        m.opacity = it.opacity;
        m.depthWrite = !seeThrough;
        m.clippingPlanes = planes;
      }
      it.front.visible = it.visible && it.opacity > 0;
      it.back.visible = it.front.visible && seeThrough;
      if (this.clipping && !it.cap) it.cap = new Cap(this.root, it.color, this.plane);
      it.cut = !!it.cap && it.cap.update(it.front.geometry, axis, -this.plane.constant * this.plane.normal.getComponent(axis),
        { on: !!this.clipping && it.front.visible, opacity: it.opacity, order: 1 + 3 * i,
          outline: !!this.clipping && this.clipping.outline });
    });
    this.requestRender();
  }

  /** Draw order of the see-through structures for the current view (view-math.js drawOrder);
   *  a cut one draws its cap between its back and front faces. */
  sortTransparent() {
    for (const it of this.items) it.front.renderOrder = it.back.renderOrder = 0;  // opaque: by depth
    const see = this.items.filter((it) => it.front.visible && it.front.material.transparent);
    const dir = new Vector3();
    this.camera.getWorldDirection(dir);
    const items = see.map((it) => {
      const s = it.front.geometry.boundingSphere;
      return { depth: s ? s.center.clone().sub(this.camera.position).dot(dir) : 0, radius: s ? s.radius : 0 };
    });
    drawOrder(items).forEach(({ index, side }, k) => {
      const it = see[index];
      it[side].renderOrder = 4 * k + 1;
      if (side === 'back' && it.cut) it.cap.setOrder(4 * k + 2);
    });
  }

  /** Draw now (the picture is on screen when the browser next composites). */
  renderNow() {
    this.frameQueued = false;
    this.sortTransparent();
    this.renderer.render(this.scene, this.camera);
    this.onChange();
  }

  requestRender() {
    if (this.frameQueued || this.level < 0) return;  // nothing to show before the first level
    this.frameQueued = true;
    requestAnimationFrame(() => { if (this.frameQueued) this.renderNow(); });
  }

  /** Pixels per millimetre on screen (orthographic: the same at every depth). */
  pxPerMm() {
    const h = this.renderer.domElement.clientHeight || 1;
    return h * this.camera.zoom / (this.camera.top - this.camera.bottom);
  }

  scaleBar(targetPx = 100) { return scaleBar(this.pxPerMm(), targetPx); }

  /** What is under the pixel (x, y) of the canvas (CSS px): {s (structure), index, point [3]
   *  mm on its surface or on its cap}, or null. Hidden and clipped parts are never picked. */
  pick(x, y) {
    const canvas = this.renderer.domElement;
    const ndc = new Vector2(2 * x / canvas.clientWidth - 1, 1 - 2 * y / canvas.clientHeight);
    const ray = new Raycaster();
    ray.setFromCamera(ndc, this.camera);
    const shown = this.items.filter((it) => it.front.visible);
    const meshes = shown.flatMap((it) => (it.cut ? [it.front, it.back] : [it.front]));
    const entered = new Set();
    const hits = [];
    for (const h of ray.intersectObjects(meshes, false)) {
      if (this.clipping && this.plane.distanceToPoint(h.point) < 0) continue;
      const index = this.items.findIndex((it) => it.front === h.object || it.back === h.object);
      const it = this.items[index];
      if (h.object === it.front) entered.add(index);
      else if (entered.has(index)) continue;  // the inside of a structure entered through its surface
      else {  // the first face of a cut structure met from inside: the ray crossed its cap
        entered.add(index);
        h.point = ray.ray.intersectPlane(this.plane, new Vector3()) || h.point;
        h.distance = h.point.clone().sub(ray.ray.origin).dot(ray.ray.direction);
      }
      hits.push({ item: it, index, distance: h.distance, opacity: it.opacity, point: h.point.toArray() });
    }
    hits.sort((a, b) => a.distance - b.distance);
    const hit = choosePick(hits);
    return hit ? { s: hit.item.s, index: hit.index, point: hit.point } : null;
  }

  /** Measured points ([[x, y, z] mm], up to two) shown as dots joined by a line, on top. */
  setMarkers(points) {
    const flat = new Float32Array(points.flat());
    for (const obj of [this.markers.dots, this.markers.line]) {
      obj.geometry.setAttribute('position', new BufferAttribute(flat, 3));
      obj.geometry.computeBoundingSphere();
    }
    this.markers.dots.visible = points.length > 0;
    this.markers.line.visible = points.length > 1;
    this.requestRender();
  }

  makeMarkers() {
    const top = { depthTest: false, depthWrite: false, transparent: true };
    const dots = new Points(new BufferGeometry(), new PointsMaterial({ color: 0xffee00, size: 9, sizeAttenuation: false, ...top }));
    const line = new Line(new BufferGeometry(), new LineBasicMaterial({ color: 0xffee00, ...top }));
    for (const m of [dots, line]) { m.renderOrder = 1e6; m.visible = false; this.scene.add(m); }
    return { dots, line };
  }

  /** The picture as drawn now (tests): {width, height, rgba: Uint8Array, rows bottom up}. */
  readPixels() {
    this.renderNow();
    const gl = this.renderer.getContext();
    const [w, h] = [gl.drawingBufferWidth, gl.drawingBufferHeight];
    const rgba = new Uint8Array(w * h * 4);
    gl.readPixels(0, 0, w, h, gl.RGBA, gl.UNSIGNED_BYTE, rgba);
    return { width: w, height: h, rgba };
  }

  /** Bounding rectangle on the canvas (CSS px) of a structure's vertices: {x0, y0, x1, y1}. */
  screenBox(name) {
    const it = this.items.find((i) => i.s.name === name);
    const pos = it && it.front.geometry.getAttribute('position');
    if (!pos) return null;
    const canvas = this.renderer.domElement;
    const v = new Vector3();
    const r = { x0: Infinity, y0: Infinity, x1: -Infinity, y1: -Infinity };
    for (let k = 0; k < pos.count; k++) {
      v.fromBufferAttribute(pos, k).project(this.camera);
      const x = (v.x + 1) / 2 * canvas.clientWidth;
      const y = (1 - v.y) / 2 * canvas.clientHeight;
      r.x0 = Math.min(r.x0, x); r.x1 = Math.max(r.x1, x);
      r.y0 = Math.min(r.y0, y); r.y1 = Math.max(r.y1, y);
    }
    return r;
  }
}
