// Per-bone pose data for the shader (skin.js): rest frames, pose arrays, the
// bone texture's rows, and the posed skeleton for drawing.

import { Matrix4, Quaternion, Vector3 } from "three";
import { TEXELS_PER_BONE } from "./skin.js";

/** Rest frames of the bones, in 3D (2D rigs get z = 0), float64 (C: the rest joints,
 * flat, j x dim; the server's float64 values where it sends them). */
export function restFrames(C, BE, dim) {
  const b = BE.length / 2;
  const a = new Float64Array(3 * b), bb = new Float64Array(3 * b);
  const u = new Float64Array(3 * b), len = new Float64Array(b);
  for (let i = 0; i < b; i++) {
    const s = BE[2 * i], t = BE[2 * i + 1];
    let l2 = 0;
    for (let c = 0; c < 3; c++) {
      const x = c < dim ? C[dim * s + c] : 0, y = c < dim ? C[dim * t + c] : 0;
      a[3 * i + c] = x; bb[3 * i + c] = y;
      l2 += (y - x) * (y - x);
    }
    const l = Math.sqrt(l2);
    len[i] = l;
    for (let c = 0; c < 3; c++) u[3 * i + c] = l > 0 ? (bb[3 * i + c] - a[3 * i + c]) / l : 0;
  }
  return { count: b, a, b: bb, u, len };
}

/** The rest pose's arrays: R = I, a' = a, sigma = 1, theta = 0 (d = dim). */
export function restPose(rest, dim) {
  const n = rest.count;
  const rotations = [], origins = [], stretch = [], twist = [];
  for (let i = 0; i < n; i++) {
    const R = [];
    for (let r = 0; r < dim; r++) {
      const row = [];
      for (let c = 0; c < dim; c++) row.push(r === c ? 1 : 0);
      R.push(row);
    }
    rotations.push(R);
    origins.push(Array.from(rest.a.subarray(3 * i, 3 * i + dim)));
    stretch.push(1);
    twist.push([0, 0]);
  }
  return { rotations, origins, stretch, twist };
}

function embed(R, dim) {   // a d x d rotation as 3x3 rows
  if (dim === 3) return R;
  return [[R[0][0], R[0][1], 0], [R[1][0], R[1][1], 0], [0, 0, 1]];
}

/**
 * Fill the bone texture's data (b rows x TEXELS_PER_BONE RGBA texels) from pose
 * arrays {rotations (b,d,d), origins (b,d), stretch (b), twist (b,2) radians}.
 */
export function packBones(rest, pose, dim, out) {
  const b = rest.count, T = 4 * TEXELS_PER_BONE;
  for (let i = 0; i < b; i++) {
    const R = embed(pose.rotations[i], dim);
    const o = pose.origins[i];
    const ap = [o[0], o[1], dim === 3 ? o[2] : 0];
    const a = [rest.a[3 * i], rest.a[3 * i + 1], rest.a[3 * i + 2]];
    const row = i * T;
    for (let c = 0; c < 3; c++) {          // columns of R
      out[row + 4 * c] = R[0][c];
      out[row + 4 * c + 1] = R[1][c];
      out[row + 4 * c + 2] = R[2][c];
    }
    out[row + 3] = pose.stretch[i];
    out[row + 7] = dim === 3 ? pose.twist[i][0] : 0;
    out[row + 11] = dim === 3 ? pose.twist[i][1] : 0;
    out.set([ap[0], ap[1], ap[2], rest.len[i]], row + 12);
    out.set([a[0], a[1], a[2], 0], row + 16);
    out.set([rest.u[3 * i], rest.u[3 * i + 1], rest.u[3 * i + 2], 0], row + 20);
    const q = new Quaternion().setFromRotationMatrix(new Matrix4().set(
      R[0][0], R[0][1], R[0][2], 0, R[1][0], R[1][1], R[1][2], 0, R[2][0], R[2][1], R[2][2], 0, 0, 0, 0, 1));
    out.set([q.x, q.y, q.z, q.w], row + 24);
    // dual part of x -> a' + R (x - a): t = a' - R a, qd = (t, 0) q / 2
    const t = new Vector3(...a).applyQuaternion(q).negate().add(new Vector3(...ap));
    const d = new Quaternion(t.x, t.y, t.z, 0).multiply(q);
    const [dx, dy, dz, dw] = [0.5 * d.x, 0.5 * d.y, 0.5 * d.z, 0.5 * d.w];
    out.set([dx, dy, dz, dw], row + 28);
  }
  return out;
}

/** Posed joints of each bone: a'_i and b'_i = a'_i + sigma_i R_i (b_i - a_i), in 3D. */
export function posedSegments(rest, pose, dim, out) {
  for (let i = 0; i < rest.count; i++) {
    const R = embed(pose.rotations[i], dim);
    const o = pose.origins[i];
    const ap = [o[0], o[1], dim === 3 ? o[2] : 0];
    const s = pose.stretch[i] * rest.len[i];
    const u = [rest.u[3 * i], rest.u[3 * i + 1], rest.u[3 * i + 2]];
    for (let c = 0; c < 3; c++) {
      out[6 * i + c] = ap[c];
      out[6 * i + 3 + c] = ap[c] + s * (R[c][0] * u[0] + R[c][1] * u[1] + R[c][2] * u[2]);
    }
  }
  return out;
}

/**
 * The offset children's links: for each bone hanging off its parent away from the
 * parent's end (DESIGN §2, `hang` t_c), a segment from where it hangs on the posed
 * parent, a'_p + t_c (b'_p - a'_p) (the twist turns about the bone, so the point
 * stays on it), to its posed start a'_c. `links` lists [child, parent, t_c].
 */
export function hangSegments(links, segs, out) {
  links.forEach(([c, p, t], k) => {
    for (let x = 0; x < 3; x++) {
      const a = segs[6 * p + x], b = segs[6 * p + 3 + x];
      out[6 * k + x] = a + t * (b - a);
      out[6 * k + 3 + x] = segs[6 * c + x];
    }
  });
  return out;
}

/**
 * The pose on the server: sends pose objects (POST /api/pose) or the page's world
 * transforms (POST /api/pose/bones) and puts what the server makes of them into the
 * store (store.setPose: per-bone arrays and the pose object). Interactive edits send
 * with send(): the latest pose wins, one request at a time. `client`: the page's API
 * client (api.js: apiJSON, poseBones, setWorldPose).
 */
export class PoseLink {
  constructor(store, client, report = () => {}) {
    for (const f of ["apiJSON", "poseBones", "setWorldPose"]) {
      if (typeof client?.[f] !== "function") throw new Error(`PoseLink: the client needs ${f}(), got ${typeof client?.[f]}`);
    }
    this.store = store;
    this.client = client;
    this.report = report;
    this.pending = null;
    this.sending = null;
    this.made = new Set();        // edits whose pose is still being made (track())
  }

  /** GET /api/pose: the current pose object, as the server keeps it. */
  get() { return this.client.apiJSON("/api/pose"); }

  /** Fetch the current pose's arrays (binary rows) into the store; `object`: the pose
   * object that gave them. */
  async fetch(object = undefined) {
    this.store.setPose(await this.client.poseBones(), object);
  }

  /** POST a pose and show it; resolves to the server's pose object. `pose`: a pose
   * object (a pose file's, POST /api/pose), or {world} (the page's world form of a pose,
   * {R, A, S, T}, POST /api/pose/bones: the server makes its forward-kinematics pose). */
  async post(pose) {
    if (pose && pose.world) {
      const reply = await this.client.setWorldPose(pose.world);
      this.store.setPose(reply.bones, reply.pose);
      return reply.pose;
    }
    const reply = await this.client.apiJSON("/api/pose", {
      method: "POST", headers: { "Content-Type": "application/json" }, body: JSON.stringify(pose) });
    await this.fetch(pose);
    return reply.pose;
  }

  /** Interactive edits (pose objects or {world}): the latest pose wins; resolves when
   * all sent poses are shown. */
  send(pose) {
    this.pending = pose;
    if (!this.sending) {
      this.sending = (async () => {
        try {
          while (this.pending) {
            const p = this.pending;
            this.pending = null;
            try { await this.post(p); } catch (err) { this.report(err); }
          }
        } finally { this.sending = null; }
      })();
    }
    return this.sending;
  }

  /** Count an edit whose pose is still being made (a promise that sends it) as in
   * flight: idle() waits for it too. Returns the promise. */
  track(p) {
    this.made.add(p);
    p.finally(() => this.made.delete(p)).catch(() => {});
    return p;
  }

  /** Whether an edit's pose is still being made (track()). */
  get preparing() { return this.made.size > 0; }

  /** Resolves once no sent pose (or one being made) is in flight. */
  async idle() {
    while (this.sending || this.made.size) {
      await Promise.all([this.sending, ...this.made].map((p) => p && p.catch(() => {})));
    }
  }
}
