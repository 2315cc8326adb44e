// Section caps: where the clipping plane cuts a closed structure, the cut face is drawn solid in
// the structure's colour (stencil capping, as three.js's webgl_clipping_stencil example): the
// structure's clipped back faces add 1 to the stencil, its clipped front faces subtract 1, so
// the pixels where the plane runs inside the structure end non-zero; a quad on the plane is then
// drawn where the stencil is non-zero, and the stencil is cleared for the next structure.
// Neighbouring structures' caps meet along their shared interface.
import {
  AlwaysStencilFunc, BackSide, DecrementWrapStencilOp, DoubleSide, FrontSide, IncrementWrapStencilOp,
  Mesh, MeshBasicMaterial, MeshStandardMaterial, NotEqualStencilFunc, PlaneGeometry, ReplaceStencilOp,
} from 'three';

const QUAD = new PlaneGeometry(1, 1);

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
   *  `order` is the first of the three render orders the cap uses. */
  update(geometry, axis, at, { on, opacity, order }) {
    const box = geometry.boundingBox;
    const cut = on && !!box && box.min.getComponent(axis) < at && at < box.max.getComponent(axis);
    for (const m of [this.back, this.front, this.quad]) m.visible = cut;
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

  setColor(color) { this.quad.material.color.copy(color); }

  remove() { for (const m of [this.back, this.front, this.quad]) m.removeFromParent(); }
}
