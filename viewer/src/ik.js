// Skeleton edits in world space on the page: the current pose's per-bone arrays
// (stbs.Pose: R_i, a'_i, sigma_i, theta_i) edited by a joint drag (stretching
// the bones at the joint, or inverse kinematics keeping bone lengths) or a rotation
// of a bone with everything below it (its children, connected or hanging off it),
// then written back as a pose object for POST /api/pose: the forward-kinematics form
// of DESIGN §2, which holds every pose exactly (each bone's rotation, start offset and
// twist in the frame its parent carries it in: stbs.Pose.local).

const DEG = 180 / Math.PI;

// ------------------------------------------------------------------ 3-vectors, 3x3 rows
export const sub = (a, b) => [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
export const add = (a, b) => [a[0] + b[0], a[1] + b[1], a[2] + b[2]];
export const scale = (a, s) => [a[0] * s, a[1] * s, a[2] * s];
export const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
export const cross = (a, b) => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2],
                                a[0] * b[1] - a[1] * b[0]];
export const norm = (a) => Math.hypot(a[0], a[1], a[2]);
export const apply = (M, v) => [dot(M[0], v), dot(M[1], v), dot(M[2], v)];
const transpose = (M) => [0, 1, 2].map((r) => [M[0][r], M[1][r], M[2][r]]);

export function matmul(A, B) {
  return [0, 1, 2].map((r) => [0, 1, 2].map((c) => A[r][0] * B[0][c] + A[r][1] * B[1][c] +
                                                     A[r][2] * B[2][c]));
}

/** Rotation by `angle` radians about `axis` (any non-zero length), as 3x3 rows. */
export function axisAngle(axis, angle) {
  const l = norm(axis);
  const [x, y, z] = scale(axis, 1 / l), c = Math.cos(angle), s = Math.sin(angle), t = 1 - c;
  return [[c + x * x * t, x * y * t - z * s, x * z * t + y * s],
          [y * x * t + z * s, c + y * y * t, y * z * t - x * s],
          [z * x * t - y * s, z * y * t + x * s, c + z * z * t]];
}

/** The smallest rotation taking direction `u` to direction `v` (both non-zero). */
export function minRotation(u, v) {
  const a = scale(u, 1 / norm(u)), b = scale(v, 1 / norm(v));
  const axis = cross(a, b), s = norm(axis), c = dot(a, b);
  if (s < 1e-12) {
    if (c > 0) return axisAngle([0, 0, 1], 0);
    // opposite: half a turn about an axis perpendicular to u (z for a vector in the xy plane)
    if (Math.abs(a[2]) < 1e-12) return axisAngle([0, 0, 1], Math.PI);
    let p = cross(a, [1, 0, 0]);
    if (norm(p) < 1e-6) p = cross(a, [0, 1, 0]);
    return axisAngle(p, Math.PI);
  }
  return axisAngle(axis, Math.atan2(s, c));
}

/** A 3x3 rotation as [axis (unit), angle in [0, pi]] (axis [0, 0, 1] for the identity). */
export function toAxisAngle(M) {
  const v = [0.5 * (M[2][1] - M[1][2]), 0.5 * (M[0][2] - M[2][0]), 0.5 * (M[1][0] - M[0][1])];
  const s = norm(v), c = 0.5 * (M[0][0] + M[1][1] + M[2][2] - 1);
  const angle = Math.atan2(s, c);
  if (angle < 1e-15) return [[0, 0, 1], 0];
  if (c > -0.5) return [scale(v, 1 / s), angle];
  // near a half turn: (M + M^T)/2 - cos I = (1 - cos) a a^T; the largest column, signed by v
  const B = [0, 1, 2].map((r) => [0, 1, 2].map((k) => 0.5 * (M[r][k] + M[k][r]) - (r === k ? c : 0)));
  let k = 0;
  if (B[1][1] > B[k][k]) k = 1;
  if (B[2][2] > B[k][k]) k = 2;
  let a = [B[0][k], B[1][k], B[2][k]];
  a = scale(a, 1 / norm(a));
  if (dot(a, v) < 0) a = scale(a, -1);
  return [a, angle];
}

// ------------------------------------------------------------------ the skeleton
/** Parents, children, hang points and joint incidences of the rig's bones (BE, P). */
export class Bones {
  /** store: the page's store (store.js), its rig loaded; world() reads its pose. */
  constructor(store) {
    const rig = store.rig, { BE } = rig;
    const s = { connected: rig.connected, hang: rig.hang };
    this.store = store;
    this.rig = rig;
    this.b = rig.b;
    this.dim = rig.dim;
    this.parents = rig.parents.slice();
    this.start = [];
    this.end = [];
    for (let i = 0; i < this.b; i++) { this.start.push(BE[2 * i]); this.end.push(BE[2 * i + 1]); }
    // connected: the child starts at its parent's end joint; else an offset child,
    // hanging at t_c on its parent (the server's Skeleton.connected and .hang)
    this.connected = this.parents.map((p, i) => (s.connected ? !!s.connected[i]
      : p >= 0 && this.start[i] === this.end[p]));
    this.hang = this.parents.map((p, i) => (s.hang ? s.hang[i] : this.connected[i] ? 1 : 0));
    this.children = Array.from({ length: this.b }, () => []);
    this.parents.forEach((p, i) => { if (p >= 0) this.children[p].push(i); });
    this.order = [];                                    // parents before children
    const todo = this.parents.map((p, i) => (p < 0 ? i : -1)).filter((i) => i >= 0);
    while (todo.length) {
      const i = todo.shift();
      this.order.push(i);
      todo.push(...this.children[i]);
    }
    this.names = rig.names.slice();
  }

  /** Bone i and everything below it. */
  subtree(i) {
    const out = [i];
    for (let k = 0; k < out.length; k++) out.push(...this.children[out[k]]);
    return out;
  }

  startingAt(j) { return this.start.flatMap((s, i) => (s === j ? [i] : [])); }

  endingAt(j) { return this.end.flatMap((e, i) => (e === j ? [i] : [])); }

  /**
   * The inverse-kinematics chain of joint j: the bone ending at j and its parents up
   * to the first joint that is a root (no bone ends there), a branching joint (more
   * than one bone starts there) or the start of an offset child (it hangs off its
   * parent elsewhere than the parent's end); that joint stays put. Bones top-down;
   * [] at a root.
   */
  chain(j) {
    const e = this.endingAt(j);
    if (!e.length) return [];
    const out = [e[0]];
    for (;;) {
      const top = out[0], p = this.parents[top];
      if (p < 0 || !this.connected[top] || this.startingAt(this.start[top]).length > 1) break;
      out.unshift(p);
    }
    return out;
  }

  // ---------------------------------------------------------------- world pose
  /** The current pose's arrays in 3D (2D: rotations about z), float64 copies. */
  world() {
    const P = this.store.pose, d = this.dim;
    const R = [], A = [], S = P.stretch.slice(), T = [];
    for (let i = 0; i < this.b; i++) {
      const M = P.rotations[i];
      R.push(d === 3 ? M.map((r) => r.slice()) : [[M[0][0], M[0][1], 0], [M[1][0], M[1][1], 0], [0, 0, 1]]);
      const o = P.origins[i];
      A.push([o[0], o[1], d === 3 ? o[2] : 0]);
      T.push(d === 3 ? P.twist[i].slice() : [0, 0]);
    }
    return { R, A, S, T };
  }

  restVec(i) {   // b_i - a_i
    const r = this.rig.rest;
    return sub([r.b[3 * i], r.b[3 * i + 1], r.b[3 * i + 2]], [r.a[3 * i], r.a[3 * i + 1], r.a[3 * i + 2]]);
  }

  restStart(i) {
    const r = this.rig.rest;
    return [r.a[3 * i], r.a[3 * i + 1], r.a[3 * i + 2]];
  }

  /** Posed end joint b'_i = a'_i + sigma_i R_i (b_i - a_i). */
  endOf(w, i) { return add(w.A[i], scale(apply(w.R[i], this.restVec(i)), w.S[i])); }

  /** Posed joint positions (j x 3) of a world pose. */
  joints(w) {
    const J = [];
    const C = this.rig.C, d = this.dim, nj = C.length / d;
    for (let k = 0; k < nj; k++) J.push([C[d * k], C[d * k + 1], d === 3 ? C[d * k + 2] : 0]);
    for (const i of this.order) { J[this.start[i]] = w.A[i].slice(); J[this.end[i]] = this.endOf(w, i); }
    return J;
  }

  /** Turn bone i and everything below it by Q about the point c (in place). */
  turn(w, i, Q, c) {
    for (const k of this.subtree(i)) {
      w.R[k] = matmul(Q, w.R[k]);
      w.A[k] = add(c, apply(Q, sub(w.A[k], c)));
    }
  }

  /** Move bone i and everything below it by t (in place). */
  shift(w, i, t) {
    for (const k of this.subtree(i)) w.A[k] = add(w.A[k], t);
  }

  // ---------------------------------------------------------------- the edits
  /** Stretch drag: joint j to `at`, every other joint stays; the bones at j turn and stretch. */
  stretchJoint(w, j, at) {
    for (const i of this.endingAt(j)) {
      const d0 = sub(this.endOf(w, i), w.A[i]), d1 = sub(at, w.A[i]);
      if (norm(d1) < 1e-9 * norm(d0)) return null;
      w.R[i] = matmul(minRotation(d0, d1), w.R[i]);
      w.S[i] = norm(d1) / norm(this.restVec(i));
    }
    for (const i of this.startingAt(j)) {
      const end = this.endOf(w, i), d0 = sub(end, w.A[i]), d1 = sub(end, at);
      if (norm(d1) < 1e-9 * norm(d0)) return null;
      w.R[i] = matmul(minRotation(d0, d1), w.R[i]);
      w.A[i] = at.slice();
      w.S[i] = norm(d1) / norm(this.restVec(i));
    }
    return w;
  }

  /**
   * IK drag: joint j towards `at` by FABRIK on j's chain (chain()), bone lengths kept;
   * the bones below j follow rigidly. At a root joint the whole skeleton there moves.
   */
  ikJoint(w, j, at) {
    const chain = this.chain(j);
    if (!chain.length) {
      const from = this.joints(w)[j], t = sub(at, from);
      for (const i of this.startingAt(j)) this.shift(w, i, t);
      return w;
    }
    const P = [w.A[chain[0]].slice()];
    for (const i of chain) P.push(this.endOf(w, i));
    const L = chain.map((i) => w.S[i] * norm(this.restVec(i)));
    const Q = fabrik(P, L, at);
    for (let k = 0; k < chain.length; k++) {
      const i = chain[k], d0 = sub(this.endOf(w, i), w.A[i]), d1 = sub(Q[k + 1], Q[k]);
      if (norm(d1) > 0) this.turn(w, i, minRotation(d0, d1), w.A[i].slice());
    }
    return w;
  }

  /** Rotate bone i and everything below it by `angle` radians about `axis` through its start. */
  rotateBone(w, i, axis, angle) {
    this.turn(w, i, axisAngle(axis, angle), w.A[i].slice());
    return w;
  }

  // ---------------------------------------------------------------- back to a pose object
  /** The pose object of a world pose: the forward-kinematics form. Returns {pose, form}. */
  poseObject(w) {
    return { pose: this.fkObject(w), form: "fk" };
  }

  /** The frame bone i hangs in (DESIGN §2): F_p = R_p K_p(t_c), its parent's rotation
   * and the parent's twist where it hangs (3x3 rows; 2D: R_p). */
  hangFrame(w, i) {
    const p = this.parents[i];
    if (this.dim !== 3) return w.R[p];
    const t = this.hang[i], angle = (1 - t) * w.T[p][0] + t * w.T[p][1];
    return angle === 0 ? w.R[p] : matmul(w.R[p], axisAngle(this.restVec(p), angle));
  }

  /**
   * The forward-kinematics form of a world pose (bones by name, degrees), exactly as
   * stbs.Pose.local gives it: each bone's rotation L_i = F_p^T R_i, its own stretch
   * and twist [theta_a, theta_b], and where its start is away from where its parent
   * carries it the offset D_i = F_p^T (a'_i - a'_p) - t_c (sigma_p - 1)(b_p - a_p) -
   * (a_i - a_p) (a root: a'_i - a_i) under "translate": [x, y, z] when only roots
   * moved, all alike, else {bone: offset}.
   */
  fkObject(w) {
    const d = this.dim;
    let big = 1;
    const restC = this.rig.restC;
    for (let k = 0; k < restC.length; k++) big = Math.max(big, Math.abs(restC[k]));
    for (const a of w.A) big = Math.max(big, Math.abs(a[0]), Math.abs(a[1]), Math.abs(a[2]));
    const tol = 1e-9 * big;       // as stbs.io.pose_to_dict: an offset below it is none
    const rotate = {}, stretch = {}, twist = {}, moved = [];
    for (const i of this.order) {
      const p = this.parents[i], name = this.names[i];
      let L, D;
      if (p < 0) {
        L = w.R[i];
        D = sub(w.A[i], this.restStart(i));
      } else {
        const Ft = transpose(this.hangFrame(w, i));
        L = matmul(Ft, w.R[i]);
        D = sub(sub(apply(Ft, sub(w.A[i], w.A[p])), scale(this.restVec(p), this.hang[i] * (w.S[p] - 1))),
                sub(this.restStart(i), this.restStart(p)));
      }
      if (d === 3) {
        const [axis, angle] = toAxisAngle(L);
        if (angle > 1e-15) rotate[name] = { axis, angle: angle * DEG };
        const [a, b] = w.T[i];
        if (a !== 0 || b !== 0) twist[name] = [a * DEG, b * DEG];
      } else {
        const angle = Math.atan2(L[1][0], L[0][0]);
        if (angle !== 0) rotate[name] = { angle: angle * DEG };
      }
      if (w.S[i] !== 1) stretch[name] = w.S[i];
      if (Math.max(Math.abs(D[0]), Math.abs(D[1]), Math.abs(D[2])) > tol) moved.push([i, D.slice(0, d)]);
    }
    const pose = {};
    if (Object.keys(rotate).length) pose.rotate = rotate;
    if (Object.keys(stretch).length) pose.stretch = stretch;
    if (Object.keys(twist).length) pose.twist = twist;
    if (moved.length) {
      const roots = this.parents.flatMap((p, i) => (p < 0 ? [i] : []));
      const D0 = moved[0][1];
      const alike = moved.length === roots.length && moved.every(([i, D]) => this.parents[i] < 0 &&
        D.every((x, c) => Math.abs(x - D0[c]) <= tol));
      if (alike) pose.translate = D0;
      else pose.translate = Object.fromEntries(moved.map(([i, D]) => [this.names[i], D]));
    }
    pose.degrees = true;
    return pose;
  }
}

/**
 * FABRIK (Aristidou & Lasenby 2011): points P[0..m] (P[0] fixed) with segment
 * lengths L[0..m-1]; moves P[m] to `target` (or as close as the lengths reach),
 * keeping every length. Returns new points.
 */
export function fabrik(P, L, target, iterations = 64) {
  const m = L.length, Q = P.map((p) => p.slice()), root = P[0].slice();
  const total = L.reduce((s, l) => s + l, 0), reach = norm(sub(target, root));
  const place = (from, to, l) => {          // the point at distance l from `from` towards `to`
    const d = sub(to, from), n = norm(d);
    return n > 0 ? add(from, scale(d, l / n)) : to.slice();
  };
  if (reach >= total) {                     // out of reach: the chain points at the target
    for (let k = 0; k < m; k++) Q[k + 1] = place(Q[k], target, L[k]);
    return Q;
  }
  const tol = 1e-10 * Math.max(total, 1e-12);
  for (let it = 0; it < iterations; it++) {
    Q[m] = target.slice();
    for (let k = m - 1; k >= 0; k--) Q[k] = place(Q[k + 1], Q[k], L[k]);
    Q[0] = root.slice();
    for (let k = 0; k < m; k++) Q[k + 1] = place(Q[k], Q[k + 1], L[k]);
    if (norm(sub(Q[m], target)) < tol) break;
  }
  return Q;
}

/**
 * X-mirror posing: the world pose w edited from w0, with each edited bone's edit also
 * applied to its mirror bone (mirror[k], mirror.js's mirrorBones) where that bone was
 * not edited itself: the rotation's change reflected across the x = centre plane
 * (S D S, S = diag(-1, 1, 1)), the start's move reflected, the stretch scaled alike and
 * the twists' change negated (a reflection turns the other way). Returns w.
 */
export function mirrorEdit(w0, w, mirror) {
  const b = w.R.length, changed = new Uint8Array(b);
  const same = (x, y) => x.length === y.length && x.every((v, k) => (Array.isArray(v) ? same(v, y[k]) : v === y[k]));
  for (let k = 0; k < b; k++) {
    changed[k] = same(w0.R[k], w.R[k]) && same(w0.A[k], w.A[k]) && w0.S[k] === w.S[k] &&
      same(w0.T[k], w.T[k]) ? 0 : 1;
  }
  const flip = (M) => M.map((row, r) => row.map((x, c) => ((r === 0) !== (c === 0) ? -x : x)));
  for (let k = 0; k < b; k++) {
    const m = mirror[k];
    if (!changed[k] || m === k || changed[m]) continue;
    const D = matmul(w.R[k], transpose(w0.R[k]));
    w.R[m] = matmul(flip(D), w0.R[m]);
    const t = sub(w.A[k], w0.A[k]);
    w.A[m] = add(w0.A[m], [-t[0], t[1], t[2]]);
    w.S[m] = w0.S[k] !== 0 ? w0.S[m] * (w.S[k] / w0.S[k]) : w.S[k];
    w.T[m] = [w0.T[m][0] - (w.T[k][0] - w0.T[k][0]), w0.T[m][1] - (w.T[k][1] - w0.T[k][1])];
  }
  return w;
}
