// The rotation gizmo: rings at the selected bone's posed start joint. Dragging a ring
// turns the bone and everything below it about the ring's axis (3D: the world x, y,
// z axes and the view axis; 2D: one ring, the view axis z). The edit is posted as
// the forward-kinematics form (ik.js), stretch and twists kept.

import * as THREE from "three";

const RING_PX = 70;        // ring radius on screen, CSS pixels (the view ring: 1.2 times)
const PICK_PX = 8;         // a ring is picked within this many pixels of its drawn circle
const SEGMENTS = 96;

function circle() {
  const pts = new Float32Array(3 * SEGMENTS);
  for (let k = 0; k < SEGMENTS; k++) {
    const t = 2 * Math.PI * k / SEGMENTS;
    pts[3 * k] = Math.cos(t);
    pts[3 * k + 1] = Math.sin(t);
  }
  const g = new THREE.BufferGeometry();
  g.setAttribute("position", new THREE.BufferAttribute(pts, 3));
  return g;
}

export class Gizmo {
  /** ctx: {store, events, view, ...}; bones: the rig's Bones (ik.js). */
  constructor(ctx, bones) {
    this.store = ctx.store;
    this.view = ctx.view;
    this.bones = bones;
    this.bone = null;
    this.group = new THREE.Group();
    this.group.visible = false;
    this.group.renderOrder = 3;
    const geom = circle();
    const specs = bones.dim === 3
      ? [["x", [1, 0, 0], 0xff6060, 1], ["y", [0, 1, 0], 0x60e060, 1],
         ["z", [0, 0, 1], 0x6090ff, 1], ["view", null, 0xf0f0f0, 1.2]]
      : [["z", [0, 0, 1], 0xffd040, 1]];
    this.rings = specs.map(([name, axis, color, size]) => {
      const line = new THREE.LineLoop(geom, new THREE.LineBasicMaterial(
        { color, depthTest: false, transparent: true }));
      line.renderOrder = 3;
      line.frustumCulled = false;
      this.group.add(line);
      return { name, axis, size, line };
    });
    this.view.scene.add(this.group);
    const box = document.getElementById("gizmo");
    box?.addEventListener("change", () => this.set(box.checked ? this.selected() : null));
    // the gizmo, when shown, is on the selected bone
    ctx.events.on("select", ({ bone }) => { if (this.bone !== null && bone !== null) this.set(bone); });
  }

  selected() {
    const i = this.store.selection.bone;
    return i === null ? 0 : i;
  }

  /** Show the gizmo on a bone (index or name), or hide it (null). */
  set(bone) {
    if (bone === null || bone === undefined) {
      this.bone = null;
    } else {
      const b = this.bones, i = typeof bone === "number" ? bone : b.names.indexOf(String(bone));
      if (!Number.isInteger(i) || i < 0 || i >= b.b) {
        throw new Error(`gizmo: expected a bone index 0..${b.b - 1} or name, got ${JSON.stringify(bone)}`);
      }
      this.bone = i;
      this.store.select(i);
    }
    const box = document.getElementById("gizmo");
    if (box) box.checked = this.bone !== null;
    this.view.render();
    return this.bone;
  }

  center() {
    const o = this.store.pose.origins[this.bone];
    return new THREE.Vector3(o[0], o[1], this.bones.dim === 3 ? o[2] : 0);
  }

  /** World units per CSS pixel at point c, in the (left) viewport. */
  perPixel(c) {
    const cam = this.view.camera, h = Math.max(this.view.viewRect().height, 1);
    if (cam.isOrthographicCamera) return (cam.top - cam.bottom) / cam.zoom / h;
    const dist = c.distanceTo(cam.position);
    return 2 * dist * Math.tan(THREE.MathUtils.degToRad(0.5 * cam.fov)) / h;
  }

  /** The axis of a ring (the view ring: towards the camera). */
  axisOf(ring) {
    if (ring.axis) return new THREE.Vector3(...ring.axis);
    const cam = this.view.camera;
    if (cam.isOrthographicCamera) return cam.getWorldDirection(new THREE.Vector3()).negate();
    return cam.position.clone().sub(this.center()).normalize();
  }

  /** Place the rings (before each draw). */
  update() {
    this.group.visible = this.bone !== null;
    if (this.bone === null) return;
    const c = this.center(), r = RING_PX * this.perPixel(c), z = new THREE.Vector3(0, 0, 1);
    this.group.position.copy(c);
    this.group.updateMatrix();
    for (const ring of this.rings) {
      ring.line.quaternion.setFromUnitVectors(z, this.axisOf(ring));
      ring.line.scale.setScalar(r * ring.size);
    }
  }

  /** A ring's circle in world space, SEGMENTS points. */
  worldRing(ring) {
    this.update();
    const c = this.center(), r = RING_PX * ring.size * this.perPixel(c);
    const n = this.axisOf(ring), q = new THREE.Quaternion().setFromUnitVectors(new THREE.Vector3(0, 0, 1), n);
    const out = [];
    for (let k = 0; k < SEGMENTS; k++) {
      const t = 2 * Math.PI * k / SEGMENTS;
      out.push(new THREE.Vector3(r * Math.cos(t), r * Math.sin(t), 0).applyQuaternion(q).add(c));
    }
    return out;
  }

  /** The gizmo on the page: {bone, name, center, radius, rings: [{name, axis, points}]}, or null. */
  info(rect) {
    if (this.bone === null) return null;
    const c = this.center(), s = (p) => this.view.toScreen(p.x, p.y, p.z, rect);
    return { bone: this.bone, name: this.bones.names[this.bone], center: s(c), radius: RING_PX,
             rings: this.rings.map((ring) => ({
               name: ring.name, axis: this.axisOf(ring).toArray(),
               points: this.worldRing(ring).map(s) })) };
  }

  /** The ring under the pointer p ({x, y, rect}), or null. */
  pick(p) {
    if (this.bone === null) return null;
    let best = null, bestD = PICK_PX;
    for (const ring of this.rings) {
      const pts = this.worldRing(ring).map((q) => this.view.toScreen(q.x, q.y, q.z, p.rect));
      for (let k = 0; k < pts.length; k++) {
        const [ax, ay] = pts[k], [bx, by] = pts[(k + 1) % pts.length];
        const dx = bx - ax, dy = by - ay, l2 = dx * dx + dy * dy;
        const t = l2 > 0 ? Math.max(0, Math.min(1, ((p.x - ax) * dx + (p.y - ay) * dy) / l2)) : 0;
        const d = Math.hypot(p.x - ax - t * dx, p.y - ay - t * dy);
        if (d < bestD) { bestD = d; best = ring; }
      }
    }
    return best;
  }

  /** Start turning with `ring` grabbed at pointer p; returns the drag state. */
  begin(ring, p) {
    const c = this.center(), n = this.axisOf(ring);
    const ray = this.ray(p), toward = Math.abs(ray.direction.dot(n));
    const drag = { ring, axis: n, center: c, angle: 0, plane: toward > 0.15, x0: p.x, y0: p.y };
    if (drag.plane) {
      drag.prev = this.onPlane(drag, p);
      if (!drag.prev) drag.plane = false;
    }
    if (!drag.plane) {            // the ring seen edge-on: pointer travel along its tangent
      const pts = this.worldRing(ring);
      let g = pts[0], best = Infinity;
      for (const q of pts) {
        const [sx, sy] = this.view.toScreen(q.x, q.y, q.z, p.rect), d = Math.hypot(sx - p.x, sy - p.y);
        if (d < best) { best = d; g = q; }
      }
      const tangent = n.clone().cross(g.clone().sub(c)).normalize();
      const s0 = this.view.toScreen(g.x, g.y, g.z, p.rect);
      const eps = g.clone().addScaledVector(tangent, RING_PX * this.perPixel(c));
      const s1 = this.view.toScreen(eps.x, eps.y, eps.z, p.rect);
      drag.tangent = [(s1[0] - s0[0]) / RING_PX, (s1[1] - s0[1]) / RING_PX];
    }
    return drag;
  }

  ray(p) {
    const ray = new THREE.Raycaster();
    ray.setFromCamera(p.ndc, this.view.camera);
    return ray.ray;
  }

  onPlane(drag, p) {
    const plane = new THREE.Plane().setFromNormalAndCoplanarPoint(drag.axis, drag.center);
    const hit = new THREE.Vector3();
    if (!this.ray(p).intersectPlane(plane, hit)) return null;
    const v = hit.sub(drag.center);
    return v.lengthSq() > 0 ? v : null;
  }

  /** The total angle (radians, about drag.axis) for pointer p; unwrapped past half turns. */
  turn(drag, p) {
    if (drag.plane) {
      const v = this.onPlane(drag, p);
      if (v) {
        const step = Math.atan2(drag.axis.dot(drag.prev.clone().cross(v)), drag.prev.dot(v));
        drag.angle += step;
        drag.prev = v;
      }
    } else {
      const t = drag.tangent, l2 = t[0] * t[0] + t[1] * t[1];
      if (l2 > 0) drag.angle = ((p.x - drag.x0) * t[0] + (p.y - drag.y0) * t[1]) / l2 / RING_PX / drag.ring.size;
    }
    return drag.angle;
  }
}
