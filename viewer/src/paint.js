// Weight paint on the page: the editor. It holds the painter's settings and locks, turns
// the pointer into strokes of dabs, and makes every stroke, recompute and baked curve one
// command on the page's History. The rest is in modules of their own:
//   paintsettings.js  the modes and setPaint's checks (pure)
//   pick.js           the ray cast that places the brush on the posed surface (pure)
//   paintdab.js       one dab on W or E: the brush, locks, X-mirror (no DOM, no WebGL)
//   paintgpu.js       the layout buffers, uploads of the changed rows, the brush's ring
//   recompute.js      the server's endpoint jobs and saving the rig (api.js)
//   paintcurve.js     the endpoint curves previewed, and baked into E
//   paintpanel.js     the weights panel
//   paintpointer.js   the pointer: presses, moves and releases as strokes, the hover ring
// The store holds the full W and E (n x b Float32Arrays, row-major), edited in place here
// and by paintdab.js; each change is announced with store.weightsChanged(rows).

import * as THREE from "three";
import { RowLog, restoreRows } from "./weightrows.js";
import { api as defaultApi } from "./api.js";
import { COLOR_MODES, FALLOFFS, PAINT_MODES, PAINT_OPS, RADIUS_STEP, bad, boneIndex, mergeSettings,
         scaledRadius } from "./paintsettings.js";
import { castRay } from "./pick.js";
import { DabPainter } from "./paintdab.js";
import { PaintGPU } from "./paintgpu.js";
import { EndpointJobs } from "./recompute.js";
import { PaintPanel } from "./paintpanel.js";
import { PaintPointer } from "./paintpointer.js";
import { EndpointCurves, rowsWith } from "./paintcurve.js";

export { COLOR_MODES, FALLOFFS, PAINT_MODES, PAINT_OPS, RADIUS_STEP };

export class WeightEditor {
  /**
   * @param ctx  the page's context {store, events, history, keys, view} (or an object
   *             holding it as .ctx), with store.rig (its summary the /api/rig answer),
   *             store.W and store.E loaded
   * @param api  fetch(path, options) with the token (unused: the requests are api.js's)
   */
  constructor(ctx, api = defaultApi) {
    ctx = ctx.ctx || ctx;
    const { store, events, history, keys, view } = ctx;
    this.store = store; this.history = history; this.view = view;
    const rig = store.rig;
    this.n = rig.n;
    this.b = rig.b;
    const nb = this.n * this.b;
    if (!(store.W instanceof Float32Array) || store.W.length !== nb || !(store.E instanceof Float32Array) || store.E.length !== nb) {
      throw new Error(`weights: expected W and E of ${this.n} x ${this.b} values from the server`);
    }
    this.W = store.W; this.E = store.E;
    this.names = rig.names.slice();
    this.rest = view.mesh.geometry.attributes.position.array;     // n x 3 (z = 0 in 2D)
    this.faces = rig.F ? Uint32Array.from(rig.F) : new Uint32Array(0);
    this.log = new RowLog(this.n, this.b);
    this.locked = new Uint8Array(this.b);
    this.curves = new EndpointCurves(this.b);        // the endpoint curves previewed (not yet in E)
    this.settings = { mode: "off", bone: store.selection.bone ?? 0, op: "add", radius: 0.08 * view.diag,
                      strength: 0.25, falloff: "smooth" };
    this.colorModeName = "shaded";
    this.stroke = null;
    this.lastStroke = null;
    this.posedCache = null;
    this.weightsVersion = 0;
    this.dabs = new DabPainter(ctx, { rest: this.rest, faces: this.faces }, this.log, this.locked);
    this.jobs = new EndpointJobs(ctx);
    this.gpu = new PaintGPU(view, { n: this.n, b: this.b, W: this.W, E: this.E, filters: this.curves.filters,
                                    bone: this.settings.bone });
    this.panel = new PaintPanel(ctx, this);
    this.pointer = new PaintPointer(ctx, this);
    events.on("pose", () => { this.posedCache = null; });
    events.on("select", ({ bone }) => { if (bone !== null && bone !== this.settings.bone) this.selectBone(bone, false); });
    events.on("mirror", () => this.panel.showSettings());
    keys.register({ key: "[", label: "brush smaller", run: () => this.resizeBrush(1 / RADIUS_STEP) });
    keys.register({ key: "]", label: "brush larger", run: () => this.resizeBrush(RADIUS_STEP) });
  }

  /** Rebuild and upload the rows (sorted; null: all) of the drawing; tell the store. */
  refreshRows(rows, count = rows ? rows.length : this.n) {
    this.gpu.refreshRows(rows, count, this.settings.bone);
    this.store.weightsChanged(rows === null ? null : rows.slice(0, count));
  }

  requestRender() { this.gpu.requestRender(); }

  boneIndex(key) { return boneIndex(key, this.names); }

  // ------------------------------------------------------------------ settings
  setColorMode(name) {
    const k = COLOR_MODES.indexOf(name);
    if (k < 0) throw bad("colour mode", `one of ${COLOR_MODES.join(", ")}`, name);
    this.colorModeName = name;
    this.view.setUniform("uColorMode", k);
    this.panel.showColorMode(name);
    this.view.render();
    return name;
  }

  colorMode() { return this.colorModeName; }

  /** Change some of {mode, bone, op, radius, strength, falloff, mirror}; returns paintSettings(). */
  setPaint(opts = {}) {
    const s = mergeSettings(this.settings, opts, this.names);
    const boneChanged = s.bone !== this.settings.bone;
    this.settings = s;
    if ("mirror" in opts) this.store.setMirror(opts.mirror);
    this.store.setBrush({ radius: s.radius, strength: s.strength, op: s.op, falloff: s.falloff, target: s.mode });
    this.store.setMode(s.mode === "off" ? "pose" : "paint");
    if (s.mode === "off") this.hideRing();
    else this.gpu.resizeRing(s.radius);
    if (boneChanged) this.selectBone(s.bone, true);
    this.panel.showSettings();
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
    if (fromApi) this.panel.showBone(i);
    this.gpu.showBone(i);
    this.panel.showCurve(this.splinePointsOf(i).slice(1, -1));
    this.panel.showSettings();
  }

  resizeBrush(k) {
    this.setPaint({ radius: scaledRadius(this.settings.radius, k, this.view.diag) });
  }

  /** Lock (true) or unlock bone weights: painting never changes a locked bone's weight. */
  setLock(bone, on) {
    const i = this.boneIndex(bone);
    if (typeof on !== "boolean") throw bad("lock", "true or false", on);
    this.locked[i] = on ? 1 : 0;
    this.panel.showSettings();
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
    return castRay(ray.ray.origin, ray.ray.direction, this.posed(), this.faces, this.rest);
  }

  // ------------------------------------------------------------------ strokes
  /** The brush's ring at a hit, of the brush's radius. */
  showRing(hit) { this.gpu.showRing(hit, this.settings.radius); }

  /** The ring goes, except during a stroke. */
  hideRing() { if (!this.stroke) this.gpu.hideRing(); }

  beginStroke(id) {
    this.stroke = { id, dabs: [], last: null, mode: this.settings.mode, bone: this.settings.bone,
                    mirror: this.store.mirror };
  }

  /** One dab of the brush at a surface point; returns the milliseconds it took. */
  dab(hit, x, y) {
    const t0 = performance.now();
    const s = this.settings, st = this.stroke;
    const { rows, count, covered } = this.dabs.dab(hit.rest, st.mode, st.bone, s, st.mirror);
    if (count) this.refreshRows(rows, count);
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

  // ------------------------------------------------------------------ History
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

  weights() { return { W: this.W.slice(), E: this.E.slice() }; }

  // ------------------------------------------------------------------ the server
  /** The endpoint methods this rig's mesh can compute (the server's list). */
  endpointMethods() { return this.jobs.methods(); }

  /**
   * Recompute bone's endpoint weights on the server as a job (recompute.js), then
   * replace column E[:, bone] (one command). `onProgress({stage, done, total})` is called
   * as the job reports; cancelRecompute() stops it. Resolves to the column
   * (Float32Array); rejects when the job fails or is cancelled.
   */
  async recompute(bone, method, options = {}, onProgress = null) {
    const i = this.boneIndex(bone);
    const onColumn = (col) => this.setEndpointColumn(i, col, `recompute endpoint weights (${method})`);
    return this.jobs.run(i, method, options, { onProgress, onColumn });
  }

  /** Cancel the running recompute; resolves to whether one was running. */
  cancelRecompute() { return this.jobs.cancel(); }

  /** POST /api/save-rig with the page's W and E; rejects with the server's 409 where the
   * file exists and `overwrite` is false; resolves to its answer. */
  saveRig(overwrite = false) { return this.jobs.save(overwrite); }

  /** The save button: save; where the file exists, ask before writing over it. */
  saveRigAsking() { return this.panel.saveAsking(); }

  // ------------------------------------------------------------------ the curve
  splinePointsOf(i) { return this.curves.points(i); }

  /** Preview a curve for bone i (its inner points; ends optional): the shader uses f(E). */
  setSpline(bone, points) {
    const i = this.boneIndex(bone), f = this.curves.set(i, points);
    if (i === this.settings.bone) this.panel.showCurve(f.points.slice(1, -1));
    this.refreshRows(rowsWith(this.W, this.n, this.b, i));
    this.requestRender();
    return f.points.map((p) => p.slice());
  }

  splineValues(bone, xs) { return this.curves.values(this.boneIndex(bone), xs); }

  /** Bake bone i's curve into E[:, i] (one command); the curve is then the identity. */
  applySpline(bone) {
    const i = this.boneIndex(bone), col = this.curves.bake(i, this.E, this.n, this.b);
    if (!col) return false;
    if (i === this.settings.bone) this.panel.showCurve([]);
    if (!this.setEndpointColumn(i, col, "apply the endpoint curve")) this.refreshRows(rowsWith(this.W, this.n, this.b, i));
    return true;
  }
}
