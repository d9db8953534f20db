// Left/right mirroring across the rest pose's symmetry plane x = centre, for X-mirror
// painting (paint.js) and mirrored posing: which bone is a bone's mirror, and which
// vertex is a vertex's. Pure: no DOM, no WebGL.
//
// The plane: x = centre, the middle of the rest mesh's extent in x (of the joints when
// the rig has no vertices), the plane a symmetric character is modelled about.

import { VertexGrid } from "./grid.js";

/** Middle of the extent in x of the points P (n x dim, row-major). */
export function centreX(P, dim) {
  let lo = Infinity, hi = -Infinity;
  for (let k = 0; k < P.length; k += dim) {
    if (P[k] < lo) lo = P[k];
    if (P[k] > hi) hi = P[k];
  }
  return lo <= hi ? 0.5 * (lo + hi) : 0;
}

// Name pairs, tried in order: whole words (Left/Right, left/right, LEFT/RIGHT) anywhere,
// then a single L/R (either case) set off by a separator at the start or the end
// (".L", "_r", "L_", "l-" ...), as Blender, Mixamo, Maya and Unreal name sides.
const WORDS = [["Left", "Right"], ["left", "right"], ["LEFT", "RIGHT"]];

/** The names a bone of this name would have on the other side (best guess first). */
export function sideSwapped(name) {
  const out = [];
  for (const [a, b] of WORDS) {
    if (name.includes(a)) out.push(name.split(a).join(b));
    if (name.includes(b)) out.push(name.split(b).join(a));
  }
  const swap = { L: "R", R: "L", l: "r", r: "l" };
  let m = /^([LRlr])([._\- ])/.exec(name);
  if (m) out.push(swap[m[1]] + name.slice(1));
  m = /([._\- ])([LRlr])$/.exec(name);
  if (m) out.push(name.slice(0, -1) + swap[m[2]]);
  return out;
}

/**
 * Each bone's mirror bone across x = centre: by left/right names where a bone's
 * swapped name is another bone's, else the bone whose reflected rest joints are
 * nearest its own (within `tol`), else the bone itself (a bone on the plane, or one
 * without a partner). The map is an involution: m[m[i]] === i.
 *
 * @param rig  {dim, C (j x dim), BE (b x 2), names?, V? (n x dim)}; flat row-major arrays
 * @param opts {centre?: number, tol?: number (default 2% of the joints' extent)}
 * @returns Int32Array(b)
 */
export function mirrorBones(rig, opts = {}) {
  const { dim, C, BE } = rig || {};
  if (dim !== 2 && dim !== 3) throw new Error(`mirrorBones: rig.dim: expected 2 or 3, got ${JSON.stringify(dim)}`);
  if (!C || C.length % dim !== 0) throw new Error(`mirrorBones: rig.C: expected j x ${dim} values, got ${C ? C.length : C}`);
  if (!BE || BE.length % 2 !== 0) throw new Error(`mirrorBones: rig.BE: expected b x 2 joint ids, got ${BE ? BE.length : BE}`);
  const b = BE.length / 2, j = C.length / dim;
  for (let k = 0; k < BE.length; k++) {
    if (!(BE[k] >= 0 && BE[k] < j)) throw new Error(`mirrorBones: rig.BE: expected joint ids 0..${j - 1}, got ${BE[k]}`);
  }
  const names = rig.names ? Array.from(rig.names, String) : null;
  if (names && names.length !== b) throw new Error(`mirrorBones: rig.names: expected ${b} names, got ${names.length}`);
  const centre = opts.centre ?? (rig.V && rig.V.length ? centreX(rig.V, dim) : centreX(C, dim));
  const m = new Int32Array(b).fill(-1);
  if (names) {
    const index = new Map(names.map((s, i) => [s, i]));
    for (let i = 0; i < b; i++) {
      if (m[i] >= 0) continue;
      for (const other of sideSwapped(names[i])) {
        const k = index.get(other);
        if (k !== undefined && k !== i && m[k] < 0) { m[i] = k; m[k] = i; break; }
      }
    }
  }
  // by position: the reflected bone (a, b) -> (a*, b*), compared joint to joint
  let lo = Infinity, hi = -Infinity, span = 0;
  for (let c = 0; c < dim; c++) {
    lo = Infinity; hi = -Infinity;
    for (let k = c; k < C.length; k += dim) { lo = Math.min(lo, C[k]); hi = Math.max(hi, C[k]); }
    if (hi > lo) span = Math.max(span, hi - lo);
  }
  const tol = opts.tol ?? 0.02 * (span || 1);
  const at = (bone, end, c) => C[BE[2 * bone + end] * dim + c];
  const gap = (p, q) => {       // bone q against bone p reflected: the larger joint distance
    let da = 0, db = 0;
    for (let c = 0; c < dim; c++) {
      const ra = c === 0 ? 2 * centre - at(p, 0, 0) : at(p, 0, c);
      const rb = c === 0 ? 2 * centre - at(p, 1, 0) : at(p, 1, c);
      da += (ra - at(q, 0, c)) ** 2;
      db += (rb - at(q, 1, c)) ** 2;
    }
    return Math.sqrt(Math.max(da, db));
  };
  const best = new Int32Array(b).fill(-1);
  for (let p = 0; p < b; p++) {
    if (m[p] >= 0) continue;
    let bd = tol;
    for (let q = 0; q < b; q++) {
      if (m[q] >= 0) continue;
      const g = gap(p, q);
      if (g <= bd) { bd = g; best[p] = q; }
    }
  }
  for (let p = 0; p < b; p++) {
    if (m[p] >= 0) continue;
    const q = best[p];
    // only mutual nearest pairs; a bone that reflects onto itself is its own mirror
    m[p] = q >= 0 && best[q] === p ? q : p;
  }
  return m;
}

/**
 * Each vertex's mirror vertex: the vertex nearest its reflection across x = centre.
 *
 * @param V    rest positions, n x dim, row-major
 * @param dim  2 or 3
 * @param opts {centre?: number (default the middle of V's extent in x)}
 * @returns Int32Array(n)
 */
export function mirrorVertices(V, dim, opts = {}) {
  const grid = opts.grid || new VertexGrid(V, dim);
  const n = V.length / dim, centre = opts.centre ?? centreX(V, dim), out = new Int32Array(n);
  const p = [0, 0, 0];
  for (let v = 0; v < n; v++) {
    p[0] = 2 * centre - V[v * dim];
    p[1] = V[v * dim + 1];
    p[2] = dim === 3 ? V[v * dim + 2] : 0;
    out[v] = grid.nearest(p);
  }
  return out;
}
