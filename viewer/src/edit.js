// Pose editing on the page: dragging joints (the joints form of a pose), per-bone
// twist and stretch sliders (the forward-kinematics form), undo and redo.

import * as THREE from "three";

const PICK_PX = 14;     // a joint is picked within this many CSS pixels of the pointer
const DEG = 180 / Math.PI;

export class PoseEditor {
  constructor(viewer) {
    this.v = viewer;
    this.undoStack = [];
    this.redoStack = [];
    this.drag = null;
    this.sliders = { twist: {}, stretch: {} };    // bone name -> end twist (deg), stretch
    this.names = [];
    const names = viewer.summary.names || [];
    for (let i = 0; i < viewer.b; i++) this.names.push(names[i] != null ? String(names[i]) : String(i));
    const canvas = viewer.renderer.domElement;
    // capture phase on the canvas: runs before OrbitControls' own listener
    canvas.addEventListener("pointerdown", (e) => this.onDown(e), { capture: true });
    canvas.addEventListener("pointermove", (e) => this.onMove(e), { capture: true });
    canvas.addEventListener("pointerup", (e) => this.onUp(e), { capture: true });
    canvas.addEventListener("pointercancel", (e) => this.onUp(e), { capture: true });
    window.addEventListener("keydown", (e) => this.onKey(e));
    this.buildPanel();
  }

  // ------------------------------------------------------------------ undo / redo
  /** Remember the pose before an edit (the pose object that made it). */
  remember() {
    this.undoStack.push(this.v.lastSent);
    if (this.undoStack.length > 200) this.undoStack.shift();
    this.redoStack.length = 0;
    this.updateButtons();
  }

  undo() { return this.step(this.undoStack, this.redoStack); }

  redo() { return this.step(this.redoStack, this.undoStack); }

  /** Pop a pose from one stack, push the current one on the other, show it. */
  step(from, to) {
    const prev = this.op || Promise.resolve();
    this.op = prev.then(async () => {
      await (this.v.sending || null);
      if (!from.length) return null;
      const pose = from.pop();
      to.push(this.v.lastSent);
      await this.v.send(pose);
      this.updateButtons();
      return this.v.getPose();
    });
    const mine = this.op;
    mine.finally(() => { if (this.op === mine) this.op = null; }).catch(() => {});
    return mine;
  }

  onKey(e) {
    if (!(e.ctrlKey || e.metaKey) || e.key.toLowerCase() !== "z") return;
    const t = e.target;
    if (t && (t.tagName === "INPUT" || t.tagName === "SELECT") && t.type !== "range") return;
    e.preventDefault();
    (e.shiftKey ? this.redo() : this.undo()).catch(() => {});
  }

  updateButtons() {
    const u = document.getElementById("undo"), r = document.getElementById("redo");
    if (u) u.disabled = !this.undoStack.length;
    if (r) r.disabled = !this.redoStack.length;
  }

  // ------------------------------------------------------------------ dragging joints
  pointer(e) {
    const rect = this.v.renderer.domElement.getBoundingClientRect();
    return { x: e.clientX, y: e.clientY,
             ndc: new THREE.Vector2(2 * (e.clientX - rect.left) / rect.width - 1,
                                    1 - 2 * (e.clientY - rect.top) / rect.height) };
  }

  /** Where the pointer's ray meets the drag plane, or null. */
  onPlane(ndc) {
    const ray = new THREE.Raycaster();
    ray.setFromCamera(ndc, this.v.camera);
    const hit = new THREE.Vector3();
    return ray.ray.intersectPlane(this.drag.plane, hit) ? hit : null;
  }

  onDown(e) {
    if (e.button !== 0 || this.drag) return;
    const p = this.pointer(e), screen = this.v.jointScreenPositions();
    let best = -1, bestD = PICK_PX;
    screen.forEach(([x, y], k) => {
      const d = Math.hypot(x - p.x, y - p.y);
      if (d <= bestD) { best = k; bestD = d; }
    });
    if (best < 0) return;                 // not on a joint: the orbit controls have it
    e.stopImmediatePropagation();
    e.preventDefault();
    const J = this.v.posedJoints();
    const start = new THREE.Vector3(J[3 * best], J[3 * best + 1], J[3 * best + 2]);
    const normal = this.v.camera.getWorldDirection(new THREE.Vector3());
    this.drag = { joint: best, joints: J, start, id: e.pointerId, moved: false,
                  plane: new THREE.Plane().setFromNormalAndCoplanarPoint(normal, start) };
    this.drag.grab = this.onPlane(p.ndc) || start.clone();
    this.v.controls.enabled = false;
    try { this.v.renderer.domElement.setPointerCapture(e.pointerId); } catch (_) { /* synthetic */ }
  }

  onMove(e) {
    if (!this.drag || e.pointerId !== this.drag.id) return;
    e.stopImmediatePropagation();
    const hit = this.onPlane(this.pointer(e).ndc);
    if (!hit) return;
    if (!this.drag.moved) { this.remember(); this.drag.moved = true; }
    const at = this.drag.start.clone().add(hit.sub(this.drag.grab));
    this.v.send(this.jointsPose(this.drag.joints, this.drag.joint, at));
  }

  onUp(e) {
    if (!this.drag || e.pointerId !== this.drag.id) return;
    e.stopImmediatePropagation();
    this.drag = null;
    this.v.controls.enabled = true;
    try { this.v.renderer.domElement.releasePointerCapture(e.pointerId); } catch (_) { /* synthetic */ }
  }

  /** The joints-form pose: the posed joints with joint k at `at`, the current twists. */
  jointsPose(J, k, at) {
    const dim = this.v.dim, joints = [];
    for (let j = 0; j < J.length / 3; j++) {
      const q = j === k ? [at.x, at.y, at.z] : [J[3 * j], J[3 * j + 1], J[3 * j + 2]];
      joints.push(q.slice(0, dim));
    }
    const pose = { joints };
    if (dim === 3) {
      const tw = this.v.poseArrays.twist, twist = {};
      for (let i = 0; i < tw.length; i++) {
        if (tw[i][0] !== 0 || tw[i][1] !== 0) twist[String(i)] = [tw[i][0] * DEG, tw[i][1] * DEG];
      }
      if (Object.keys(twist).length) pose.twist = twist;
    }
    return pose;
  }

  // ------------------------------------------------------------------ the panel
  buildPanel() {
    const sel = document.getElementById("bone");
    if (!sel) return;
    this.names.forEach((name, i) => {
      const o = document.createElement("option");
      o.value = String(i);
      o.textContent = name;
      sel.appendChild(o);
    });
    const twist = document.getElementById("twist"), stretch = document.getElementById("stretch");
    const twistRow = document.getElementById("twist-row");
    if (this.v.dim !== 3 && twistRow) twistRow.hidden = true;
    sel.addEventListener("change", () => this.showBone());
    for (const el of [twist, stretch]) {
      el.addEventListener("input", () => this.onSlider());
      el.addEventListener("change", () => { this.sliding = false; });
    }
    document.getElementById("reset")?.addEventListener("click", () => this.reset());
    document.getElementById("undo")?.addEventListener("click", () => this.undo());
    document.getElementById("redo")?.addEventListener("click", () => this.redo());
    document.getElementById("frame")?.addEventListener("click", () => this.v.frame());
    this.showBone();
    this.updateButtons();
  }

  showBone() {
    const name = this.names[Number(document.getElementById("bone").value) || 0];
    const t = this.sliders.twist[name] || 0, s = this.sliders.stretch[name] || 1;
    document.getElementById("twist").value = String(t);
    document.getElementById("stretch").value = String(s);
    this.showValues();
  }

  showValues() {
    const t = document.getElementById("twist"), s = document.getElementById("stretch");
    document.getElementById("twist-value").textContent = `${Number(t.value).toFixed(0)}°`;
    document.getElementById("stretch-value").textContent = `×${Number(s.value).toFixed(2)}`;
  }

  sliderPose() {
    const pose = { stretch: {} };
    for (const [n, s] of Object.entries(this.sliders.stretch)) if (s !== 1) pose.stretch[n] = s;
    if (this.v.dim === 3) {
      pose.twist = {};
      for (const [n, t] of Object.entries(this.sliders.twist)) if (t !== 0) pose.twist[n] = [0, t];
    }
    return pose;
  }

  onSlider() {
    const name = this.names[Number(document.getElementById("bone").value) || 0];
    this.sliders.twist[name] = Number(document.getElementById("twist").value);
    this.sliders.stretch[name] = Number(document.getElementById("stretch").value);
    this.showValues();
    if (!this.sliding) { this.remember(); this.sliding = true; }
    return this.v.send(this.sliderPose());
  }

  reset() {
    this.remember();
    this.sliders = { twist: {}, stretch: {} };
    this.showBone();
    return this.v.send({});
  }
}
