// The endpoint curves of the painter's bones, without the page: a curve f (spline.js
// splineFilter) previewed for a bone changes what the shader draws (f(E), through the
// layout's stbsEnd and stbsSel) but not E, until it is baked into E's column. No DOM,
// no WebGL.

import { splineFilter } from "./spline.js";

export class EndpointCurves {
  /** @param b  the rig's bone count */
  constructor(b) {
    this.filters = new Array(b).fill(null);     // bone -> its curve, null: the identity
  }

  /** Bone i's curve's points, ends included ([[0, 0], [1, 1]]: the identity). */
  points(i) {
    const f = this.filters[i];
    return f ? f.points.map((p) => p.slice()) : [[0, 0], [1, 1]];
  }

  /** Preview the curve through `points` for bone i (checked by splineFilter); returns it. */
  set(i, points) {
    const f = splineFilter(points);
    this.filters[i] = f.identity ? null : f;
    return f;
  }

  /** f(x) of bone i's curve for each x of xs. */
  values(i, xs) {
    const f = this.filters[i] || splineFilter([]);
    return Array.from(xs, (x) => f(x));
  }

  /**
   * Bone i's curve applied to column i of E (n x b, row-major): f(E[:, i]) as a
   * Float64Array n; the curve is then the identity. null when bone i has none.
   */
  bake(i, E, n, b) {
    const f = this.filters[i];
    if (!f) return null;
    const col = new Float64Array(n);
    for (let r = 0; r < n; r++) col[r] = f(E[r * b + i]);
    this.filters[i] = null;
    return col;
  }
}

/** The rows of W (n x b, row-major) where bone i has weight: whose drawing follows
 * bone i's curve. */
export function rowsWith(W, n, b, i) {
  const rows = [];
  for (let r = 0; r < n; r++) if (W[r * b + i] > 0) rows.push(r);
  return Int32Array.from(rows);
}
