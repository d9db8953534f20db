// What weight painting draws: the four-heaviest layout (stbsIndex, stbsWeight, stbsEnd)
// and the selected bone's (W, f(E)) per vertex (stbsSel) on the GPU, and the brush's ring.
//
// The layout attributes are drawn from the read-back program's own buffers (the view's
// feedback.bufferOf), so one upload per dab serves both the drawing and
// skinnedPositions(). A dab rebuilds the layout of the rows it changed (weightrows.js
// layoutRows) and uploads only those ranges, with bufferSubData (rowRanges merges rows
// close together into one range). Drawing waits for the next animation frame, so many
// dabs in one frame cost one drawing.

import * as THREE from "three";
import { layoutRows, rowRanges } from "./weightrows.js";

const LAYOUT = [["stbsIndex", 4], ["stbsWeight", 4], ["stbsEnd", 4]];

export class PaintGPU {
  /**
   * @param view     the page's drawing services {renderer, feedback, mesh, scene, render}
   * @param weights  {n, b, W, E, filters, bone}: the store's W and E (n x b, read here),
   *                 the endpoint curve of each bone (null: none; the editor's array, read
   *                 here) and the selected bone
   */
  constructor(view, { n, b, W, E, filters, bone }) {
    this.view = view;
    this.n = n;
    this.b = b;
    this.W = W;
    this.E = E;
    this.filters = filters;
    const gl = view.renderer.getContext(), fb = view.feedback, geom = view.mesh.geometry;
    this.gl = gl;
    // the layout the page loaded, taken over: the geometry draws from GL buffers below
    this.I4 = geom.attributes.stbsIndex.array;
    this.W4 = geom.attributes.stbsWeight.array;
    this.E4 = geom.attributes.stbsEnd.array;
    // the server's layout (from its float64 W) stands for every row still as loaded
    this.loaded = { W: W.slice(), I4: this.I4.slice(), W4: this.W4.slice() };
    this.sel = new Float32Array(2 * n);
    this.selBuffer = gl.createBuffer();
    gl.bindBuffer(gl.ARRAY_BUFFER, this.selBuffer);
    gl.bufferData(gl.ARRAY_BUFFER, this.sel, gl.DYNAMIC_DRAW);
    gl.bindBuffer(gl.ARRAY_BUFFER, null);
    this.uploads = [[fb.bufferOf.stbsIndex, this.I4, 4], [fb.bufferOf.stbsWeight, this.W4, 4],
                    [fb.bufferOf.stbsEnd, this.E4, 4], [this.selBuffer, this.sel, 2]]
      .map(([buffer, data, size]) => ({ buffer, data, size }));
    for (const [name, size] of LAYOUT) {
      geom.setAttribute(name, new THREE.GLBufferAttribute(fb.bufferOf[name], gl.FLOAT, size, 4, n));
    }
    geom.setAttribute("stbsSel", new THREE.GLBufferAttribute(this.selBuffer, gl.FLOAT, 2, 4, n));
    this.renderFrame = 0;
    this.ring = makeRing();
    view.scene.add(this.ring);
    this.showBone(bone);
  }

  /** Upload the rows (sorted, `count` of them; null: all) of every buffer. */
  upload(rows, count) {
    const gl = this.gl;
    const ranges = rows === null ? [[0, this.n]] : rowRanges(rows, count);
    for (const { buffer, data, size } of this.uploads) {
      gl.bindBuffer(gl.ARRAY_BUFFER, buffer);
      for (const [a, e] of ranges) gl.bufferSubData(gl.ARRAY_BUFFER, 4 * size * a, data, size * a, size * (e - a));
    }
    gl.bindBuffer(gl.ARRAY_BUFFER, null);
  }

  /** Rebuild the layout and bone's (W, f(E)) of rows (sorted, `count` of them; null:
   * all) from W and E, and upload them. */
  refreshRows(rows, count, bone) {
    if (rows === null) {
      const every = new Int32Array(this.n);
      for (let v = 0; v < this.n; v++) every[v] = v;
      layoutRows(this.W, this.E, this.b, every, this.n, this.I4, this.W4, this.E4, this.loaded, this.filters);
    } else {
      layoutRows(this.W, this.E, this.b, rows, count, this.I4, this.W4, this.E4, this.loaded, this.filters);
    }
    this.fillSelection(rows, count, bone);
    this.upload(rows, count);
  }

  /** Bone i's W and f(E) per vertex (rows, `count` of them, or all when null), into sel. */
  fillSelection(rows, count, i) {
    const b = this.b, f = this.filters[i], all = rows === null;
    const m = all ? this.n : count;
    for (let q = 0; q < m; q++) {
      const r = all ? q : rows[q], e = this.E[r * b + i];
      this.sel[2 * r] = this.W[r * b + i];
      this.sel[2 * r + 1] = f ? f(e) : e;
    }
  }

  /** Show bone i's weights (the heat maps' stbsSel) at every vertex. */
  showBone(i) {
    this.fillSelection(null, this.n, i);
    const gl = this.gl;
    gl.bindBuffer(gl.ARRAY_BUFFER, this.selBuffer);
    gl.bufferSubData(gl.ARRAY_BUFFER, 0, this.sel);
    gl.bindBuffer(gl.ARRAY_BUFFER, null);
    this.requestRender();
  }

  /** Draw on the next animation frame (many dabs, one drawing). */
  requestRender() {
    if (this.renderFrame) return;
    this.renderFrame = requestAnimationFrame(() => { this.renderFrame = 0; this.view.render(); });
  }

  // ------------------------------------------------------------------ the brush ring
  /** The brush's circle of `radius` on the posed surface at a hit, facing along the
   * surface normal. */
  showRing(hit, radius) {
    const r = this.ring, n = new THREE.Vector3(...hit.normal);
    if (n.lengthSq() === 0) n.set(0, 0, 1);
    r.position.set(...hit.posed);
    r.quaternion.setFromUnitVectors(new THREE.Vector3(0, 0, 1), n.normalize());
    r.scale.setScalar(radius);
    r.visible = true;
    this.requestRender();
  }

  hideRing() {
    if (!this.ring.visible) return;
    this.ring.visible = false;
    this.requestRender();
  }

  /** A new radius for the ring, where it is shown. */
  resizeRing(radius) {
    if (!this.ring.visible) return;
    this.ring.scale.setScalar(radius);
    this.requestRender();
  }
}

/** A unit circle in the xy plane, drawn over everything, hidden until placed. */
function makeRing() {
  const k = 64, pts = new Float32Array(3 * k);
  for (let i = 0; i < k; i++) {
    pts[3 * i] = Math.cos(2 * Math.PI * i / k); pts[3 * i + 1] = Math.sin(2 * Math.PI * i / k);
  }
  const g = new THREE.BufferGeometry();
  g.setAttribute("position", new THREE.BufferAttribute(pts, 3));
  const ring = new THREE.LineLoop(g, new THREE.LineBasicMaterial(
    { color: 0xffffff, depthTest: false, transparent: true, opacity: 0.85 }));
  ring.visible = false;
  ring.renderOrder = 3;
  ring.frustumCulled = false;
  return ring;
}
