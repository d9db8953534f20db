// Weights on the page: colour modes (shaded, bones, endpoint), painting the selected
// bone's bone weights W or endpoint weights E with a brush, recomputing one bone's
// endpoint weights on the server, and the endpoint filter curve (spline.js).
//
// The page keeps the full W and E (n x b, row-major Float32Arrays). After each change
// the top-4 layout (I4, W4, E4: the four heaviest bones, heaviest first, ties by bone
// index, weights renormalised; as stbs.skinning.top_k) of the changed vertices is
// rebuilt and uploaded to the mesh and to the transform-feedback buffers, so the
// drawing and skinnedPositions() follow every dab. Every change (a stroke, a
// recompute, a baked curve) is one undo step that restores W and E bit for bit.

import * as THREE from "three";
import { SplineEditor, splineFilter } from "./spline.js";

export const COLOR_MODES = ["shaded", "bones", "endpoint"];
export const PAINT_MODES = ["off", "bone", "endpoint"];
export const PAINT_OPS = ["add", "subtract", "smooth"];
export const FALLOFFS = ["smooth", "linear", "constant"];
export const ENDPOINT_METHODS = ["projection", "idw", "heat", "bbw", "bbw-joints"];

const FALL = {
  smooth: (x) => { const t = 1 - x * x; return t * t; },
  linear: (x) => 1 - x,
  constant: () => 1,
};

const UNDO_LIMIT = 100;

function sameArray(a, b) {
  if (a.length !== b.length) return false;
  for (let k = 0; k < a.length; k++) if (a[k] !== b[k]) return false;
  return true;
}

function bad(what, expected, got) {
  return new Error(`${what}: expected ${expected}, got ${JSON.stringify(got)}`);
}

export class WeightEditor {
  /**
   * @param viewer  the page's Viewer, loaded, with arrays W and E (n x b float32)
   * @param api     fetch(path, options) with the token, throwing on an error answer
   */
  constructor(viewer, api) {
    const v = viewer;
    this.v = v;
    this.api = api;
    this.n = v.n;
    this.b = v.b;
    const nb = this.n * this.b;
    if (!v.arrays.W || v.arrays.W.length !== nb || !v.arrays.E || v.arrays.E.length !== nb) {
      throw new Error(`weights: expected W and E of ${this.n} x ${this.b} values from the server`);
    }
    this.W = Float32Array.from(v.arrays.W);
    this.E = Float32Array.from(v.arrays.E);
    this.parents = (v.summary.parents || []).map(Number);
    this.names = [];
    const names = v.summary.names || [];
    for (let i = 0; i < this.b; i++) this.names.push(names[i] != null ? String(names[i]) : String(i));
    this.rest = v.mesh.geometry.attributes.position.array;      // n x 3 (z = 0 in 2D)
    this.faces = v.arrays.F ? Uint32Array.from(v.arrays.F) : new Uint32Array(0);
    this.neighbours = this.adjacency();
    this.settings = { mode: "off", bone: 0, op: "add", radius: 0.08 * v.diag, strength: 0.25,
                      falloff: "smooth" };
    this.colorModeName = "shaded";
    this.filters = new Map();     // bone -> spline filter previewed (not yet in E)
    this.undoStack = [];
    this.redoStack = [];
    this.stroke = null;
    this.lastStroke = null;
    const geom = v.mesh.geometry;
    // the server's layout (from its float64 W) stands for every row still as loaded
    this.W0 = this.W.slice();
    this.serverW = this.W0;
    this.I4_0 = geom.attributes.stbsIndex.array.slice();
    this.W4_0 = geom.attributes.stbsWeight.array.slice();
    this.sel = new Float32Array(2 * this.n);       // per vertex: W and f(E) of the selected bone
    geom.setAttribute("stbsSel", new THREE.BufferAttribute(this.sel, 2));
    this.updateSelection();
    const canvas = v.renderer.domElement;
    // capture phase on window: runs before the canvas' own listeners (joint drags, orbit)
    window.addEventListener("pointerdown", (e) => this.onDown(e), { capture: true });
    window.addEventListener("pointermove", (e) => this.onMove(e), { capture: true });
    window.addEventListener("pointerup", (e) => this.onUp(e), { capture: true });
    window.addEventListener("pointercancel", (e) => this.onUp(e), { capture: true });
    window.addEventListener("keydown", (e) => this.onKey(e), { capture: true });
    this.canvas = canvas;
    canvas.addEventListener("pointerleave", () => this.hideRing());
    this.ring = this.makeRing();
    v.scene.add(this.ring);
    this.buildPanel();
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
    this.v.render();
  }

  hideRing() {
    if (!this.ring.visible || this.stroke) return;
    this.ring.visible = false;
    this.v.render();
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

  // ------------------------------------------------------------------ mesh helpers
  adjacency() {
    const n = this.n, F = this.faces, sets = Array.from({ length: n }, () => new Set());
    for (let f = 0; f < F.length; f += 3) {
      const a = F[f], b = F[f + 1], c = F[f + 2];
      sets[a].add(b); sets[a].add(c); sets[b].add(a); sets[b].add(c); sets[c].add(a); sets[c].add(b);
    }
    return sets.map((s) => Int32Array.from(s));
  }

  boneIndex(key) {
    if (typeof key === "number" && Number.isInteger(key) && key >= 0 && key < this.b) return key;
    if (typeof key === "string") {
      const k = this.names.indexOf(key);
      if (k >= 0) return k;
      if (/^\d+$/.test(key) && Number(key) < this.b) return Number(key);
    }
    throw bad("bone", `an index 0..${this.b - 1} or a bone name`, key);
  }

  // ------------------------------------------------------------------ GPU layout
  /** f(E) of vertex r for bone j: the previewed filter of j applied. */
  endOf(r, j) {
    const e = this.E[r * this.b + j], f = this.filters.get(j);
    return f ? f(e) : e;
  }

  /**
   * Rebuild the top-4 layout of rows (all when null) and upload it. A row whose W is
   * as loaded keeps the server's layout (made from the rig's float64 W: near-ties
   * among the heaviest bones fall as the library's); E4 is always f(E) of its slots.
   */
  updateRows(rows) {
    const geom = this.v.mesh.geometry, b = this.b, W = this.W;
    const I4 = geom.attributes.stbsIndex.array, W4 = geom.attributes.stbsWeight.array;
    const E4 = geom.attributes.stbsEnd.array;
    const all = rows == null, count = all ? this.n : rows.length;
    const top = [0, 0, 0, 0], tw = [0, 0, 0, 0];
    for (let q = 0; q < count; q++) {
      const r = all ? q : rows[q];
      let asLoaded = true;
      for (let j = 0; j < b && asLoaded; j++) asLoaded = W[r * b + j] === this.W0[r * b + j];
      if (asLoaded) {
        for (let c = 0; c < 4; c++) {
          const o = 4 * r + c;
          I4[o] = this.I4_0[o]; W4[o] = this.W4_0[o];
          E4[o] = W4[o] > 0 ? Math.min(1, Math.max(0, this.endOf(r, I4[o]))) : 0;
        }
        continue;
      }
      let k = 0;
      for (let j = 0; j < b; j++) {        // insertion into the 4 heaviest, earlier bone first on ties
        const w = W[r * b + j];
        if (!(w > 0)) continue;
        if (k === 4 && w <= tw[3]) continue;
        let p = k < 4 ? k++ : 3;
        while (p > 0 && tw[p - 1] < w) { tw[p] = tw[p - 1]; top[p] = top[p - 1]; p--; }
        tw[p] = w; top[p] = j;
      }
      let s = 0;
      for (let c = 0; c < k; c++) s += tw[c];
      for (let c = 0; c < 4; c++) {
        const o = 4 * r + c;
        if (c < k) {
          I4[o] = top[c]; W4[o] = tw[c] / s; E4[o] = Math.min(1, Math.max(0, this.endOf(r, top[c])));
        } else {
          I4[o] = 0; W4[o] = 0; E4[o] = 0;
        }
      }
    }
    for (const name of ["stbsIndex", "stbsWeight", "stbsEnd"]) {
      geom.attributes[name].needsUpdate = true;
      this.v.feedback.setAttribute(name, geom.attributes[name].array);
    }
    this.v.renderer.resetState();
    this.updateSelection(rows);
  }

  /** The selected bone's W and f(E) per vertex, for the endpoint colour mode. */
  updateSelection(rows) {
    const i = this.settings.bone, b = this.b, all = rows == null;
    const count = all ? this.n : rows.length;
    for (let q = 0; q < count; q++) {
      const r = all ? q : rows[q];
      this.sel[2 * r] = this.W[r * b + i];
      this.sel[2 * r + 1] = this.endOf(r, i);
    }
    this.v.mesh.geometry.attributes.stbsSel.needsUpdate = true;
    this.v.render();
  }

  // ------------------------------------------------------------------ colour modes
  setColorMode(name) {
    const k = COLOR_MODES.indexOf(name);
    if (k < 0) throw bad("colour mode", `one of ${COLOR_MODES.join(", ")}`, name);
    this.colorModeName = name;
    this.v.material.uniforms.uColorMode.value = k;
    const sel = document.getElementById("color-mode");
    if (sel) sel.value = name;
    this.v.render();
    return name;
  }

  colorMode() { return this.colorModeName; }

  // ------------------------------------------------------------------ settings
  setPaint(opts = {}) {
    if (opts === null || typeof opts !== "object" || Array.isArray(opts)) {
      throw bad("setPaint", "an object {mode, bone, op, radius, strength, falloff}", opts);
    }
    const keys = ["mode", "bone", "op", "radius", "strength", "falloff"];
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
    const boneChanged = s.bone !== this.settings.bone;
    this.settings = s;
    if (s.mode === "off") this.hideRing();
    else if (this.ring.visible) { this.ring.scale.setScalar(s.radius); this.v.render(); }
    if (boneChanged) this.selectBone(s.bone, true);
    this.showSettings();
    return this.paintSettings();
  }

  paintSettings() {
    return Object.assign({}, this.settings, { boneName: this.names[this.settings.bone] });
  }

  /** The selected bone (shared with the pose panel's bone list). */
  selectBone(i, fromApi) {
    this.settings.bone = i;
    const sel = document.getElementById("bone");
    if (fromApi && sel && sel.value !== String(i)) {
      sel.value = String(i);
      sel.dispatchEvent(new Event("change"));
    }
    this.updateSelection();
    if (this.curve) this.curve.set(this.splinePointsOf(i).slice(1, -1));
  }

  // ------------------------------------------------------------------ picking
  /** Where the pointer's ray meets the posed surface: {face, u, v, t, rest, posed} or null. */
  pick(clientX, clientY) {
    const rect = this.v.viewRect ? this.v.viewRect() : this.canvas.getBoundingClientRect();
    const ndc = new THREE.Vector2(2 * (clientX - rect.left) / rect.width - 1,
                                  1 - 2 * (clientY - rect.top) / rect.height);
    if (Math.abs(ndc.x) > 1 || Math.abs(ndc.y) > 1) return null;     // outside the (left) view
    const ray = new THREE.Raycaster();
    ray.setFromCamera(ndc, this.v.camera);
    const o = ray.ray.origin, d = ray.ray.direction;
    const U = this.v.skinned()[0], F = this.faces;
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
    if (this.settings.mode === "off" || e.target !== this.canvas || e.button !== 0 || this.stroke) return;
    const hit = this.pick(e.clientX, e.clientY);
    if (!hit) return;                          // off the mesh: the orbit controls have it
    e.stopImmediatePropagation();
    e.preventDefault();
    this.v.controls.enabled = false;
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
    this.v.controls.enabled = true;
    this.endStroke();
  }

  beginStroke(id) {
    this.stroke = { id, saved: new Map(), dabs: [], last: null,
                    mode: this.settings.mode, bone: this.settings.bone };
  }

  /** Keep a vertex's rows as they were before this step. */
  save(r) {
    const saved = this.stroke.saved, b = this.b;
    if (saved.has(r)) return;
    saved.set(r, [this.W.slice(r * b, (r + 1) * b), this.E.slice(r * b, (r + 1) * b)]);
  }

  /** One dab of the brush at a surface point. */
  dab(hit, x, y) {
    const s = this.settings, st = this.stroke, b = this.b, i = st.bone, n = this.n;
    const R = this.rest, c = hit.rest, r2 = s.radius * s.radius, fall = FALL[s.falloff];
    const X = st.mode === "bone" ? this.W : this.E;
    const inside = [], amount = [];
    for (let v = 0; v < n; v++) {
      const dx = R[3 * v] - c[0], dy = R[3 * v + 1] - c[1], dz = R[3 * v + 2] - c[2];
      const d2 = dx * dx + dy * dy + dz * dz;
      if (d2 >= r2) continue;
      const a = s.strength * fall(Math.sqrt(d2) / s.radius);
      if (a > 0) { inside.push(v); amount.push(a); }
    }
    // smoothing averages the neighbours' values from before this dab
    const before = s.op === "smooth" ? inside.map((v) => {
      const nb = this.neighbours[v];
      if (!nb.length) return X[v * b + i];
      let m = 0;
      for (const u of nb) m += X[u * b + i];
      return m / nb.length;
    }) : null;
    const changed = [];
    inside.forEach((v, k) => {
      const old = X[v * b + i], a = amount[k];
      let t = s.op === "add" ? old + a : s.op === "subtract" ? old - a : old + a * (before[k] - old);
      t = Math.min(1, Math.max(0, t));
      if (t === old) return;
      this.save(v);
      if (st.mode === "bone") { if (this.setBoneWeight(v, i, t)) changed.push(v); } else {
        this.E[v * b + i] = t;
        changed.push(v);
      }
    });
    st.dabs.push({ rest: hit.rest.slice(), posed: hit.posed.slice(), x, y, radius: s.radius });
    st.last = hit.rest;
    if (changed.length) this.updateRows(changed);
    this.showRing(hit);
  }

  /**
   * W[v, i] = t with the row summing to 1: the other bones are scaled by
   * (1 - t) / (their sum). Where the painted bone had all the weight, 1 - t goes to
   * the other bones in the proportions of the vertex's mesh neighbours' weights; when
   * those have none either, to the bone's parent, else its first child, else the
   * next bone. A rig of one bone keeps its weights (1 everywhere). Returns whether
   * the row changed.
   */
  setBoneWeight(v, i, t) {
    const b = this.b, W = this.W, o = v * b;
    if (b === 1) return false;
    const row = new Float64Array(b);
    let others = 0;
    for (let j = 0; j < b; j++) { row[j] = W[o + j]; if (j !== i) others += row[j]; }
    row[i] = t;
    if (others > 0) {
      const k = (1 - t) / others;
      for (let j = 0; j < b; j++) if (j !== i) row[j] *= k;
    } else if (t < 1) {
      const share = new Float64Array(b);
      let total = 0;
      for (const u of this.neighbours[v]) {
        for (let j = 0; j < b; j++) if (j !== i) { share[j] += W[u * b + j]; total += W[u * b + j]; }
      }
      if (!(total > 0)) {
        let j = this.parents[i];
        if (!(j >= 0)) j = this.parents.indexOf(i);
        if (!(j >= 0)) j = (i + 1) % b;
        share[j] = 1; total = 1;
      }
      for (let j = 0; j < b; j++) if (j !== i) row[j] = (1 - t) * share[j] / total;
    }
    let sum = 0;
    for (let j = 0; j < b; j++) sum += row[j];
    let same = true;
    for (let j = 0; j < b; j++) {
      const w = Math.fround(row[j] / sum);
      if (w !== W[o + j]) same = false;
      W[o + j] = w;
    }
    return !same;
  }

  endStroke() {
    const st = this.stroke;
    this.stroke = null;
    this.lastStroke = { mode: st.mode, bone: st.bone, dabs: st.dabs, vertices: 0 };
    const entry = this.entryFromSaved(st.saved, st.mode === "bone" ? "paint bone weights" : "paint endpoint weights");
    if (entry) { this.push(entry); this.lastStroke.vertices = entry.rows.length; }
  }

  /** An undo step from the rows saved before a change (only rows that changed). */
  entryFromSaved(saved, label) {
    const b = this.b, rows = [];
    for (const [r, [w0, e0]] of saved) {
      for (let j = 0; j < b; j++) {
        if (w0[j] !== this.W[r * b + j] || e0[j] !== this.E[r * b + j]) { rows.push(r); break; }
      }
    }
    if (!rows.length) return null;
    rows.sort((p, q) => p - q);
    const m = rows.length, e = { label, rows: Int32Array.from(rows),
      Wb: new Float32Array(m * b), Eb: new Float32Array(m * b),
      Wa: new Float32Array(m * b), Ea: new Float32Array(m * b) };
    rows.forEach((r, k) => {
      const [w0, e0] = saved.get(r);
      e.Wb.set(w0, k * b); e.Eb.set(e0, k * b);
      e.Wa.set(this.W.subarray(r * b, (r + 1) * b), k * b);
      e.Ea.set(this.E.subarray(r * b, (r + 1) * b), k * b);
    });
    return e;
  }

  push(entry) {
    this.undoStack.push(entry);
    if (this.undoStack.length > UNDO_LIMIT) this.undoStack.shift();
    this.redoStack.length = 0;
    this.updateButtons();
  }

  restore(entry, which) {
    const b = this.b, Wx = which === "before" ? entry.Wb : entry.Wa, Ex = which === "before" ? entry.Eb : entry.Ea;
    entry.rows.forEach((r, k) => {
      this.W.set(Wx.subarray(k * b, (k + 1) * b), r * b);
      this.E.set(Ex.subarray(k * b, (k + 1) * b), r * b);
    });
    this.updateRows(entry.rows);
  }

  undo() {
    if (this.stroke || !this.undoStack.length) return false;
    const e = this.undoStack.pop();
    this.restore(e, "before");
    this.redoStack.push(e);
    this.updateButtons();
    return true;
  }

  redo() {
    if (this.stroke || !this.redoStack.length) return false;
    const e = this.redoStack.pop();
    this.restore(e, "after");
    this.undoStack.push(e);
    this.updateButtons();
    return true;
  }

  onKey(e) {
    if (this.settings.mode === "off") return;
    if (!(e.ctrlKey || e.metaKey) || e.key.toLowerCase() !== "z") return;
    const t = e.target;
    if (t && (t.tagName === "INPUT" || t.tagName === "SELECT") && t.type !== "range") return;
    e.preventDefault();
    e.stopImmediatePropagation();       // painting's undo, not the pose's
    if (e.shiftKey) this.redo(); else this.undo();
  }

  /** Replace column E[:, i] (one undo step); returns whether anything changed. */
  setEndpointColumn(i, col, label) {
    const b = this.b, saved = new Map();
    for (let r = 0; r < this.n; r++) {
      const e = Math.fround(col[r]);
      if (e === this.E[r * b + i]) continue;
      saved.set(r, [this.W.slice(r * b, (r + 1) * b), this.E.slice(r * b, (r + 1) * b)]);
      this.E[r * b + i] = e;
    }
    const entry = this.entryFromSaved(saved, label);
    if (!entry) return false;
    this.push(entry);
    this.updateRows(entry.rows);
    return true;
  }

  weights() {
    return { W: this.W.slice(), E: this.E.slice() };
  }

  // ------------------------------------------------------------------ the server
  async recompute(bone, method, options = {}) {
    const i = this.boneIndex(bone);
    if (!ENDPOINT_METHODS.includes(method)) throw bad("endpoint method", `one of ${ENDPOINT_METHODS.join(", ")}`, method);
    if (options === null || typeof options !== "object" || Array.isArray(options)) {
      throw bad("endpoint options", "an object", options);
    }
    const body = Object.assign({}, options, { bone: i, method });
    if (!sameArray(this.W, this.serverW)) {     // painted since loaded or saved: send ours
      const W = [], b = this.b;
      for (let r = 0; r < this.n; r++) W.push(Array.from(this.W.subarray(r * b, (r + 1) * b)));
      body.W = W;
    }
    const r = await this.api("/api/endpoint-weights", {
      method: "POST", body: JSON.stringify(body),
      headers: { "Content-Type": "application/json", Accept: "application/octet-stream" } });
    const col = new Float32Array(await r.arrayBuffer());
    if (col.length !== this.n) throw new Error(`/api/endpoint-weights: expected ${this.n} values, got ${col.length}`);
    this.setEndpointColumn(i, col, `recompute endpoint weights (${method})`);
    return col;
  }

  async saveRig() {
    const nb = this.n * this.b, body = new Float32Array(2 * nb);
    body.set(this.W, 0);
    body.set(this.E, nb);
    const sent = this.W.slice();
    const r = await this.api("/api/save-rig", {
      method: "POST", body: body.buffer,
      headers: { "Content-Type": "application/octet-stream", "X-Stbs-Arrays": "W,E", "X-Stbs-Dtype": "float32" } });
    this.serverW = sent;          // the rig served now has these weights
    return r.json();
  }

  // ------------------------------------------------------------------ the curve
  splinePointsOf(i) {
    const f = this.filters.get(i);
    return f ? f.points.map((p) => p.slice()) : [[0, 0], [1, 1]];
  }

  /** Preview a curve for bone i (its inner points; ends optional): the shader uses f(E). */
  setSpline(bone, points) {
    const i = this.boneIndex(bone), f = splineFilter(points);
    if (f.identity) this.filters.delete(i); else this.filters.set(i, f);
    if (this.curve && i === this.settings.bone) this.curve.set(f.points.slice(1, -1));
    this.updateRows(this.rowsOf(i));
    return f.points.map((p) => p.slice());
  }

  /** Rows where bone i is among the top 4 (whose E4 can change with i's curve). */
  rowsOf(i) {
    const b = this.b, rows = [];
    for (let r = 0; r < this.n; r++) if (this.W[r * b + i] > 0) rows.push(r);
    return rows;
  }

  splineValues(bone, xs) {
    const i = this.boneIndex(bone), f = this.filters.get(i) || splineFilter([]);
    return Array.from(xs, (x) => f(x));
  }

  /** Bake bone i's curve into E[:, i] (one undo step); the curve is then the identity. */
  applySpline(bone) {
    const i = this.boneIndex(bone), f = this.filters.get(i);
    if (!f) return false;
    const col = new Float64Array(this.n);
    for (let r = 0; r < this.n; r++) col[r] = f(this.E[r * this.b + i]);
    this.filters.delete(i);
    if (this.curve && i === this.settings.bone) this.curve.set([]);
    if (!this.setEndpointColumn(i, col, "apply the endpoint curve")) this.updateRows(this.rowsOf(i));
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
    fill($("color-mode"), COLOR_MODES);
    fill($("paint-mode"), PAINT_MODES, ["off", "bone weights", "endpoint weights"]);
    fill($("paint-op"), PAINT_OPS);
    fill($("paint-falloff"), FALLOFFS);
    fill($("endpoint-method"), ENDPOINT_METHODS);
    $("color-mode")?.addEventListener("change", () => this.setColorMode($("color-mode").value));
    $("paint-mode")?.addEventListener("change", () => this.setPaint({ mode: $("paint-mode").value }));
    $("paint-op")?.addEventListener("change", () => this.setPaint({ op: $("paint-op").value }));
    $("paint-falloff")?.addEventListener("change", () => this.setPaint({ falloff: $("paint-falloff").value }));
    const radius = $("paint-radius");
    if (radius) {
      radius.min = String(this.v.diag / 200); radius.max = String(this.v.diag / 2);
      radius.step = String(this.v.diag / 1000);
      radius.addEventListener("input", () => this.setPaint({ radius: Number(radius.value) }));
    }
    $("paint-strength")?.addEventListener("input", () => this.setPaint({ strength: Number($("paint-strength").value) }));
    $("paint-undo")?.addEventListener("click", () => this.undo());
    $("paint-redo")?.addEventListener("click", () => this.redo());
    $("save-rig")?.addEventListener("click", () => this.uiCall(() => this.saveRig(), (r) => `saved ${r.path}`));
    $("endpoint-recompute")?.addEventListener("click", () => {
      const m = $("endpoint-method").value;
      this.uiCall(() => this.recompute(this.settings.bone, m),
                  () => `${this.names[this.settings.bone]}: endpoint weights by ${m}`, `computing (${m})...`);
    });
    $("bone")?.addEventListener("change", () => this.selectBone(Number($("bone").value) || 0, false));
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
    if ($("save-rig") && !(this.v.summary.save && this.v.summary.save.rig)) {
      $("save-rig").disabled = true;
      $("save-rig").title = "start stbs view with --save-as PATH to save the rig";
    }
    this.showSettings();
    this.updateButtons();
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
    this.canvas.classList.toggle("painting", s.mode !== "off");
  }

  updateButtons() {
    const u = document.getElementById("paint-undo"), r = document.getElementById("paint-redo");
    if (u) u.disabled = !this.undoStack.length;
    if (r) r.disabled = !this.redoStack.length;
  }
}
