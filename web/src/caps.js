// Section caps: where the clipping plane cuts a closed structure, the cut face is drawn solid in
// the structure's colour (stencil capping, as three.js's webgl_clipping_stencil example): the
// structure's clipped back faces add 1 to the stencil, its clipped front faces subtract 1, so
// the pixels where the plane runs inside the structure end non-zero; a quad on the plane is then
// drawn where the stencil is non-zero, and the stencil is cleared for the next structure.
// Neighbouring structures' caps meet along their shared interface. On request each structure's
// outline on the cut is drawn too, a line of its colour darkened.
import {
  AlwaysStencilFunc, BackSide, BufferAttribute, BufferGeometry, DecrementWrapStencilOp, DoubleSide,
  FrontSide, IncrementWrapStencilOp, LineBasicMaterial, LineSegments, Mesh, MeshBasicMaterial,
  MeshStandardMaterial, NotEqualStencilFunc, PlaneGeometry, ReplaceStencilOp,
} from 'three';
import { planeSection } from './section.js';

const QUAD = new PlaneGeometry(1, 1);
/** The outline's distance (mm) off the plane, toward the side cut away: in front of the caps. */
const LIFT_MM = 0.05;
/** The outline's colour: the structure's, this much as bright. */
const OUTLINE_SHADE = 0.3;

function counter(side, op, plane) {
  return new MeshBasicMaterial({
    side, clippingPlanes: [plane], colorWrite: false, depthWrite: false, depthTest: false,
    stencilWrite: true, stencilFunc: AlwaysStencilFunc, stencilFail: op, stencilZFail: op, stencilZPass: op,
  });
}

/** The cap of one structure: two stencil passes over its geometry and a quad on the plane;
 *  `group` (a three.js Group) holds them, `plane` is the viewer's clipping plane. */
export class Cap {
  constructor(group, color, plane) {
    this.plane = plane;
    this.group = group;
    this.color = color;
    this.outline = null;  // made when first asked for
    this.back = new Mesh(undefined, counter(BackSide, IncrementWrapStencilOp, plane));
    this.front = new Mesh(undefined, counter(FrontSide, DecrementWrapStencilOp, plane));
    this.quad = new Mesh(QUAD, new MeshStandardMaterial({
      color, roughness: 0.55, metalness: 0, side: DoubleSide,
      stencilWrite: true, stencilRef: 0, stencilFunc: NotEqualStencilFunc,
      stencilFail: ReplaceStencilOp, stencilZFail: ReplaceStencilOp, stencilZPass: ReplaceStencilOp,
    }));
    this.quad.onAfterRender = (renderer) => renderer.clearStencil();
    for (const m of [this.back, this.front, this.quad]) {
      m.visible = false;
      m.raycast = () => {};  // picking goes to the structure's own meshes
      group.add(m);
    }
  }

  /** Show the cap of `geometry` (its bounding box in the display frame, mm) on the plane along
   *  `axis` (0 x, 1 y, 2 z) at `at` mm when the plane cuts the box; `opacity` < 1: see-through.
   *  `order` is the first of the three render orders the cap uses; `outline`: draw the outline. */
  update(geometry, axis, at, { on, opacity, order, outline = false }) {
    const box = geometry.boundingBox;
    const cut = on && !!box && box.min.getComponent(axis) < at && at < box.max.getComponent(axis);
    for (const m of [this.back, this.front, this.quad]) m.visible = cut;
    this.drawOutline(cut && outline ? geometry : null, axis, at);
    if (!cut) return false;
    this.back.geometry = this.front.geometry = geometry;
    const size = box.getSize(this.quad.scale.clone());
    const centre = box.getCenter(this.quad.position);
    centre.setComponent(axis, at);
    this.quad.rotation.set(axis === 1 ? -Math.PI / 2 : 0, axis === 0 ? Math.PI / 2 : 0, 0);
    const [u, v] = [[2, 1], [0, 2], [0, 1]][axis];  // the quad's x and y in the box's axes
    this.quad.scale.set(size.getComponent(u) * 1.02 + 1, size.getComponent(v) * 1.02 + 1, 1);
    const m = this.quad.material;
    const seeThrough = opacity < 1;
    if (m.transparent !== seeThrough) m.needsUpdate = true;
    Object.assign(m, { transparent: seeThrough, opacity, depthWrite: !seeThrough });
    for (const x of [this.back, this.front]) x.material.transparent = seeThrough;  // drawn in the same pass
    this.setOrder(order);
    return true;
  }

  /** Draw the two stencil passes and the quad at render orders order, order + 1, order + 2. */
  setOrder(order) {
    this.back.renderOrder = order;
    this.front.renderOrder = order + 1;
    this.quad.renderOrder = order + 2;
  }

  /** The outline of `geometry` on the plane along `axis` at `at` mm (planeSection), lifted
   *  LIFT_MM toward the side cut away; `geometry` null: none. */
  drawOutline(geometry, axis, at) {
    if (!geometry) { if (this.outline) this.outline.visible = false; return; }
    if (!this.outline) {
      const shade = this.color.clone().multiplyScalar(OUTLINE_SHADE);
      this.outline = new LineSegments(new BufferGeometry(), new LineBasicMaterial({ color: shade }));
      this.outline.raycast = () => {};
      this.outline.renderOrder = 1e5;
      this.group.add(this.outline);
    }
    this.outline.visible = true;
    const lifted = at - LIFT_MM * this.plane.normal.getComponent(axis);
    const key = `${geometry.id} ${axis} ${lifted}`;
    if (this.outline.userData.key === key) return;
    const ends = planeSection(geometry.getAttribute('position').array, geometry.index.array, axis, at);
    for (let k = axis; k < ends.length; k += 3) ends[k] = lifted;
    this.outline.geometry.dispose();
    this.outline.geometry = new BufferGeometry().setAttribute('position', new BufferAttribute(ends, 3));
    this.outline.userData.key = key;
  }

  remove() {
    for (const m of [this.back, this.front, this.quad, this.outline]) if (m) m.removeFromParent();
  }
}
