// Weight paint on the page: the panel, the pointer and the GPU. The work itself is in
// pure modules: brush.js (which vertices a dab covers, the new values), weightrows.js
// (a bone weight set with the row summing to 1 and locked bones kept, the four-heaviest
// layout, the log of changed rows), mirror.js (the X-mirror's bones and vertices).
//
// The store holds the full W and E (n x b Float32Arrays, row-major), edited in place.
// A dab rebuilds the four-heaviest layout (I4, W4, E4) of the rows it changed and
// uploads only those ranges, with bufferSubData, into the buffers that both the mesh
// and the read-back program draw from (so the drawing and skinnedPositions() follow
// every dab). The brush is placed by a ray cast against the skinned positions, read
// back once per pose (and method, and after each change of the weights), not per dab.
// Every stroke, recompute and baked curve is one command on the page's History.

import * as THREE from "three";
import { SplineEditor, splineFilter } from "./spline.js";
import { Brush, FALLOFFS, PAINT_OPS, adjacency } from "./brush.js";
import { RowLog, layoutRows, restoreRows, rowRanges, setBoneWeight } from "./weightrows.js";
import { centreX, mirrorBones, mirrorVertices } from "./mirror.js";
import { api as defaultApi, cancelJob, jobResult, jobStatus, saveRig as postRig, startEndpointJob } from "./api.js";

export { FALLOFFS, PAINT_OPS };
/** Colour modes, in the order of the shader's uColorMode (skin.js). */
export const COLOR_MODES = ["shaded", "bones", "endpoint", "weight"];
export const PAINT_MODES = ["off", "bone", "endpoint"];
export const ENDPOINT_METHODS = ["projection", "idw", "heat", "bbw", "bbw-joints"];
/** `[` and `]` scale the brush's radius by this. */
export const RADIUS_STEP = 1.25;

function bad(what, expected, got) {
  return new Error(`${what}: expected ${expected}, got ${JSON.stringify(got)}`);
}

function sameArray(a, b) {
  if (a.length !== b.length) return false;
  for (let k = 0; k < a.length; k++) if (a[k] !== b[k]) return false;
  return true;
}

export class WeightEditor {
  /**
   * @param ctx  the page's context {store, events, history, keys, view} (or an object
   *             holding it as .ctx), with store.rig, store.W and store.E loaded
   * @param api  fetch(path, options) with the token, throwing on an error answer
   */
  constructor(ctx, api = defaultApi) {
    ctx = ctx.ctx || ctx;
    const { store, events, history, keys, view } = ctx;
    this.store = store; this.events = events; this.history = history; this.keys = keys; this.view = view;
    this.api = api;
    const rig = store.rig;
    this.n = rig.n;
    this.b = rig.b;
    this.dim = rig.dim;
    const nb = this.n * this.b;
    if (!(store.W instanceof Float32Array) || store.W.length !== nb || !(store.E instanceof Float32Array) || store.E.length !== nb) {
      throw new Error(`weights: expected W and E of ${this.n} x ${this.b} values from the server`);
    }
    this.W = store.W;
    this.E = store.E;
    this.parents = Int32Array.from(rig.parents || new Array(this.b).fill(-1));
    this.names = rig.names.slice();
    this.rig = rig;
    this.summary = rig.summary || {};
    const geom = view.mesh.geometry;
    this.rest = geom.attributes.position.array;                 // n x 3 (z = 0 in 2D)
    this.faces = rig.F ? Uint32Array.from(rig.F) : new Uint32Array(0);
    this.nbrs = adjacency(this.faces, this.n);
    this.brush = new Brush(this.rest, 3, this.nbrs);
    this.log = new RowLog(this.n, this.b);
    this.locked = new Uint8Array(this.b);
    this.filters = new Array(this.b).fill(null);     // bone -> spline filter previewed (not yet in E)
    this.scratch = new Float64Array(2 * this.b);
    this.changed = new Int32Array(1024);
    this.stamp = new Int32Array(this.n);             // per vertex: the dab that last took it
    this.dabCount = 0;
    this.mirrorMaps = null;
    const diag = view.diag;
    this.settings = { mode: "off", bone: store.selection.bone ?? 0, op: "add", radius: 0.08 * diag,
                      strength: 0.25, falloff: "smooth" };
    this.colorModeName = "shaded";
    this.stroke = null;
    this.lastStroke = null;
    this.serverW = this.W.slice();       // the weights the server has (sent with a recompute when not)
    this.setupBuffers(geom);
    this.posedCache = null;
    this.weightsVersion = 0;
    events.on("pose", () => { this.posedCache = null; });
    events.on("select", ({ bone }) => { if (bone !== null && bone !== this.settings.bone) this.selectBone(bone, false); });
    events.on("mirror", () => this.showSettings());
    const canvas = view.renderer.domElement;
    this.canvas = canvas;
    // capture phase on window: runs before the canvas' own listeners (joint drags, orbit)
    window.addEventListener("pointerdown", (e) => this.onDown(e), { capture: true });
    window.addEventListener("pointermove", (e) => this.onMove(e), { capture: true });
    window.addEventListener("pointerup", (e) => this.onUp(e), { capture: true });
    window.addEventListener("pointercancel", (e) => this.onUp(e), { capture: true });
    canvas.addEventListener("pointerleave", () => this.hideRing());
    this.ring = this.makeRing();
    view.scene.add(this.ring);
    keys.register({ key: "[", label: "brush smaller", run: () => this.resizeBrush(1 / RADIUS_STEP) });
    keys.register({ key: "]", label: "brush larger", run: () => this.resizeBrush(RADIUS_STEP) });
    this.buildPanel();
  }

  // ------------------------------------------------------------------ GPU buffers
  /**
   * The layout attributes (stbsIndex, stbsWeight, stbsEnd) drawn from the read-back
   * program's buffers, and stbsSel (the selected bone's W and f(E)) from a buffer of
   * our own: one upload per dab serves the drawing and skinnedPositions().
   */
  setupBuffers(geom) {
    const gl = this.view.renderer.getContext(), fb = this.view.feedback;
    this.gl = gl;
    this.I4 = geom.attributes.stbsIndex.array;
    this.W4 = geom.attributes.stbsWeight.array;
    this.E4 = geom.attributes.stbsEnd.array;
    // the server's layout (from its float64 W) stands for every row still as loaded
    this.loaded = { W: this.W.slice(), I4: this.I4.slice(), W4: this.W4.slice() };
    this.sel = new Float32Array(2 * this.n);
    this.selBuffer = gl.createBuffer();
    gl.bindBuffer(gl.ARRAY_BUFFER, this.selBuffer);
    gl.bufferData(gl.ARRAY_BUFFER, this.sel, gl.DYNAMIC_DRAW);
    gl.bindBuffer(gl.ARRAY_BUFFER, null);
    this.uploads = [["stbsIndex", this.I4, 4], ["stbsWeight", this.W4, 4], ["stbsEnd", this.E4, 4]]
      .map(([name, data, size]) => ({ buffer: fb.bufferOf[name], data, size }));
    this.uploads.push({ buffer: this.selBuffer, data: this.sel, size: 2 });
    for (const [name, size] of [["stbsIndex", 4], ["stbsWeight", 4], ["stbsEnd", 4]]) {
      geom.setAttribute(name, new THREE.GLBufferAttribute(fb.bufferOf[name], gl.FLOAT, size, 4, this.n));
    }
    geom.setAttribute("stbsSel", new THREE.GLBufferAttribute(this.selBuffer, gl.FLOAT, 2, 4, this.n));
    this.updateSelection(null);
  }

  /** Upload the rows (sorted, `count` of them; null: all) of every layout buffer. */
  upload(rows, count) {
    const gl = this.gl;
    const ranges = rows === null ? [[0, this.n]] : rowRanges(rows, count);
    for (const { buffer, data, size } of this.uploads) {
      gl.bindBuffer(gl.ARRAY_BUFFER, buffer);
      for (const [a, e] of ranges) gl.bufferSubData(gl.ARRAY_BUFFER, 4 * size * a, data, size * a, size * (e - a));
    }
    gl.bindBuffer(gl.ARRAY_BUFFER, null);
  }

  /** Rebuild the layout and the selection of rows (sorted; null: all) and upload them. */
  refreshRows(rows, count = rows ? rows.length : this.n) {
    const all = rows === null;
    const list = all ? null : rows;
    if (all) {
      const every = new Int32Array(this.n);
      for (let v = 0; v < this.n; v++) every[v] = v;
      layoutRows(this.W, this.E, this.b, every, this.n, this.I4, this.W4, this.E4, this.loaded, this.filters);
    } else {
      layoutRows(this.W, this.E, this.b, list, count, this.I4, this.W4, this.E4, this.loaded, this.filters);
    }
    this.fillSelection(list, count);
    this.upload(list, count);
    this.store.weightsChanged(all ? null : list.slice(0, count));
  }

  /** The selected bone's W and f(E) per vertex (rows, or all when null), into sel. */
  fillSelection(rows, count) {
    const i = this.settings.bone, b = this.b, f = this.filters[i], all = rows === null;
    const m = all ? this.n : count;
    for (let q = 0; q < m; q++) {
      const r = all ? q : rows[q], e = this.E[r * b + i];
      this.sel[2 * r] = this.W[r * b + i];
      this.sel[2 * r + 1] = f ? f(e) : e;
    }
  }

  updateSelection(rows) {
    this.fillSelection(rows, rows ? rows.length : this.n);
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
  makeRing() {
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

  /** The brush's circle on the posed surface at a hit, facing along the surface normal. */
  showRing(hit) {
    const r = this.ring, n = new THREE.Vector3(...hit.normal);
    if (n.lengthSq() === 0) n.set(0, 0, 1);
    r.position.set(...hit.posed);
    r.quaternion.setFromUnitVectors(new THREE.Vector3(0, 0, 1), n.normalize());
    r.scale.setScalar(this.settings.radius);
    r.visible = true;
    this.requestRender();
  }

  hideRing() {
    if (!this.ring.visible || this.stroke) return;
    this.ring.visible = false;
    this.requestRender();
  }

  /** Pointer over the canvas in paint mode: the ring follows (once a frame). */
  hover(e) {
    if (this.settings.mode === "off" || e.target !== this.canvas) { this.hideRing(); return; }
    this.hoverAt = [e.clientX, e.clientY];
    if (this.hoverFrame) return;
    this.hoverFrame = requestAnimationFrame(() => {
      this.hoverFrame = 0;
      if (this.stroke || this.settings.mode === "off" || !this.hoverAt) return;
      const hit = this.pick(...this.hoverAt);
      if (hit) this.showRing(hit); else this.hideRing();
    });
  }

  resizeBrush(k) {
    const lo = this.view.diag / 200, hi = this.view.diag / 2;
    this.setPaint({ radius: Math.min(hi, Math.max(lo, this.settings.radius * k)) });
  }

  // ------------------------------------------------------------------ helpers
  boneIndex(key) {
    if (typeof key === "number" && Number.isInteger(key) && key >= 0 && key < this.b) return key;
    if (typeof key === "string") {
      const k = this.names.indexOf(key);
      if (k >= 0) return k;
      if (/^\d+$/.test(key) && Number(key) < this.b) return Number(key);
    }
    throw bad("bone", `an index 0..${this.b - 1} or a bone name`, key);
  }

  /** The X-mirror's maps (made when first needed): bone -> bone, vertex -> vertex. */
  mirror() {
    if (!this.mirrorMaps) {
      const rig = this.rig, centre = centreX(rig.V, rig.dim);
      this.mirrorMaps = { bones: mirrorBones(rig, { centre }),
                          vertices: mirrorVertices(this.rest, 3, { centre, grid: this.brush.grid }) };
    }
    return this.mirrorMaps;
  }

  // ------------------------------------------------------------------ colour modes
  setColorMode(name) {
    const k = COLOR_MODES.indexOf(name);
    if (k < 0) throw bad("colour mode", `one of ${COLOR_MODES.join(", ")}`, name);
    this.colorModeName = name;
    this.view.setUniform("uColorMode", k);
    const sel = document.getElementById("color-mode");
    if (sel) sel.value = name;
    this.view.render();
    return name;
  }

  colorMode() { return this.colorModeName; }

  // ------------------------------------------------------------------ settings
  setPaint(opts = {}) {
    if (opts === null || typeof opts !== "object" || Array.isArray(opts)) {
      throw bad("setPaint", "an object {mode, bone, op, radius, strength, falloff, mirror}", opts);
    }
    const keys = ["mode", "bone", "op", "radius", "strength", "falloff", "mirror"];
    for (const k of Object.keys(opts)) {
      if (!keys.includes(k)) throw bad("setPaint", `keys among ${keys.join(", ")}`, k);
    }
    const s = Object.assign({}, this.settings);
    if ("mode" in opts) {
      if (!PAINT_MODES.includes(opts.mode)) throw bad("paint mode", `one of ${PAINT_MODES.join(", ")}`, opts.mode);
      s.mode = opts.mode;
    }
    if ("bone" in opts) s.bone = this.boneIndex(opts.bone);
    if ("op" in opts) {
      if (!PAINT_OPS.includes(opts.op)) throw bad("brush op", `one of ${PAINT_OPS.join(", ")}`, opts.op);
      s.op = opts.op;
    }
    if ("radius" in opts) {
      if (typeof opts.radius !== "number" || !(opts.radius > 0) || !Number.isFinite(opts.radius)) {
        throw bad("brush radius", "a positive number (the rig's units)", opts.radius);
      }
      s.radius = opts.radius;
    }
    if ("strength" in opts) {
      if (typeof opts.strength !== "number" || !(opts.strength >= 0 && opts.strength <= 1)) {
        throw bad("brush strength", "a number in [0, 1]", opts.strength);
      }
      s.strength = opts.strength;
    }
    if ("falloff" in opts) {
      if (!FALLOFFS.includes(opts.falloff)) throw bad("brush falloff", `one of ${FALLOFFS.join(", ")}`, opts.falloff);
      s.falloff = opts.falloff;
    }
    if ("mirror" in opts && typeof opts.mirror !== "boolean") throw bad("mirror", "true or false", opts.mirror);
    const boneChanged = s.bone !== this.settings.bone;
    this.settings = s;
    if ("mirror" in opts) this.store.setMirror(opts.mirror);
    this.store.setBrush({ radius: s.radius, strength: s.strength, op: s.op, falloff: s.falloff, target: s.mode });
    this.store.setMode(s.mode === "off" ? "pose" : "paint");
    if (s.mode === "off") this.hideRing();
    else if (this.ring.visible) { this.ring.scale.setScalar(s.radius); this.requestRender(); }
    if (boneChanged) this.selectBone(s.bone, true);
    this.showSettings();
    return this.paintSettings();
  }

  paintSettings() {
    return Object.assign({}, this.settings, { boneName: this.names[this.settings.bone],
                                              mirror: this.store.mirror, locked: this.lockedBones() });
  }

  /** The selected bone: the one painted and shown by the heat maps. */
  selectBone(i, fromApi) {
    this.settings.bone = i;
    if (this.store.selection.bone !== i) this.store.select(i);
    const sel = document.getElementById("bone");
    if (fromApi && sel && sel.value !== String(i)) {
      sel.value = String(i);
      sel.dispatchEvent(new Event("change"));
    }
    this.updateSelection(null);
    if (this.curve) this.curve.set(this.splinePointsOf(i).slice(1, -1));
    this.showSettings();
  }

  // ------------------------------------------------------------------ locks
  /** Lock (true) or unlock bone weights: painting never changes a locked bone's weight. */
  setLock(bone, on) {
    const i = this.boneIndex(bone);
    if (typeof on !== "boolean") throw bad("lock", "true or false", on);
    this.locked[i] = on ? 1 : 0;
    this.showSettings();
    return this.lockedBones();
  }

  lockedBones() {
    const out = [];
    for (let i = 0; i < this.b; i++) if (this.locked[i]) out.push(i);
    return out;
  }

  // ------------------------------------------------------------------ picking
  /** The skinned positions (n x 3) for the pose shown, read back once per pose. */
  posed() {
    const method = this.view.material.uniforms.uMethod.value;
    const c = this.posedCache;
    if (c && (this.stroke || (c.method === method && c.version === this.weightsVersion))) return c.U;
    const U = this.view.skinned()[0];
    this.posedCache = { U, method, version: this.weightsVersion };
    return U;
  }

  /** Where the pointer's ray meets the posed surface: {face, u, v, t, rest, posed, normal} or null. */
  pick(clientX, clientY) {
    const rect = this.view.viewRectAt ? this.view.viewRectAt(clientX, clientY) : this.view.viewRect();
    const ndc = new THREE.Vector2(2 * (clientX - rect.left) / rect.width - 1,
                                  1 - 2 * (clientY - rect.top) / rect.height);
    if (Math.abs(ndc.x) > 1 || Math.abs(ndc.y) > 1) return null;     // outside the view
    const ray = new THREE.Raycaster();
    ray.setFromCamera(ndc, this.view.camera);
    const o = ray.ray.origin, d = ray.ray.direction;
    const U = this.posed(), F = this.faces;
    let best = null;
    for (let f = 0; f < F.length; f += 3) {    // Moller-Trumbore, both sides
      const i0 = 3 * F[f], i1 = 3 * F[f + 1], i2 = 3 * F[f + 2];
      const e1x = U[i1] - U[i0], e1y = U[i1 + 1] - U[i0 + 1], e1z = U[i1 + 2] - U[i0 + 2];
      const e2x = U[i2] - U[i0], e2y = U[i2 + 1] - U[i0 + 1], e2z = U[i2 + 2] - U[i0 + 2];
      const px = d.y * e2z - d.z * e2y, py = d.z * e2x - d.x * e2z, pz = d.x * e2y - d.y * e2x;
      const det = e1x * px + e1y * py + e1z * pz;
      if (Math.abs(det) < 1e-20) continue;
      const inv = 1 / det;
      const sx = o.x - U[i0], sy = o.y - U[i0 + 1], sz = o.z - U[i0 + 2];
      const u = (sx * px + sy * py + sz * pz) * inv;
      if (u < 0 || u > 1) continue;
      const qx = sy * e1z - sz * e1y, qy = sz * e1x - sx * e1z, qz = sx * e1y - sy * e1x;
      const w = (d.x * qx + d.y * qy + d.z * qz) * inv;
      if (w < 0 || u + w > 1) continue;
      const t = (e2x * qx + e2y * qy + e2z * qz) * inv;
      if (t <= 0 || (best && t >= best.t)) continue;
      best = { face: f / 3, u, v: w, t };
    }
    if (!best) return null;
    const a = 3 * F[3 * best.face], b = 3 * F[3 * best.face + 1], c = 3 * F[3 * best.face + 2];
    const wa = 1 - best.u - best.v, R = this.rest;
    best.rest = [0, 1, 2].map((k) => wa * R[a + k] + best.u * R[b + k] + best.v * R[c + k]);
    best.posed = [0, 1, 2].map((k) => wa * U[a + k] + best.u * U[b + k] + best.v * U[c + k]);
    const e1 = [0, 1, 2].map((k) => U[b + k] - U[a + k]), e2 = [0, 1, 2].map((k) => U[c + k] - U[a + k]);
    best.normal = [e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]];
    return best;
  }

  // ------------------------------------------------------------------ strokes
  onDown(e) {
    if (this.settings.mode === "off" || e.target !== this.canvas || e.button !== 0 || e.altKey ||
        this.stroke) return;                   // Alt+drag orbits, as in every mode
    const hit = this.pick(e.clientX, e.clientY);
    if (!hit) return;                          // off the mesh: the orbit controls have it
    e.stopImmediatePropagation();
    e.preventDefault();
    this.view.setOrbit(false);
    try { this.canvas.setPointerCapture(e.pointerId); } catch (_) { /* synthetic */ }
    this.beginStroke(e.pointerId);
    this.dab(hit, e.clientX, e.clientY);
  }

  onMove(e) {
    if (!this.stroke) { this.hover(e); return; }
    if (e.pointerId !== this.stroke.id) return;
    e.stopImmediatePropagation();
    e.preventDefault();
    const hit = this.pick(e.clientX, e.clientY);
    if (!hit) return;
    const last = this.stroke.last;
    const dist = last ? Math.hypot(hit.rest[0] - last[0], hit.rest[1] - last[1], hit.rest[2] - last[2]) : Infinity;
    if (dist < 0.25 * this.settings.radius) return;     // dabs a quarter radius apart
    this.dab(hit, e.clientX, e.clientY);
  }

  onUp(e) {
    if (!this.stroke || e.pointerId !== this.stroke.id) return;
    e.stopImmediatePropagation();
    try { this.canvas.releasePointerCapture(e.pointerId); } catch (_) { /* synthetic */ }
    this.view.setOrbit(true);
    this.endStroke();
  }

  beginStroke(id) {
    this.stroke = { id, dabs: [], last: null, mode: this.settings.mode, bone: this.settings.bone,
                    mirror: this.store.mirror };
  }

  /** Remember a changed vertex of this dab (growing the reusable list). */
  mark(v, count) {
    if (count === this.changed.length) {
      const c = new Int32Array(2 * count);
      c.set(this.changed);
      this.changed = c;
    }
    this.changed[count] = v;
    return count + 1;
  }

  /**
   * Paint column i of W (mode "bone") or E with the brush's current cover (brush.ids,
   * brush.amount); the changed vertices are added to this.changed from `count`.
   */
  paintCover(mode, i, op, count) {
    const brush = this.brush, W = this.W, E = this.E, b = this.b;
    const m = brush.apply(mode === "bone" ? W : E, b, i, op);
    const opts = { locked: this.locked, nbrs: this.nbrs, parents: this.parents, scratch: this.scratch };
    for (let q = 0; q < m; q++) {
      const v = brush.ids[q], t = brush.values[q];
      this.log.keep(W, E, v);
      if (mode === "bone") {
        if (setBoneWeight(W, b, v, i, t, opts)) count = this.mark(v, count);
      } else {
        E[v * b + i] = t;
        count = this.mark(v, count);
      }
    }
    return count;
  }

  /** One dab of the brush at a surface point; returns the milliseconds it took. */
  dab(hit, x, y) {
    const t0 = performance.now();
    const s = this.settings, st = this.stroke, i = st.bone, brush = this.brush;
    const stamp = ++this.dabCount;
    const covered = brush.cover(hit.rest, s);
    let count = 0;
    let mids = null, mamt = null, mcount = 0, j = i;
    if (st.mirror) {
      // the mirror vertices of the cover, each once (the largest amount), for the mirror
      // bone; where that is the same bone, vertices the dab covers itself are left out
      const maps = this.mirror();
      j = maps.bones[i];
      mids = new Int32Array(brush.count); mamt = new Float64Array(brush.count);
      const own = j === i ? stamp : -1, slot = new Map();
      if (own > 0) for (let q = 0; q < brush.count; q++) this.stamp[brush.ids[q]] = own;
      for (let q = 0; q < brush.count; q++) {
        const u = maps.vertices[brush.ids[q]], a = brush.amount[q];
        if (this.stamp[u] === own) continue;
        const k = slot.get(u);
        if (k === undefined) { slot.set(u, mcount); mids[mcount] = u; mamt[mcount++] = a; } else if (a > mamt[k]) mamt[k] = a;
      }
    }
    count = this.paintCover(st.mode, i, s.op, count);
    if (mcount) {
      brush.ids.set(mids.subarray(0, mcount));
      brush.amount.set(mamt.subarray(0, mcount));
      brush.count = mcount;
      count = this.paintCover(st.mode, j, s.op, count);
    }
    if (count) {
      const rows = this.changed.subarray(0, count).sort();
      let m = 0;                       // a vertex painted twice (mirror) counts once
      for (let q = 0; q < count; q++) if (q === 0 || rows[q] !== rows[q - 1]) rows[m++] = rows[q];
      this.refreshRows(rows, m);
    }
    const ms = performance.now() - t0;
    st.dabs.push({ rest: hit.rest.slice(), posed: hit.posed.slice(), x, y, radius: s.radius, ms, covered });
    st.last = hit.rest;
    this.showRing(hit);
    return ms;
  }

  endStroke() {
    const st = this.stroke;
    this.stroke = null;
    this.lastStroke = { mode: st.mode, bone: st.bone, mirror: st.mirror, dabs: st.dabs, vertices: 0 };
    const change = this.log.take(this.W, this.E);
    if (change) {
      this.record(change, st.mode === "bone" ? "paint bone weights" : "paint endpoint weights");
      this.lastStroke.vertices = change.rows.length;
    }
  }

  /** A change already made, as a History command that restores the rows bit for bit. */
  record(change, name) {
    this.weightsVersion++;
    const apply = (which) => {
      if (this.stroke) throw new Error("weights: a stroke is in progress");
      restoreRows(this.W, this.E, this.b, change, which);
      this.weightsVersion++;
      this.refreshRows(change.rows, change.rows.length);
      this.requestRender();
    };
    this.history.push({ name, execute: () => apply("after"), undo: () => apply("before") });
  }

  get undoStack() { return this.history.undos; }
  get redoStack() { return this.history.redos; }

  /** One step back on the page's History; resolves to whether there was one. */
  async undo() {
    if (this.stroke) return false;
    return (await this.history.undo()) !== null;
  }

  async redo() {
    if (this.stroke) return false;
    return (await this.history.redo()) !== null;
  }

  /** Replace column E[:, i] (one command); returns whether anything changed. */
  setEndpointColumn(i, col, label) {
    const b = this.b;
    for (let r = 0; r < this.n; r++) {
      const e = Math.fround(col[r]);
      if (e === this.E[r * b + i]) continue;
      this.log.keep(this.W, this.E, r);
      this.E[r * b + i] = e;
    }
    const change = this.log.take(this.W, this.E);
    if (!change) return false;
    this.refreshRows(change.rows, change.rows.length);
    this.requestRender();
    this.record(change, label);
    return true;
  }

  weights() {
    return { W: this.W.slice(), E: this.E.slice() };
  }

  // ------------------------------------------------------------------ the server
  /** The endpoint methods this rig's mesh can compute (the server's list). */
  endpointMethods() {
    const m = this.summary.endpoint_methods;
    return Array.isArray(m) && m.length ? m.filter((x) => ENDPOINT_METHODS.includes(x)) : ENDPOINT_METHODS.slice();
  }

  /**
   * Recompute bone's endpoint weights on the server as a job (POST /api/jobs/endpoint),
   * following its progress until done, then replace column E[:, bone] (one command).
   * `onProgress({stage, done, total})` is called as the job reports; cancel() stops it.
   * Resolves to the column (Float32Array); rejects when the job fails or is cancelled.
   */
  async recompute(bone, method, options = {}, onProgress = null) {
    const i = this.boneIndex(bone), can = this.endpointMethods();
    if (!can.includes(method)) throw bad("endpoint method", `one of ${can.join(", ")}`, method);
    if (options === null || typeof options !== "object" || Array.isArray(options)) {
      throw bad("endpoint options", "an object", options);
    }
    if (this.job) throw new Error(`an endpoint recompute is running (${this.job.method}); cancel it first`);
    let W = null;
    if (!sameArray(this.W, this.serverW)) {     // painted since loaded or saved: send ours
      const b = this.b;
      W = [];
      for (let r = 0; r < this.n; r++) W.push(Array.from(this.W.subarray(r * b, (r + 1) * b)));
    }
    const id = await startEndpointJob(i, method, { W, options });
    this.job = { id, method };
    try {
      let st = await jobStatus(id);
      while (st.state === "running") {
        if (onProgress) onProgress(st);
        await new Promise((ok) => setTimeout(ok, 100));
        st = await jobStatus(id);
      }
      if (onProgress) onProgress(st);
      if (st.state === "cancelled") throw new Error(`recompute (${method}): cancelled`);
      if (st.state !== "done") throw new Error(`recompute (${method}): ${st.error || st.state}`);
      const col = await jobResult(id);
      if (col.length !== this.n) throw new Error(`/api/jobs/${id}/result: expected ${this.n} values, got ${col.length}`);
      this.setEndpointColumn(i, col, `recompute endpoint weights (${method})`);
      return col;
    } finally {
      this.job = null;
    }
  }

  /** Cancel the running recompute; resolves to whether one was running. */
  async cancelRecompute() {
    const job = this.job;
    if (!job) return false;
    await cancelJob(job.id);
    return true;
  }

  /**
   * POST /api/save-rig with the page's W and E. The server answers 409 when the file
   * exists and `overwrite` is false; resolves to its answer.
   */
  async saveRig(overwrite = false) {
    if (typeof overwrite !== "boolean") throw bad("overwrite", "true or false", overwrite);
    const sent = this.W.slice();
    const reply = await postRig(this.W, this.E, { overwrite });
    this.serverW = sent;          // the rig served now has these weights
    return reply;
  }

  /** The save button: save; where the file exists, ask before writing over it. */
  async saveRigAsking() {
    try {
      return await this.saveRig(false);
    } catch (err) {
      if (err.status !== 409) throw err;
      if (!window.confirm(`${err.message}\n\nWrite over it?`)) return null;
      return this.saveRig(true);
    }
  }

  // ------------------------------------------------------------------ the curve
  splinePointsOf(i) {
    const f = this.filters[i];
    return f ? f.points.map((p) => p.slice()) : [[0, 0], [1, 1]];
  }

  /** Preview a curve for bone i (its inner points; ends optional): the shader uses f(E). */
  setSpline(bone, points) {
    const i = this.boneIndex(bone), f = splineFilter(points);
    this.filters[i] = f.identity ? null : f;
    if (this.curve && i === this.settings.bone) this.curve.set(f.points.slice(1, -1));
    this.refreshRows(this.rowsOf(i));
    this.requestRender();
    return f.points.map((p) => p.slice());
  }

  /** Rows where bone i has weight (whose E4 can change with i's curve). */
  rowsOf(i) {
    const b = this.b, rows = [];
    for (let r = 0; r < this.n; r++) if (this.W[r * b + i] > 0) rows.push(r);
    return Int32Array.from(rows);
  }

  splineValues(bone, xs) {
    const i = this.boneIndex(bone), f = this.filters[i] || splineFilter([]);
    return Array.from(xs, (x) => f(x));
  }

  /** Bake bone i's curve into E[:, i] (one command); the curve is then the identity. */
  applySpline(bone) {
    const i = this.boneIndex(bone), f = this.filters[i];
    if (!f) return false;
    const col = new Float64Array(this.n);
    for (let r = 0; r < this.n; r++) col[r] = f(this.E[r * this.b + i]);
    this.filters[i] = null;
    if (this.curve && i === this.settings.bone) this.curve.set([]);
    if (!this.setEndpointColumn(i, col, "apply the endpoint curve")) this.refreshRows(this.rowsOf(i));
    return true;
  }

  // ------------------------------------------------------------------ the panel
  buildPanel() {
    const $ = (id) => document.getElementById(id);
    const fill = (sel, items, labels) => {
      if (!sel) return;
      items.forEach((m, k) => {
        const o = document.createElement("option");
        o.value = m; o.textContent = labels ? labels[k] : m;
        sel.appendChild(o);
      });
    };
    fill($("color-mode"), COLOR_MODES, ["shaded", "bones", "endpoint weight (heat)", "bone weight (heat)"]);
    fill($("paint-mode"), PAINT_MODES, ["off", "bone weights", "endpoint weights"]);
    fill($("paint-op"), PAINT_OPS);
    fill($("paint-falloff"), FALLOFFS);
    fill($("endpoint-method"), this.endpointMethods());
    $("color-mode")?.addEventListener("change", () => this.setColorMode($("color-mode").value));
    $("paint-mode")?.addEventListener("change", () => this.setPaint({ mode: $("paint-mode").value }));
    $("paint-op")?.addEventListener("change", () => this.setPaint({ op: $("paint-op").value }));
    $("paint-falloff")?.addEventListener("change", () => this.setPaint({ falloff: $("paint-falloff").value }));
    const radius = $("paint-radius");
    if (radius) {
      radius.min = String(this.view.diag / 200); radius.max = String(this.view.diag / 2);
      radius.step = String(this.view.diag / 1000);
      radius.addEventListener("input", () => this.setPaint({ radius: Number(radius.value) }));
    }
    $("paint-strength")?.addEventListener("input", () => this.setPaint({ strength: Number($("paint-strength").value) }));
    $("paint-undo")?.addEventListener("click", () => this.undo());
    $("paint-redo")?.addEventListener("click", () => this.redo());
    this.history.events?.on("history", () => this.updateButtons());
    $("save-rig")?.addEventListener("click", () => this.uiCall(() => this.saveRigAsking(),
      (r) => (r ? `saved ${r.path}` : "not saved")));
    const progress = this.buildProgress($("endpoint-recompute"));
    $("endpoint-recompute")?.addEventListener("click", () => {
      const m = $("endpoint-method").value;
      progress.show(true);
      this.uiCall(() => this.recompute(this.settings.bone, m, {}, (st) => progress.set(st)),
                  () => `${this.names[this.settings.bone]}: endpoint weights by ${m}`, `computing (${m})...`)
        .finally(() => progress.show(false));
    });
    $("bone")?.addEventListener("change", () => this.selectBone(Number($("bone").value) || 0, false));
    this.buildLockAndMirror($("paint-mode"));
    const canvas = $("spline");
    if (canvas) {
      this.curve = new SplineEditor(canvas, (inner) => {
        try { this.setSpline(this.settings.bone, inner); } catch (err) { this.say(err.message, true); }
      });
    }
    // the canvas has no size while the box is closed: draw it when it opens
    $("weights-panel")?.addEventListener("toggle", () => this.curve && this.curve.draw());
    $("spline-apply")?.addEventListener("click", () => this.applySpline(this.settings.bone));
    $("spline-reset")?.addEventListener("click", () => this.setSpline(this.settings.bone, []));
    if ($("save-rig") && !(this.summary.save && this.summary.save.rig)) {
      $("save-rig").disabled = true;
      $("save-rig").title = "start stbs view with --save-as PATH to save the rig";
    }
    this.showSettings();
    this.updateButtons();
  }

  /** A progress bar and a cancel button for the endpoint recompute, after `button`. */
  buildProgress(button) {
    const bar = document.createElement("progress"), cancel = document.createElement("button");
    bar.id = "endpoint-progress";
    bar.max = 1;
    bar.value = 0;
    cancel.id = "endpoint-cancel";
    cancel.type = "button";
    cancel.textContent = "cancel";
    cancel.addEventListener("click", () => this.cancelRecompute().catch((err) => this.say(err.message, true)));
    const show = (on) => { bar.hidden = cancel.hidden = !on; button && (button.disabled = on); };
    show(false);
    if (button && button.parentNode) button.parentNode.insertBefore(cancel, button.nextSibling);
    if (button && button.parentNode) button.parentNode.insertBefore(bar, button.nextSibling);
    return {
      show,
      set: (st) => {
        if (st.total > 0) { bar.max = st.total; bar.value = st.done; } else bar.removeAttribute("value");
        bar.title = `${st.stage || st.state}: ${st.done ?? 0} of ${st.total ?? "?"}`;
      },
    };
  }

  /** The lock (selected bone) and X-mirror checkboxes, after the paint menu's row. */
  buildLockAndMirror(after) {
    const row = document.createElement("div");
    row.className = "row";
    row.id = "paint-locks";
    const box = (id, text, title) => {
      const label = document.createElement("label"), input = document.createElement("input");
      input.type = "checkbox";
      input.id = id;
      label.title = title;
      label.append(input, ` ${text}`);
      row.appendChild(label);
      return input;
    };
    const lock = box("paint-lock", "lock", "lock the selected bone's weights: painting other bones leaves them");
    const mirror = box("paint-mirror", "X-mirror", "each dab also paints the mirror bone on the mirror side (x = centre)");
    const list = document.createElement("span");
    list.id = "paint-locked";
    list.className = "muted";
    row.appendChild(list);
    lock.addEventListener("change", () => this.setLock(this.settings.bone, lock.checked));
    mirror.addEventListener("change", () => this.store.setMirror(mirror.checked));
    const anchor = after && after.closest ? after.closest("label") || after : null;
    if (anchor && anchor.parentNode) anchor.parentNode.insertBefore(row, anchor.nextSibling);
    else (document.getElementById("weights-panel") || document.body).appendChild(row);
  }

  async uiCall(f, done, busy) {
    if (busy) this.say(busy);
    try { const r = await f(); this.say(done(r)); } catch (err) { this.say(`stbs view: ${err.message}`, true); }
  }

  say(text, isError = false) {
    const el = document.getElementById("status");
    if (el) { el.textContent = text; el.classList.toggle("error", isError); }
  }

  showSettings() {
    const s = this.settings, $ = (id) => document.getElementById(id);
    if ($("paint-mode")) $("paint-mode").value = s.mode;
    if ($("paint-op")) $("paint-op").value = s.op;
    if ($("paint-falloff")) $("paint-falloff").value = s.falloff;
    if ($("paint-radius")) $("paint-radius").value = String(s.radius);
    if ($("paint-radius-value")) $("paint-radius-value").textContent = s.radius.toPrecision(3);
    if ($("paint-strength")) $("paint-strength").value = String(s.strength);
    if ($("paint-strength-value")) $("paint-strength-value").textContent = s.strength.toFixed(2);
    if ($("paint-lock")) $("paint-lock").checked = !!this.locked[s.bone];
    if ($("paint-mirror")) $("paint-mirror").checked = this.store.mirror;
    const locked = this.lockedBones();
    if ($("paint-locked")) $("paint-locked").textContent = locked.length ? `locked: ${locked.map((i) => this.names[i]).join(", ")}` : "";
    this.canvas.classList.toggle("painting", s.mode !== "off");
  }

  updateButtons() {
    const u = document.getElementById("paint-undo"), r = document.getElementById("paint-redo");
    if (u) u.disabled = !this.history.canUndo;
    if (r) r.disabled = !this.history.canRedo;
  }
}
