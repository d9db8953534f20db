// Pose editing on the page: selecting a bone (a click on it, or the bone list),
// dragging joints (stretching the bones at the joint, or inverse kinematics keeping
// bone lengths) and the rotation gizmo's rings (ik.js, gizmo.js), per-bone twist and
// stretch sliders (the forward-kinematics form), X-mirror posing. Every edit is a
// command on the one History (ctx.history).

import * as THREE from "three";
import { mirrorBones } from "./mirror.js";
import { copyWorld, mirrorEdit, worldJSON } from "./ik.js";

const PICK_PX = 14;     // a joint is picked within this many CSS pixels of the pointer
const BONE_PX = 6;      // a bone is picked by a click within this many CSS pixels of it
const CLICK_PX = 4;     // a press and release closer than this is a click, not a drag
const DRAG_MODES = ["stretch", "ik"];
const DEG = 180 / Math.PI;

function copy(x) { return JSON.parse(JSON.stringify(x)); }

/** Distance from point (px, py) to the segment (ax, ay)-(bx, by). */
export function segmentDistance(px, py, ax, ay, bx, by) {
  const dx = bx - ax, dy = by - ay, l2 = dx * dx + dy * dy;
  const t = l2 > 0 ? Math.max(0, Math.min(1, ((px - ax) * dx + (py - ay) * dy) / l2)) : 0;
  return Math.hypot(px - ax - t * dx, py - ay - t * dy);
}

export class PoseEditor {
  /**
   * ctx: {store, events, history, keys, view, poses}; bones: the rig's Bones (ik.js);
   * gizmo: the rotation gizmo (gizmo.js); painting(): whether painting has the pointer.
   */
  constructor(ctx, { bones, gizmo, painting = () => false }) {
    this.ctx = ctx;
    this.store = ctx.store;
    this.view = ctx.view;
    this.history = ctx.history;
    this.poses = ctx.poses;
    this.bones = bones;
    this.gizmo = gizmo;
    this.painting = painting;
    this.drag = null;
    this.press = null;
    this.mode = "stretch";
    this.names = bones.names;
    this.mirrorMap = null;
    const canvas = this.view.renderer.domElement;
    // capture phase on the canvas: runs before OrbitControls' own listener
    canvas.addEventListener("pointerdown", (e) => this.onDown(e), { capture: true });
    canvas.addEventListener("pointermove", (e) => this.onMove(e), { capture: true });
    canvas.addEventListener("pointerup", (e) => this.onUp(e), { capture: true });
    canvas.addEventListener("pointercancel", (e) => this.onUp(e), { capture: true });
    ctx.events.on("history", () => this.updateButtons());
    ctx.events.on("select", () => this.showBone());
    ctx.events.on("pose", () => { if (!this.sliding) this.showBone(); });
    this.buildPanel();
  }

  /** Select a bone (index or name); the bone list, sliders and gizmo follow. */
  select(bone) {
    const i = this.boneIndex(bone);
    return this.store.select(i);
  }

  boneIndex(bone) {
    const b = this.bones, i = typeof bone === "number" ? bone : b.names.indexOf(String(bone));
    if (!Number.isInteger(i) || i < 0 || i >= b.b) {
      throw new Error(`bone: expected a bone index 0..${b.b - 1} or name, got ${JSON.stringify(bone)}`);
    }
    return i;
  }

  selected() {
    const i = this.store.selection.bone;
    return i === null ? 0 : i;
  }

  // ------------------------------------------------------------------ undo / redo
  /**
   * A command setting the pose object `after` (execute, redo) or `before` (undo). The
   * pose shown is a function of the pose object (the server's), so both restore it
   * exactly.
   */
  command(name, before, after) {
    const cmd = { name, before: copy(before), after: copy(after),
                  execute: () => this.poses.send(cmd.after),
                  undo: () => this.poses.send(cmd.before) };
    return cmd;
  }

  /** Start an interactive edit: its command goes on the History now, its `after`
   * follows the edit (sendFor). */
  begin(name) {
    const cmd = this.command(name, this.store.poseObject, this.store.poseObject);
    this.history.push(cmd);
    return cmd;
  }

  /** Send a pose as part of the edit `cmd`. */
  sendFor(cmd, pose) {
    cmd.after = copy(pose);
    return this.poses.send(pose);
  }

  undo() { return this.history.undo().then(() => this.poses.get()); }

  redo() { return this.history.redo().then(() => this.poses.get()); }

  updateButtons() {
    const h = this.history;
    const u = document.getElementById("undo"), r = document.getElementById("redo");
    if (u) u.disabled = !h.canUndo;
    if (r) r.disabled = !h.canRedo;
  }

  // ------------------------------------------------------------------ mirroring
  /** With the mirror on, the world pose w (edited from w0) with each edited bone's
   * edit also applied to its mirror bone (mirror.js, across x = the rest's centre). */
  mirrored(w0, w) {
    if (!this.store.mirror) return w;
    if (!this.mirrorMap) this.mirrorMap = mirrorBones(this.store.rig);
    return mirrorEdit(w0, w, this.mirrorMap);
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
    const rect = this.view.viewRectAt(e.clientX, e.clientY);
    return { x: e.clientX, y: e.clientY, rect,
             ndc: new THREE.Vector2(2 * (e.clientX - rect.left) / rect.width - 1,
                                    1 - 2 * (e.clientY - rect.top) / rect.height) };
  }

  /** Where the pointer's ray meets the drag plane, or null. */
  onPlane(ndc) {
    const ray = new THREE.Raycaster();
    ray.setFromCamera(ndc, this.view.camera);
    const hit = new THREE.Vector3();
    return ray.ray.intersectPlane(this.drag.plane, hit) ? hit : null;
  }

  /** The joint within PICK_PX of the pointer (the nearest), or -1. */
  jointAt(p) {
    const J = this.view.posedJoints();
    let best = -1, bestD = PICK_PX;
    for (let k = 0; k < J.length / 3; k++) {
      const [x, y] = this.view.toScreen(J[3 * k], J[3 * k + 1], J[3 * k + 2], p.rect);
      const d = Math.hypot(x - p.x, y - p.y);
      if (d <= bestD) { best = k; bestD = d; }
    }
    return best;
  }

  /** The bone drawn within BONE_PX of the pointer (the nearest on screen), or -1. */
  boneAt(p) {
    const S = this.view.segments();
    let best = -1, bestD = BONE_PX;
    for (let i = 0; i < this.bones.b; i++) {
      const [ax, ay] = this.view.toScreen(S[6 * i], S[6 * i + 1], S[6 * i + 2], p.rect);
      const [bx, by] = this.view.toScreen(S[6 * i + 3], S[6 * i + 4], S[6 * i + 5], p.rect);
      const d = segmentDistance(p.x, p.y, ax, ay, bx, by);
      if (d <= bestD) { best = i; bestD = d; }
    }
    return best;
  }

  onDown(e) {
    // a plain left press: Alt+drag and the middle button orbit, the right one pans
    if (e.button !== 0 || e.altKey || this.drag) return;
    if (this.painting()) return;                          // painting has the pointer
    this.press = { x: e.clientX, y: e.clientY, id: e.pointerId, far: false };
    const p = this.pointer(e), gizmo = this.gizmo;
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
      const J = this.view.posedJoints();
      const start = new THREE.Vector3(J[3 * best], J[3 * best + 1], J[3 * best + 2]);
      const normal = this.view.camera.getWorldDirection(new THREE.Vector3());
      this.drag = { kind: this.mode, joint: best, world, start, id: e.pointerId, moved: false,
                    plane: new THREE.Plane().setFromNormalAndCoplanarPoint(normal, start) };
      this.drag.grab = this.onPlane(p.ndc) || start.clone();
    }
    this.view.setOrbit(false);
    try { this.view.renderer.domElement.setPointerCapture(e.pointerId); } catch (_) { /* synthetic */ }
  }

  onMove(e) {
    const pr = this.press;
    if (pr && e.pointerId === pr.id && Math.hypot(e.clientX - pr.x, e.clientY - pr.y) > CLICK_PX) pr.far = true;
    if (!this.drag || e.pointerId !== this.drag.id) return;
    e.stopImmediatePropagation();
    const d = this.drag, p = this.pointer(e), w = copyWorld(d.world);
    let edited;
    if (d.kind === "gizmo") {
      const angle = this.gizmo.turn(d.turn, p);
      if (angle === 0 && !d.moved) return;
      edited = this.bones.rotateBone(w, d.bone, d.turn.axis, angle);
    } else {
      const hit = this.onPlane(p.ndc);
      if (!hit) return;
      const at = d.start.clone().add(hit.sub(d.grab));
      if (this.bones.dim === 2) at.z = 0;
      edited = d.kind === "ik" ? this.bones.ikJoint(w, d.joint, at) : this.bones.stretchJoint(w, d.joint, at);
    }
    if (!edited) return;
    edited = this.mirrored(d.world, edited);
    if (!d.moved) { d.cmd = this.begin(d.kind === "gizmo" ? "turn bone" : `drag joint (${d.kind})`); d.moved = true; }
    this.sendFor(d.cmd, { world: worldJSON(edited) });
  }

  onUp(e) {
    const pr = this.press;
    if (pr && e.pointerId === pr.id) {
      this.press = null;
      // a click (no drag, of a joint or of the camera): select the bone under it;
      // a click on nothing keeps the selection
      if (!pr.far && !(this.drag && this.drag.moved) && !(this.drag && this.drag.kind === "gizmo")) {
        const p = this.pointer(e);
        let bone = -1;
        if (this.drag) {                   // a joint: the bone starting there (else ending)
          const j = this.drag.joint;
          bone = [...this.bones.startingAt(j), ...this.bones.endingAt(j)][0] ?? -1;
        } else {
          bone = this.boneAt(p);
        }
        if (bone >= 0) this.store.select(bone);
      }
    }
    if (!this.drag || e.pointerId !== this.drag.id) return;
    e.stopImmediatePropagation();
    this.drag = null;
    this.view.setOrbit(true);
    try { this.view.renderer.domElement.releasePointerCapture(e.pointerId); } catch (_) { /* synthetic */ }
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
    if (this.bones.dim !== 3 && twistRow) twistRow.hidden = true;
    sel.addEventListener("change", () => this.store.select(Number(sel.value) || 0));
    for (const el of [twist, stretch]) {
      el.addEventListener("input", () => this.onSlider());
      el.addEventListener("change", () => { this.sliding = false; });
    }
    document.getElementById("reset")?.addEventListener("click", () => this.reset());
    document.getElementById("undo")?.addEventListener("click", () => this.undo());
    document.getElementById("redo")?.addEventListener("click", () => this.redo());
    document.getElementById("frame")?.addEventListener("click", () => this.view.frame());
    const mode = document.getElementById("drag-mode");
    mode?.addEventListener("change", () => this.setDragMode(mode.value));
    this.showBone();
    this.updateButtons();
  }

  /** The bone list and sliders show the selected bone: its stretch and end twist now. */
  showBone() {
    const sel = document.getElementById("bone");
    if (!sel || !this.store.pose) return;
    const i = this.selected(), P = this.store.pose;
    if (sel.value !== String(i)) sel.value = String(i);
    const s = P.stretch[i], t = this.bones.dim === 3 ? Math.round(P.twist[i][1] * DEG * 1e6) / 1e6 : 0;
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
   * A slider move: the current pose in the forward-kinematics form (the server's pose
   * object) with the selected
   * bone's stretch and end twist set (rotations, offsets and the other twists kept);
   * the bones below follow by forward kinematics, offset children included. With the
   * mirror on, the mirror bone gets the same stretch and the opposite twist.
   */
  onSlider() {
    const i = this.selected();
    const t = Number(document.getElementById("twist").value);
    const s = Number(document.getElementById("stretch").value);
    this.showValues();
    if (!this.sliding) {
      this.slideCmd = this.begin("slider");
      this.sliding = true;
      // the server's pose object of the pose shown (its forward-kinematics form), once
      // the edit before has been sent
      this.slideBase = Promise.resolve(this.poses.sending).catch(() => {}).then(() => this.poses.get());
    }
    return this.poses.track(this.slideTo(this.slideCmd, i, s, t));
  }

  async slideTo(cmd, i, s, t) {
    const pose = copy(await this.slideBase);
    const set = (k, stretch, twist) => {
      const name = this.names[k];
      pose.stretch = Object.assign({}, pose.stretch, { [name]: stretch });
      if (stretch === 1) delete pose.stretch[name];
      if (this.bones.dim === 3) {
        const start = pose.twist && pose.twist[name] ? pose.twist[name][0] : 0;
        pose.twist = Object.assign({}, pose.twist, { [name]: [start, twist] });
        if (start === 0 && twist === 0) delete pose.twist[name];
      }
    };
    set(i, s, t);
    if (this.store.mirror) {
      if (!this.mirrorMap) this.mirrorMap = mirrorBones(this.store.rig);
      const m = this.mirrorMap[i];
      if (m !== i) set(m, s, -t);
    }
    return this.sendFor(cmd, pose);
  }

  /**
   * Turn a bone (index or name) and everything below it by `degrees` about the world
   * `axis` ([x, y, z]; 2D: about z, the axis optional) through its posed start, as a
   * gizmo ring does: one undo step. Resolves to the pose as the server keeps it.
   */
  async turnBone(bone, axis, degrees) {
    const b = this.bones, i = this.boneIndex(bone);
    if (b.dim === 2 && (axis === null || axis === undefined)) axis = [0, 0, 1];
    if (!Array.isArray(axis) || axis.length !== 3 || !axis.every(Number.isFinite) ||
        axis.every((x) => x === 0) || (b.dim === 2 && (axis[0] !== 0 || axis[1] !== 0))) {
      throw new Error(`axis: expected a non-zero [x, y, z]${b.dim === 2 ? " along z (2D)" : ""}, got ${JSON.stringify(axis)}`);
    }
    if (typeof degrees !== "number" || !Number.isFinite(degrees)) {
      throw new Error(`degrees: expected a finite number, got ${JSON.stringify(degrees)}`);
    }
    await this.history.idle();
    await this.poses.idle();
    const w0 = b.world(), w = this.mirrored(w0, b.rotateBone(copyWorld(w0), i, axis, degrees / DEG));
    await this.history.execute(this.command("turn bone", this.store.poseObject, { world: worldJSON(w) }));
    return this.poses.get();
  }

  reset() {
    return this.history.execute(this.command("reset pose", this.store.poseObject, {}));
  }
}
