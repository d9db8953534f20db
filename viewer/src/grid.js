// A uniform grid over a mesh's rest vertices, for the two queries weight painting asks
// many times: the vertices within a radius of a point (a brush dab) and the vertex
// nearest a point (the mirror of a vertex). Pure: no DOM, no WebGL.
//
// The cells are a counting sort of the vertices by cell (start offsets and one array of
// vertex ids), built once in O(n); a query visits only the cells its ball touches.

/**
 * @param {Float32Array|Float64Array|number[]} V  rest positions, n x dim, row-major
 * @param {number} dim  2 or 3
 * @param {number} [perCell]  about how many vertices a cell should hold (default 8)
 */
export class VertexGrid {
  constructor(V, dim, perCell = 8) {
    if (dim !== 2 && dim !== 3) throw new Error(`grid: dim: expected 2 or 3, got ${JSON.stringify(dim)}`);
    if (!V || V.length % dim !== 0) {
      throw new Error(`grid: V: expected n x ${dim} values, got ${V ? V.length : V}`);
    }
    const n = V.length / dim;
    this.V = V;
    this.dim = dim;
    this.n = n;
    const lo = [Infinity, Infinity, 0], hi = [-Infinity, -Infinity, 0];
    for (let v = 0; v < n; v++) {
      for (let c = 0; c < dim; c++) {
        const x = V[v * dim + c];
        if (!Number.isFinite(x)) throw new Error(`grid: V: expected finite values, got ${x} at vertex ${v}`);
        if (x < lo[c]) lo[c] = x;
        if (x > hi[c]) hi[c] = x;
      }
    }
    if (n === 0) { lo[0] = lo[1] = hi[0] = hi[1] = 0; }
    const ext = [0, 1, 2].map((c) => (c < dim ? hi[c] - lo[c] : 0));
    const diag = Math.hypot(...ext) || 1;
    // A mesh's vertices lie on a surface (3D) or fill an area (2D): size the cells by the
    // box's largest faces, so that an occupied cell holds about perCell vertices.
    const sorted = ext.slice(0, dim).map((e) => Math.max(e, 1e-9 * diag)).sort((a, b) => b - a);
    const area = sorted[0] * sorted[1];
    let h = Math.sqrt(area * Math.max(1, perCell) / Math.max(n, 1));
    if (!(h > 0)) h = diag;
    // at most about 4n cells
    const cellsFor = (s) => ext.slice(0, dim).reduce((p, e) => p * (Math.floor(e / s) + 1), 1);
    while (cellsFor(h) > 4 * Math.max(n, 1) + 64) h *= 1.5;
    this.h = h;
    this.lo = lo;
    this.size = [0, 1, 2].map((c) => (c < dim ? Math.floor(ext[c] / h) + 1 : 1));
    const [sx, sy, sz] = this.size, cells = sx * sy * sz;
    const cellOf = new Int32Array(n), start = new Int32Array(cells + 1);
    for (let v = 0; v < n; v++) {
      const k = this.cellIndex(v);
      cellOf[v] = k;
      start[k + 1]++;
    }
    for (let k = 0; k < cells; k++) start[k + 1] += start[k];
    const fill = start.slice(0, cells), items = new Int32Array(n);
    for (let v = 0; v < n; v++) items[fill[cellOf[v]]++] = v;
    this.start = start;
    this.items = items;
  }

  /** The cell coordinate of a point's component c (clamped to the grid). */
  coord(x, c) {
    const k = Math.floor((x - this.lo[c]) / this.h);
    return k < 0 ? 0 : k >= this.size[c] ? this.size[c] - 1 : k;
  }

  cellIndex(v) {
    const V = this.V, d = this.dim, o = v * d;
    const i = this.coord(V[o], 0), j = this.coord(V[o + 1], 1), k = d === 3 ? this.coord(V[o + 2], 2) : 0;
    return (k * this.size[1] + j) * this.size[0] + i;
  }

  /**
   * Every vertex within `radius` of point p (strictly closer), with its squared distance.
   * Writes into `out` {ids: Int32Array, d2: Float64Array} growing them as needed (so a
   * caller that keeps `out` allocates nothing per query); returns the count.
   */
  within(p, radius, out) {
    const V = this.V, d = this.dim, r2 = radius * radius, [sx, sy] = this.size;
    const i0 = this.coord(p[0] - radius, 0), i1 = this.coord(p[0] + radius, 0);
    const j0 = this.coord(p[1] - radius, 1), j1 = this.coord(p[1] + radius, 1);
    const k0 = d === 3 ? this.coord(p[2] - radius, 2) : 0, k1 = d === 3 ? this.coord(p[2] + radius, 2) : 0;
    const pz = d === 3 ? p[2] : 0;
    let m = 0;
    for (let k = k0; k <= k1; k++) {
      for (let j = j0; j <= j1; j++) {
        const row = (k * sy + j) * sx;
        const a = this.start[row + i0], b = this.start[row + i1 + 1];
        for (let q = a; q < b; q++) {
          const v = this.items[q], o = v * d;
          const dx = V[o] - p[0], dy = V[o + 1] - p[1], dz = d === 3 ? V[o + 2] - pz : 0;
          const d2 = dx * dx + dy * dy + dz * dz;
          if (d2 >= r2) continue;
          if (m === out.ids.length) grow(out, 2 * m + 64);
          out.ids[m] = v;
          out.d2[m] = d2;
          m++;
        }
      }
    }
    return m;
  }

  /** The vertex nearest point p (ties: the lower id), or -1 for an empty grid. */
  nearest(p) {
    if (this.n === 0) return -1;
    const d = this.dim, [sx, sy, sz] = this.size, V = this.V;
    const ci = this.coord(p[0], 0), cj = this.coord(p[1], 1), ck = d === 3 ? this.coord(p[2], 2) : 0;
    const pz = d === 3 ? p[2] : 0;
    // distance from p to the outside of its own cell box grown by s cells: a vertex in a
    // shell beyond s is at least that far
    let best = -1, bestD2 = Infinity;
    const maxShell = Math.max(sx, sy, sz);
    for (let s = 0; s <= maxShell; s++) {
      for (let k = Math.max(0, ck - s); k <= Math.min(sz - 1, ck + s); k++) {
        for (let j = Math.max(0, cj - s); j <= Math.min(sy - 1, cj + s); j++) {
          const edge = k === ck - s || k === ck + s || j === cj - s || j === cj + s;
          const row = (k * sy + j) * sx;
          for (let i = Math.max(0, ci - s); i <= Math.min(sx - 1, ci + s); i++) {
            if (!edge && i !== ci - s && i !== ci + s) continue;     // inner cells: seen before
            for (let q = this.start[row + i]; q < this.start[row + i + 1]; q++) {
              const v = this.items[q], o = v * d;
              const dx = V[o] - p[0], dy = V[o + 1] - p[1], dz = d === 3 ? V[o + 2] - pz : 0;
              const d2 = dx * dx + dy * dy + dz * dz;
              if (d2 < bestD2 || (d2 === bestD2 && v < best)) { best = v; bestD2 = d2; }
            }
          }
        }
      }
      if (best >= 0) {
        // every unvisited cell is at least s cells of h beyond p's own cell
        const gap = this.gapBeyond(p, ci, cj, ck, s);
        if (gap * gap > bestD2) break;
      }
    }
    return best;
  }

  /** The least distance from p to any cell outside the (2s+1)^dim block around its cell. */
  gapBeyond(p, ci, cj, ck, s) {
    const h = this.h, lo = this.lo;
    let g = Infinity;
    const cs = [ci, cj, ck];
    for (let c = 0; c < this.dim; c++) {
      const x = p[c], base = lo[c];
      const below = x - (base + (cs[c] - s) * h), above = base + (cs[c] + s + 1) * h - x;
      if (cs[c] - s > 0) g = Math.min(g, below);
      if (cs[c] + s + 1 < this.size[c]) g = Math.min(g, above);
    }
    return g;
  }
}

function grow(out, m) {
  const ids = new Int32Array(m), d2 = new Float64Array(m);
  ids.set(out.ids);
  d2.set(out.d2);
  out.ids = ids;
  out.d2 = d2;
}

/** A reusable result for VertexGrid.within. */
export function hits(capacity = 1024) {
  return { ids: new Int32Array(capacity), d2: new Float64Array(capacity) };
}
