// The weight brush, without the page: which vertices a dab covers (a ball in the rest
// mesh, found through a VertexGrid), how much (strength x falloff), and the new values
// of the painted column after add, subtract or smooth. Pure: no DOM, no WebGL.

import { VertexGrid, hits } from "./grid.js";

export const PAINT_OPS = ["add", "subtract", "smooth"];

/** falloff(x) for x = distance / radius in [0, 1). */
export const FALLOFF = {
  smooth: (x) => { const t = 1 - x * x; return t * t; },
  linear: (x) => 1 - x,
  constant: () => 1,
};
export const FALLOFFS = Object.keys(FALLOFF);

/**
 * Mesh neighbours from triangles, as CSR: the neighbours of v are
 * ids[start[v] .. start[v + 1]), sorted, each once.
 *
 * @param F  triangles, f x 3 vertex ids (flat)
 * @param n  vertex count
 */
export function adjacency(F, n) {
  const deg = new Int32Array(n + 1);
  for (let k = 0; k < F.length; k++) {
    const v = F[k];
    if (!(v >= 0 && v < n)) throw new Error(`adjacency: F: expected vertex ids 0..${n - 1}, got ${v}`);
  }
  for (let k = 0; k < F.length; k++) deg[F[k] + 1] += 2;
  for (let v = 0; v < n; v++) deg[v + 1] += deg[v];
  const fill = deg.slice(0, n), raw = new Int32Array(deg[n]);
  for (let f = 0; f < F.length; f += 3) {
    const a = F[f], b = F[f + 1], c = F[f + 2];
    raw[fill[a]++] = b; raw[fill[a]++] = c;
    raw[fill[b]++] = a; raw[fill[b]++] = c;
    raw[fill[c]++] = a; raw[fill[c]++] = b;
  }
  // sort each list and drop repeats and self loops (degenerate triangles)
  const start = new Int32Array(n + 1), ids = new Int32Array(raw.length);
  let m = 0;
  for (let v = 0; v < n; v++) {
    const list = raw.subarray(deg[v], deg[v + 1]).sort();
    start[v] = m;
    for (let k = 0; k < list.length; k++) {
      const u = list[k];
      if (u !== v && (m === start[v] || ids[m - 1] !== u)) ids[m++] = u;
    }
  }
  start[n] = m;
  return { start, ids: ids.slice(0, m) };
}

/**
 * One dab's work on a column X[:, i] (X n x b, row-major): the vertices within `radius`
 * of `centre` (rest space), a = strength x falloff(d / radius), and the new value
 * clamp(add: x + a, subtract: x - a, smooth: x + a (m - x)) with m the mean of the
 * vertex's neighbours before the dab. Only vertices whose value changes are kept.
 */
export class Brush {
  /**
   * @param V     rest positions, n x dim (flat)
   * @param dim   2 or 3
   * @param nbrs  adjacency(F, n) (for smooth)
   */
  constructor(V, dim, nbrs) {
    this.grid = new VertexGrid(V, dim);
    this.n = this.grid.n;
    this.nbrs = nbrs || { start: new Int32Array(this.n + 1), ids: new Int32Array(0) };
    this.found = hits();
    this.ids = new Int32Array(1024);       // the dab's result, reused
    this.amount = new Float64Array(1024);
    this.values = new Float32Array(1024);
    this.count = 0;
  }

  /** The vertices a dab covers and their amounts a (> 0); returns the count. */
  cover(centre, { radius, strength, falloff }) {
    const fall = FALLOFF[falloff];
    if (!fall) throw new Error(`brush falloff: expected one of ${FALLOFFS.join(", ")}, got ${JSON.stringify(falloff)}`);
    const m = this.grid.within(centre, radius, this.found);
    if (this.ids.length < m) {
      this.ids = new Int32Array(2 * m);
      this.amount = new Float64Array(2 * m);
      this.values = new Float32Array(2 * m);
    }
    const { ids, d2 } = this.found;
    let k = 0;
    for (let q = 0; q < m; q++) {
      const a = strength * fall(Math.sqrt(d2[q]) / radius);
      if (a > 0) { this.ids[k] = ids[q]; this.amount[k] = a; k++; }
    }
    this.count = k;
    return k;
  }

  /**
   * The dab's new values of column i of X (b columns): after cover(); fills
   * this.ids/this.values with the vertices whose value changes (in float32) and returns
   * how many. `amount` may be scaled per vertex beforehand (locks, mirror).
   */
  apply(X, b, i, op) {
    if (!PAINT_OPS.includes(op)) throw new Error(`brush op: expected one of ${PAINT_OPS.join(", ")}, got ${JSON.stringify(op)}`);
    const { start, ids: nb } = this.nbrs, m = this.count;
    const out = this.ids, amount = this.amount, values = this.values;
    let k = 0;
    for (let q = 0; q < m; q++) {
      const v = out[q], old = X[v * b + i], a = amount[q];
      let t;
      if (op === "add") t = old + a;
      else if (op === "subtract") t = old - a;
      else {
        const s = start[v], e = start[v + 1];
        let mean = old;
        if (e > s) {
          mean = 0;
          for (let p = s; p < e; p++) mean += X[nb[p] * b + i];
          mean /= e - s;
        }
        t = old + a * (mean - old);
      }
      t = Math.fround(t < 0 ? 0 : t > 1 ? 1 : t);
      if (t === old) continue;
      // compacting in place: q >= k, and the means read X, which is not written here
      out[k] = v; amount[k] = a; values[k] = t;
      k++;
    }
    this.count = k;
    return k;
  }
}
