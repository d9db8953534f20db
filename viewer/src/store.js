// The page's one store of the rig and the pose (after three.js's editor): modules read
// its fields and change them only through its setters, each of which emits an event
// (events.js) that the modules showing that state subscribe to. No DOM, no WebGL.

export const MODES = ["pose", "paint"];

function bad(what, expected, got) {
  return new Error(`${what}: expected ${expected}, got ${JSON.stringify(got)}`);
}

export class Store {
  /** events: an Events (events.js); every setter emits on it. */
  constructor(events) {
    if (!events || typeof events.emit !== "function") throw bad("store", "an Events", events);
    this.events = events;
    this.rig = null;            // {dim, n, b, V, F, C, BE, parents, names, rest, ...}
    this.W = null;              // bone weights, Float32Array n * b
    this.E = null;              // endpoint weights being edited, Float32Array n * b
    this.pose = null;           // per-bone arrays {rotations, origins, stretch, twist}
    this.poseObject = {};       // the pose object (a pose file's) that gives this.pose
    this.selection = { bone: null };
    this.mode = "pose";
    this.mirror = false;
    this.brush = { radius: 0, strength: 0.25, op: "add", falloff: "smooth", target: 0 };
  }

  /** The rig as loaded; emits "rig". */
  setRig(rig) {
    if (!rig || !Number.isInteger(rig.b) || !Number.isInteger(rig.dim)) {
      throw bad("store.setRig", "a rig {dim, n, b, ...}", rig && Object.keys(rig));
    }
    this.rig = rig;
    this.events.emit("rig", rig);
  }

  /** The bone (W) and endpoint (E) weights, n * b each; emits "weights" {rows: null}. */
  setWeights(W, E) {
    const nb = this.rig ? this.rig.n * this.rig.b : null;
    for (const [name, A] of [["W", W], ["E", E]]) {
      if (!(A instanceof Float32Array) || (nb !== null && A.length !== nb)) {
        throw bad(`store.setWeights: ${name}`, `a Float32Array of ${nb} values`,
                  A ? `${A.constructor.name} of ${A.length}` : A);
      }
    }
    this.W = W;
    this.E = E;
    this.events.emit("weights", { rows: null });
  }

  /** After an edit of W or E in place: emits "weights" {rows} (null: all rows). */
  weightsChanged(rows = null) {
    this.events.emit("weights", { rows });
  }

  /** The pose shown: its per-bone arrays and (when known) the pose object that gives
   * them; emits "pose" {arrays, object}. */
  setPose(arrays, object = undefined) {
    if (!arrays || !Array.isArray(arrays.rotations) || !Array.isArray(arrays.origins)) {
      throw bad("store.setPose", "pose arrays {rotations, origins, stretch, twist}",
                arrays && Object.keys(arrays));
    }
    this.pose = arrays;
    if (object !== undefined) this.poseObject = JSON.parse(JSON.stringify(object));
    this.events.emit("pose", { arrays, object: this.poseObject });
  }

  /** Select a bone (an index, or null for none); emits "select" {bone} on a change. */
  select(bone) {
    if (bone !== null) {
      const b = this.rig ? this.rig.b : 0;
      if (!Number.isInteger(bone) || bone < 0 || bone >= b) {
        throw bad("bone", `a bone index 0..${b - 1} or null`, bone);
      }
    }
    if (bone === this.selection.bone) return bone;
    this.selection = { bone };
    this.events.emit("select", { bone });
    return bone;
  }

  /** "pose" or "paint"; emits "mode" {mode} on a change. */
  setMode(mode) {
    if (!MODES.includes(mode)) throw bad("mode", `one of ${MODES.join(", ")}`, mode);
    if (mode !== this.mode) {
      this.mode = mode;
      this.events.emit("mode", { mode });
    }
    return mode;
  }

  /** X-mirror editing on or off; emits "mirror" {on} on a change. */
  setMirror(on) {
    if (typeof on !== "boolean") throw bad("mirror", "true or false", on);
    if (on !== this.mirror) {
      this.mirror = on;
      this.events.emit("mirror", { on });
    }
    return on;
  }

  /** Change some of the brush's settings; emits "brush" with all of them. */
  setBrush(patch) {
    if (!patch || typeof patch !== "object") throw bad("brush", "an object of settings", patch);
    for (const k of Object.keys(patch)) {
      if (!(k in this.brush)) {
        throw bad("brush", `settings among ${Object.keys(this.brush).join(", ")}`, k);
      }
    }
    this.brush = Object.assign({}, this.brush, patch);
    this.events.emit("brush", Object.assign({}, this.brush));
    return this.brush;
  }
}
