// Skeleton edits in world space on the page: the current pose's per-bone arrays
// (stbs.Pose: R_i, a'_i, sigma_i, theta_i) edited by a joint drag (stretching the
// bones at the joint, or inverse kinematics keeping bone lengths) or a rotation of a
// bone with everything below it (its children, connected or hanging off it), with
// three.js's Vector3, Quaternion and Matrix3. The edited world pose goes to the server
// as it is (POST /api/pose/bones), which makes the forward-kinematics pose of it.

import { Matrix3, Matrix4, Quaternion, Vector3 } from "three";

const Z = new Vector3(0, 0, 1);

/** A rotation as a Matrix3, from a quaternion. */
function fromQuaternion(q) {
  return new Matrix3().setFromMatrix4(new Matrix4().makeRotationFromQuaternion(q));
}

/** Rotation by `angle` radians about `axis` (a Vector3 or [x, y, z], any non-zero length). */
export function axisAngle(axis, angle) {
  const a = Array.isArray(axis) ? new Vector3(...axis) : axis.clone();
  return fromQuaternion(new Quaternion().setFromAxisAngle(a.normalize(), angle));
}

/** The smallest rotation taking direction `u` to direction `v` (both non-zero Vector3s);
 * a half turn between opposite directions in the xy plane is about z. */
export function minRotation(u, v) {
  const a = u.clone().normalize(), b = v.clone().normalize();
  if (a.dot(b) < -1 + 1e-12 && Math.abs(a.z) < 1e-12 && Math.abs(b.z) < 1e-12) {
    return axisAngle(Z, Math.PI);
  }
  return fromQuaternion(new Quaternion().setFromUnitVectors(a, b));
}

/** A Matrix3 as rows [[..], [..], [..]] (Matrix3 keeps its elements by column). */
export function rows(M) {
  const e = M.elements;
  return [[e[0], e[3], e[6]], [e[1], e[4], e[7]], [e[2], e[5], e[8]]];
}

/** A copy of a world pose {R (Matrix3), A (Vector3), S, T}. */
export function copyWorld(w) {
  return { R: w.R.map((M) => M.clone()), A: w.A.map((a) => a.clone()), S: w.S.slice(),
           T: w.T.map((t) => t.slice()) };
}

/** A world pose as POST /api/pose/bones takes it: {R (b x 3 x 3 rows), A, S, T}. */
export function worldJSON(w) {
  return { R: w.R.map(rows), A: w.A.map((a) => a.toArray()), S: w.S.slice(), T: w.T.map((t) => t.slice()) };
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
  /** The current pose's arrays in 3D (2D: rotations about z), as Matrix3 and Vector3. */
  world() {
    const P = this.store.pose, d = this.dim;
    const R = [], A = [], S = P.stretch.slice(), T = [];
    for (let i = 0; i < this.b; i++) {
      const M = P.rotations[i];
      R.push(d === 3 ? new Matrix3().set(...M[0], ...M[1], ...M[2])
        : new Matrix3().set(M[0][0], M[0][1], 0, M[1][0], M[1][1], 0, 0, 0, 1));
      const o = P.origins[i];
      A.push(new Vector3(o[0], o[1], d === 3 ? o[2] : 0));
      T.push(d === 3 ? P.twist[i].slice() : [0, 0]);
    }
    return { R, A, S, T };
  }

  restVec(i) {   // b_i - a_i
    const r = this.rig.rest;
    return new Vector3(r.b[3 * i] - r.a[3 * i], r.b[3 * i + 1] - r.a[3 * i + 1], r.b[3 * i + 2] - r.a[3 * i + 2]);
  }

  /** Posed end joint b'_i = a'_i + sigma_i R_i (b_i - a_i). */
  endOf(w, i) { return this.restVec(i).applyMatrix3(w.R[i]).multiplyScalar(w.S[i]).add(w.A[i]); }

  /** Posed joint positions (j Vector3s) of a world pose. */
  joints(w) {
    const J = [];
    const C = this.rig.C, d = this.dim, nj = C.length / d;
    for (let k = 0; k < nj; k++) J.push(new Vector3(C[d * k], C[d * k + 1], d === 3 ? C[d * k + 2] : 0));
    for (const i of this.order) { J[this.start[i]] = w.A[i].clone(); J[this.end[i]] = this.endOf(w, i); }
    return J;
  }

  /** Turn bone i and everything below it by Q (Matrix3) about the point c (in place). */
  turn(w, i, Q, c) {
    for (const k of this.subtree(i)) {
      w.R[k] = new Matrix3().multiplyMatrices(Q, w.R[k]);
      w.A[k] = w.A[k].clone().sub(c).applyMatrix3(Q).add(c);
    }
  }

  /** Move bone i and everything below it by t (in place). */
  shift(w, i, t) {
    for (const k of this.subtree(i)) w.A[k] = w.A[k].clone().add(t);
  }

  // ---------------------------------------------------------------- the edits
  /** Stretch drag: joint j to `at` (Vector3), every other joint stays; the bones at j
   * turn and stretch. Null where a bone would shrink to nothing. */
  stretchJoint(w, j, at) {
    for (const i of this.endingAt(j)) {
      const d0 = this.endOf(w, i).sub(w.A[i]), d1 = at.clone().sub(w.A[i]);
      if (d1.length() < 1e-9 * d0.length()) return null;
      w.R[i] = new Matrix3().multiplyMatrices(minRotation(d0, d1), w.R[i]);
      w.S[i] = d1.length() / this.restVec(i).length();
    }
    for (const i of this.startingAt(j)) {
      const end = this.endOf(w, i), d0 = end.clone().sub(w.A[i]), d1 = end.clone().sub(at);
      if (d1.length() < 1e-9 * d0.length()) return null;
      w.R[i] = new Matrix3().multiplyMatrices(minRotation(d0, d1), w.R[i]);
      w.A[i] = at.clone();
      w.S[i] = d1.length() / this.restVec(i).length();
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
      const t = at.clone().sub(this.joints(w)[j]);
      for (const i of this.startingAt(j)) this.shift(w, i, t);
      return w;
    }
    const P = [w.A[chain[0]].clone()];
    for (const i of chain) P.push(this.endOf(w, i));
    const L = chain.map((i) => w.S[i] * this.restVec(i).length());
    const Q = fabrik(P, L, at);
    for (let k = 0; k < chain.length; k++) {
      const i = chain[k], d0 = this.endOf(w, i).sub(w.A[i]), d1 = Q[k + 1].clone().sub(Q[k]);
      if (d1.lengthSq() > 0) this.turn(w, i, minRotation(d0, d1), w.A[i].clone());
    }
    return w;
  }

  /** Rotate bone i and everything below it by `angle` radians about `axis` through its start. */
  rotateBone(w, i, axis, angle) {
    this.turn(w, i, axisAngle(axis, angle), w.A[i].clone());
    return w;
  }
}

/**
 * FABRIK (Aristidou & Lasenby 2011): points P[0..m] (Vector3s, P[0] fixed) with
 * segment lengths L[0..m-1]; moves P[m] to `target` (or as close as the lengths
 * reach), keeping every length. Returns new points.
 */
export function fabrik(P, L, target, iterations = 64) {
  const m = L.length, Q = P.map((p) => p.clone()), root = P[0].clone();
  const total = L.reduce((s, l) => s + l, 0), reach = target.distanceTo(root);
  const place = (from, to, l) => {          // the point at distance l from `from` towards `to`
    const d = to.clone().sub(from), n = d.length();
    return n > 0 ? from.clone().addScaledVector(d, l / n) : to.clone();
  };
  if (reach >= total) {                     // out of reach: the chain points at the target
    for (let k = 0; k < m; k++) Q[k + 1] = place(Q[k], target, L[k]);
    return Q;
  }
  const tol = 1e-10 * Math.max(total, 1e-12);
  for (let it = 0; it < iterations; it++) {
    Q[m] = target.clone();
    for (let k = m - 1; k >= 0; k--) Q[k] = place(Q[k + 1], Q[k], L[k]);
    Q[0] = root.clone();
    for (let k = 0; k < m; k++) Q[k + 1] = place(Q[k], Q[k + 1], L[k]);
    if (Q[m].distanceTo(target) < tol) break;
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
  for (let k = 0; k < b; k++) {
    changed[k] = w0.R[k].equals(w.R[k]) && w0.A[k].equals(w.A[k]) && w0.S[k] === w.S[k] &&
      w0.T[k][0] === w.T[k][0] && w0.T[k][1] === w.T[k][1] ? 0 : 1;
  }
  const S = new Matrix3().set(-1, 0, 0, 0, 1, 0, 0, 0, 1);
  for (let k = 0; k < b; k++) {
    const m = mirror[k];
    if (!changed[k] || m === k || changed[m]) continue;
    const D = new Matrix3().multiplyMatrices(w.R[k], w0.R[k].clone().transpose());
    const SDS = new Matrix3().multiplyMatrices(S, D).multiply(S);
    w.R[m] = new Matrix3().multiplyMatrices(SDS, w0.R[m]);
    w.A[m] = w.A[k].clone().sub(w0.A[k]).applyMatrix3(S).add(w0.A[m]);
    w.S[m] = w0.S[k] !== 0 ? w0.S[m] * (w.S[k] / w0.S[k]) : w.S[k];
    w.T[m] = [w0.T[m][0] - (w.T[k][0] - w0.T[k][0]), w0.T[m][1] - (w.T[k][1] - w0.T[k][1])];
  }
  return w;
}
