// Pose editing on the page: dragging joints (stretching the bones at the joint, or
// inverse kinematics keeping bone lengths) and the rotation gizmo's rings (ik.js,
// gizmo.js), per-bone twist and stretch sliders (the forward-kinematics form), undo
// and redo.

import * as THREE from "three";
import { Bones } from "./ik.js";

const PICK_PX = 14;     // a joint is picked within this many CSS pixels of the pointer
const DRAG_MODES = ["stretch", "ik"];
const DEG = 180 / Math.PI;

function copyWorld(w) {
  return { R: w.R.map((M) => M.map((r) => r.slice())), A: w.A.map((a) => a.slice()),
           S: w.S.slice(), T: w.T.map((t) => t.slice()) };
}

export class PoseEditor {
  constructor(viewer) {
    this.v = viewer;
    this.drag = null;
    this.mode = "stretch";
    this.bones = new Bones(viewer);
    this.names = [];
    const names = viewer.summary.names || [];
    for (let i = 0; i < viewer.b; i++) this.names.push(names[i] != null ? String(names[i]) : String(i));
    const canvas = viewer.renderer.domElement;
    // capture phase on the canvas: runs before OrbitControls' own listener
    canvas.addEventListener("pointerdown", (e) => this.onDown(e), { capture: true });
    canvas.addEventListener("pointermove", (e) => this.onMove(e), { capture: true });
    canvas.addEventListener("pointerup", (e) => this.onUp(e), { capture: true });
    canvas.addEventListener("pointercancel", (e) => this.onUp(e), { capture: true });
    viewer.events.on("history", () => this.updateButtons());
    this.buildPanel();
  }

  // ------------------------------------------------------------------ undo / redo
  /**
   * Start an edit: a command on the one History (ctx.history) that sets the pose object
   * the edit last sent (execute, redo) or the one before it (undo). The pose shown is
   * a function of the pose object (the server's), so both restore it exactly. Returns
   * the command; set its `after` as the edit goes on.
   */
  begin(name) {
    const v = this.v, before = v.lastSent;
    const cmd = { name, before, after: before,
                  execute: () => v.send(cmd.after).then(() => this.showBone()),
                  undo: () => v.send(cmd.before).then(() => this.showBone()) };
    this.v.history.push(cmd);
    return cmd;
  }

  /** Send a pose as part of the edit `cmd`. */
  sendFor(cmd, pose) {
    cmd.after = JSON.parse(JSON.stringify(pose));
    return this.v.send(pose);
  }

  undo() { return this.v.history.undo().then(() => this.v.getPose()); }

  redo() { return this.v.history.redo().then(() => this.v.getPose()); }

  updateButtons() {
    const h = this.v.history;
    const u = document.getElementById("undo"), r = document.getElementById("redo");
    if (u) u.disabled = !h.canUndo;
    if (r) r.disabled = !h.canRedo;
  }

  // ------------------------------------------------------------------ dragging
  /** "stretch" (the joint moves alone, its bones stretch) or "ik" (bone lengths kept). */
  setDragMode(mode) {
    if (!DRAG_MODES.includes(mode)) {
      throw new Error(`drag mode must be one of ${DRAG_MODES.join(", ")}, got ${JSON.stringify(mode)}`);
    }
    this.mode = mode;
    const sel = document.getElementById("drag-mode");
    if (sel) sel.value = mode;
    return mode;
  }

  /** The pointer on the page, and in the viewport under it (two when side by side). */
  pointer(e) {
    const rect = this.v.viewRectAt(e.clientX, e.clientY);
    return { x: e.clientX, y: e.clientY, rect,
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

  /** The joint within PICK_PX of the pointer (the nearest), or -1. */
  jointAt(p) {
    const J = this.v.posedJoints();
    let best = -1, bestD = PICK_PX;
    for (let k = 0; k < J.length / 3; k++) {
      const [x, y] = this.v.toScreen(J[3 * k], J[3 * k + 1], J[3 * k + 2], p.rect);
      const d = Math.hypot(x - p.x, y - p.y);
      if (d <= bestD) { best = k; bestD = d; }
    }
    return best;
  }

  /** Whether weight painting is on (it takes the pointer; joint drags and the gizmo wait). */
  painting() {
    const w = this.v.weights;
    return !!(w && w.settings && w.settings.mode && w.settings.mode !== "off");
  }

  onDown(e) {
    if (e.button !== 0 || this.drag) return;
    if (this.painting()) return;                          // painting has the pointer
    const p = this.pointer(e), gizmo = this.v.gizmo;
    const ring = gizmo ? gizmo.pick(p) : null;
    const best = ring ? -1 : this.jointAt(p);
    if (!ring && best < 0) return;        // not on a ring or a joint: the orbit controls have it
    e.stopImmediatePropagation();
    e.preventDefault();
    const world = this.bones.world();
    if (ring) {
      this.drag = { kind: "gizmo", turn: gizmo.begin(ring, p), bone: gizmo.bone, world,
                    id: e.pointerId, moved: false };
    } else {
      const J = this.v.posedJoints();
      const start = new THREE.Vector3(J[3 * best], J[3 * best + 1], J[3 * best + 2]);
      const normal = this.v.camera.getWorldDirection(new THREE.Vector3());
      this.drag = { kind: this.mode, joint: best, world, start, id: e.pointerId, moved: false,
                    plane: new THREE.Plane().setFromNormalAndCoplanarPoint(normal, start) };
      this.drag.grab = this.onPlane(p.ndc) || start.clone();
    }
    this.v.controls.enabled = false;
    try { this.v.renderer.domElement.setPointerCapture(e.pointerId); } catch (_) { /* synthetic */ }
  }

  onMove(e) {
    if (!this.drag || e.pointerId !== this.drag.id) return;
    e.stopImmediatePropagation();
    const d = this.drag, p = this.pointer(e), w = copyWorld(d.world);
    let edited;
    if (d.kind === "gizmo") {
      const angle = this.v.gizmo.turn(d.turn, p);
      if (angle === 0 && !d.moved) return;
      edited = this.bones.rotateBone(w, d.bone, d.turn.axis.toArray(), angle);
    } else {
      const hit = this.onPlane(p.ndc);
      if (!hit) return;
      const at = d.start.clone().add(hit.sub(d.grab)).toArray();
      if (this.v.dim === 2) at[2] = 0;
      edited = d.kind === "ik" ? this.bones.ikJoint(w, d.joint, at) : this.bones.stretchJoint(w, d.joint, at);
    }
    if (!edited) return;
    if (!d.moved) { d.cmd = this.begin(d.kind === "gizmo" ? "turn bone" : `drag joint (${d.kind})`); d.moved = true; }
    this.sendFor(d.cmd, this.bones.poseObject(edited).pose);
  }

  onUp(e) {
    if (!this.drag || e.pointerId !== this.drag.id) return;
    e.stopImmediatePropagation();
    const d = this.drag;
    this.drag = null;
    this.v.controls.enabled = true;
    try { this.v.renderer.domElement.releasePointerCapture(e.pointerId); } catch (_) { /* synthetic */ }
    if (d.moved) this.v.idle().then(() => this.showBone());
    // a click on a joint with the gizmo on: the gizmo goes to the bone starting there
    if (!d.moved && d.kind !== "gizmo" && this.v.gizmo && this.v.gizmo.bone !== null) {
      const bones = this.bones.startingAt(d.joint);
      if (bones.length) this.v.gizmo.set(bones[0]);
    }
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
    const mode = document.getElementById("drag-mode");
    mode?.addEventListener("change", () => this.setDragMode(mode.value));
    this.showBone();
    this.updateButtons();
  }

  /** The sliders show the selected bone's stretch and end twist in the current pose. */
  showBone() {
    const i = Number(document.getElementById("bone").value) || 0, P = this.v.poseArrays;
    const s = P.stretch[i], t = this.v.dim === 3 ? Math.round(P.twist[i][1] * DEG * 1e6) / 1e6 : 0;
    document.getElementById("twist").value = String(t);
    document.getElementById("stretch").value = String(s);
    this.showValues();
  }

  showValues() {
    const t = document.getElementById("twist"), s = document.getElementById("stretch");
    document.getElementById("twist-value").textContent = `${Number(t.value).toFixed(0)}°`;
    document.getElementById("stretch-value").textContent = `×${Number(s.value).toFixed(2)}`;
  }

  /**
   * A slider move: the current pose in the forward-kinematics form with the selected
   * bone's stretch and end twist set (rotations, offsets and the other twists kept);
   * the bones below follow by forward kinematics, offset children included.
   */
  onSlider() {
    const name = this.names[Number(document.getElementById("bone").value) || 0];
    const t = Number(document.getElementById("twist").value);
    const s = Number(document.getElementById("stretch").value);
    this.showValues();
    if (!this.sliding) {
      this.slideCmd = this.begin("slider");
      this.sliding = true;
      this.slideBase = this.bones.fkObject(this.bones.world());
    }
    const pose = JSON.parse(JSON.stringify(this.slideBase));
    pose.stretch = Object.assign({}, pose.stretch, { [name]: s });
    if (s === 1) delete pose.stretch[name];
    if (this.v.dim === 3) {
      const start = pose.twist && pose.twist[name] ? pose.twist[name][0] : 0;
      pose.twist = Object.assign({}, pose.twist, { [name]: [start, t] });
      if (start === 0 && t === 0) delete pose.twist[name];
    }
    return this.sendFor(this.slideCmd, pose);
  }

  /**
   * Turn a bone (index or name) and everything below it by `degrees` about the world
   * `axis` ([x, y, z]; 2D: about z, the axis optional) through its posed start, as a
   * gizmo ring does: one undo step. Resolves to the pose as the server keeps it.
   */
  async turnBone(bone, axis, degrees) {
    const b = this.bones;
    const i = typeof bone === "number" ? bone : b.names.indexOf(String(bone));
    if (!Number.isInteger(i) || i < 0 || i >= b.b) {
      throw new Error(`bone: expected a bone index 0..${b.b - 1} or name, got ${JSON.stringify(bone)}`);
    }
    if (this.v.dim === 2 && (axis === null || axis === undefined)) axis = [0, 0, 1];
    if (!Array.isArray(axis) || axis.length !== 3 || !axis.every(Number.isFinite) ||
        axis.every((x) => x === 0) || (this.v.dim === 2 && (axis[0] !== 0 || axis[1] !== 0))) {
      throw new Error(`axis: expected a non-zero [x, y, z]${this.v.dim === 2 ? " along z (2D)" : ""}, got ${JSON.stringify(axis)}`);
    }
    if (typeof degrees !== "number" || !Number.isFinite(degrees)) {
      throw new Error(`degrees: expected a finite number, got ${JSON.stringify(degrees)}`);
    }
    await this.v.settled();
    const w = b.rotateBone(b.world(), i, axis, degrees / DEG);
    await this.v.history.execute(this.command("turn bone", b.poseObject(w).pose));
    return this.v.getPose();
  }

  /** A command setting the pose object `pose` (undo: the pose object before). */
  command(name, pose) {
    const v = this.v, before = v.lastSent, after = JSON.parse(JSON.stringify(pose));
    return { name, before, after,
             execute: () => v.send(after).then(() => this.showBone()),
             undo: () => v.send(before).then(() => this.showBone()) };
  }

  reset() {
    return this.v.history.execute(this.command("reset pose", {}));
  }
}
