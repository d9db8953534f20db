// Endpoint-weight filters (paper Fig. 10): the curve f on [0, 1]^2 through control
// points, f(0) = 0, f(1) = 1, monotone. The same curve as stbs.weights.SplineFilter:
// the monotone cubic (Fritsch-Carlson, PCHIP) interpolant as scipy's
// PchipInterpolator builds it, then clipped to [0, 1] with exact ends.
// Also the small canvas editor for one bone's curve.

/** Check control points as SplineFilter does; returns all points, ends included, by x. */
export function splinePoints(points) {
  if (points == null) points = [];
  if (!Array.isArray(points)) {
    throw new Error(`spline points: expected an array of [x, y] pairs, got ${JSON.stringify(points)}`);
  }
  const P = points.map((p, k) => {
    if (!Array.isArray(p) || p.length !== 2 || !p.every((v) => typeof v === "number" && Number.isFinite(v))) {
      throw new Error(`spline points: point ${k} must be [x, y] (two finite numbers), got ${JSON.stringify(p)}`);
    }
    if (p[0] < 0 || p[0] > 1 || p[1] < 0 || p[1] > 1) {
      throw new Error(`spline points: points must lie in [0, 1]^2, got ${JSON.stringify(p)} (point ${k})`);
    }
    return [p[0], p[1]];
  });
  P.sort((a, b) => a[0] - b[0]);
  for (let k = 1; k < P.length; k++) {
    if (P[k][0] === P[k - 1][0]) throw new Error(`spline points: points must have distinct x, got x = ${P[k][0]} twice`);
  }
  for (const [x, y] of [[0, 0], [1, 1]]) {
    const at = P.find((p) => p[0] === x);
    if (at && at[1] !== y) {
      throw new Error(`spline points: f(${x}) must be ${y} (endpoint weights stay 0 at a and 1 at b), ` +
                      `got the point ${JSON.stringify(at)}`);
    }
  }
  if (!P.length || P[0][0] !== 0) P.unshift([0, 0]);
  if (P[P.length - 1][0] !== 1) P.push([1, 1]);
  for (let k = 1; k < P.length; k++) {
    if (P[k][1] < P[k - 1][1]) {
      throw new Error(`spline points: points must be monotone (y non-decreasing in x), but y drops ` +
                      `from ${JSON.stringify(P[k - 1])} to ${JSON.stringify(P[k])}`);
    }
  }
  return P;
}

function edgeSlope(h0, h1, m0, m1) {      // scipy's PchipInterpolator._edge_case
  let d = ((2 * h0 + h1) * m0 - h0 * m1) / (h0 + h1);
  if (Math.sign(d) !== Math.sign(m0)) d = 0;
  else if (Math.sign(m0) !== Math.sign(m1) && Math.abs(d) > 3 * Math.abs(m0)) d = 3 * m0;
  return d;
}

/**
 * The filter of control points (any order, ends optional): a function [0, 1] -> [0, 1],
 * with .points (all, by x) and .identity.
 */
export function splineFilter(points) {
  const P = splinePoints(points), k = P.length;
  const x = P.map((p) => p[0]), y = P.map((p) => p[1]);
  const identity = k === 2 || P.every((p) => p[0] === p[1]);
  let f;
  if (identity) {
    f = (t) => Math.min(1, Math.max(0, t));
  } else {
    const h = [], m = [];
    for (let i = 0; i < k - 1; i++) { h.push(x[i + 1] - x[i]); m.push((y[i + 1] - y[i]) / h[i]); }
    const d = new Array(k).fill(0);
    if (k === 2) { d[0] = d[1] = m[0]; } else {
      for (let i = 1; i < k - 1; i++) {
        const a = m[i - 1], b = m[i];
        if (Math.sign(a) !== Math.sign(b) || a === 0 || b === 0) { d[i] = 0; continue; }
        const w1 = 2 * h[i] + h[i - 1], w2 = h[i] + 2 * h[i - 1];
        d[i] = 1 / ((w1 / a + w2 / b) / (w1 + w2));
      }
      d[0] = edgeSlope(h[0], h[1], m[0], m[1]);
      d[k - 1] = edgeSlope(h[k - 2], h[k - 3], m[k - 2], m[k - 3]);
    }
    f = (t) => {
      t = Math.min(1, Math.max(0, t));
      if (t === 0) return 0;
      if (t === 1) return 1;
      let i = 0;
      while (i < k - 2 && t >= x[i + 1]) i++;
      const s = t - x[i], hi = h[i];
      const c2 = (3 * m[i] - 2 * d[i] - d[i + 1]) / hi, c3 = (d[i] + d[i + 1] - 2 * m[i]) / (hi * hi);
      const v = ((c3 * s + c2) * s + d[i]) * s + y[i];
      return Math.min(1, Math.max(0, v));
    };
  }
  f.points = P;
  f.identity = identity;
  return f;
}

const PICK = 8;       // CSS pixels around a control point that grab it
const PAD = 10;       // canvas margin, CSS pixels

/** The curve editor on a canvas: drag points, click to add, double-click to remove. */
export class SplineEditor {
  /** @param onChange  called with the new inner points (ends excluded) on every edit */
  constructor(canvas, onChange) {
    this.canvas = canvas;
    this.onChange = onChange;
    this.points = [];          // inner points, by x
    this.drag = -1;
    canvas.addEventListener("pointerdown", (e) => this.onDown(e));
    canvas.addEventListener("pointermove", (e) => this.onMove(e));
    canvas.addEventListener("pointerup", (e) => this.onUp(e));
    canvas.addEventListener("pointercancel", (e) => this.onUp(e));
    canvas.addEventListener("dblclick", (e) => this.onDouble(e));
    this.draw();
  }

  set(inner) {
    this.points = inner.map((p) => [p[0], p[1]]);
    this.draw();
  }

  size() {
    const r = this.canvas.getBoundingClientRect();
    return { w: r.width || this.canvas.width, h: r.height || this.canvas.height, left: r.left, top: r.top };
  }

  toPx([x, y]) {
    const { w, h } = this.size();
    return [PAD + x * (w - 2 * PAD), h - PAD - y * (h - 2 * PAD)];
  }

  fromEvent(e) {
    const { w, h, left, top } = this.size();
    const x = (e.clientX - left - PAD) / (w - 2 * PAD), y = (h - PAD - (e.clientY - top)) / (h - 2 * PAD);
    return [Math.min(1, Math.max(0, x)), Math.min(1, Math.max(0, y))];
  }

  nearest(e) {
    const { left, top } = this.size();
    let best = -1, bestD = PICK;
    this.points.forEach((p, k) => {
      const [px, py] = this.toPx(p);
      const dd = Math.hypot(px - (e.clientX - left), py - (e.clientY - top));
      if (dd <= bestD) { best = k; bestD = dd; }
    });
    return best;
  }

  /** Keep point k strictly between its neighbours in x and between them in y. */
  constrain(k, [x, y]) {
    const all = [[0, 0], ...this.points, [1, 1]], prev = all[k], next = all[k + 2];
    const eps = 1e-3;
    x = Math.min(next[0] - eps, Math.max(prev[0] + eps, x));
    y = Math.min(next[1], Math.max(prev[1], y));
    return [x, y];
  }

  onDown(e) {
    if (e.button !== 0) return;
    e.preventDefault();
    let k = this.nearest(e);
    if (k < 0) {                  // add a point where the click is
      const [x, y] = this.fromEvent(e);
      if (x <= 1e-3 || x >= 1 - 1e-3 || this.points.some((p) => Math.abs(p[0] - x) < 2e-3)) return;
      k = this.points.findIndex((p) => p[0] > x);
      if (k < 0) k = this.points.length;
      this.points.splice(k, 0, [x, y]);
      this.points[k] = this.constrain(k, [x, y]);
      this.changed();
    }
    this.drag = k;
    try { this.canvas.setPointerCapture(e.pointerId); } catch (_) { /* synthetic */ }
  }

  onMove(e) {
    if (this.drag < 0) return;
    this.points[this.drag] = this.constrain(this.drag, this.fromEvent(e));
    this.changed();
  }

  onUp(e) {
    if (this.drag < 0) return;
    this.drag = -1;
    try { this.canvas.releasePointerCapture(e.pointerId); } catch (_) { /* synthetic */ }
  }

  onDouble(e) {
    const k = this.nearest(e);
    if (k < 0) return;
    this.points.splice(k, 1);
    this.changed();
  }

  changed() {
    this.draw();
    this.onChange(this.points.map((p) => [p[0], p[1]]));
  }

  draw() {
    const c = this.canvas, ctx = c.getContext("2d");
    if (!ctx) return;
    const dpr = window.devicePixelRatio || 1, { w, h } = this.size();
    if (c.width !== Math.round(w * dpr) || c.height !== Math.round(h * dpr)) {
      c.width = Math.round(w * dpr); c.height = Math.round(h * dpr);
    }
    ctx.setTransform(dpr, 0, 0, dpr, 0, 0);
    ctx.clearRect(0, 0, w, h);
    ctx.fillStyle = "rgba(10, 12, 16, 0.6)";
    ctx.fillRect(0, 0, w, h);
    ctx.strokeStyle = "rgba(255, 255, 255, 0.12)";
    ctx.lineWidth = 1;
    for (let g = 0; g <= 4; g++) {
      const [gx] = this.toPx([g / 4, 0]), [, gy] = this.toPx([0, g / 4]);
      ctx.beginPath(); ctx.moveTo(gx, PAD); ctx.lineTo(gx, h - PAD); ctx.stroke();
      ctx.beginPath(); ctx.moveTo(PAD, gy); ctx.lineTo(w - PAD, gy); ctx.stroke();
    }
    ctx.setLineDash([3, 3]);
    ctx.beginPath(); ctx.moveTo(...this.toPx([0, 0])); ctx.lineTo(...this.toPx([1, 1])); ctx.stroke();
    ctx.setLineDash([]);
    let f;
    try { f = splineFilter(this.points); } catch (_) { return; }
    ctx.strokeStyle = "#7fd4ff";
    ctx.lineWidth = 2;
    ctx.beginPath();
    for (let s = 0; s <= 100; s++) {
      const [px, py] = this.toPx([s / 100, f(s / 100)]);
      if (s === 0) ctx.moveTo(px, py); else ctx.lineTo(px, py);
    }
    ctx.stroke();
    for (const p of f.points) {
      const [px, py] = this.toPx(p), end = p[0] === 0 || p[0] === 1;
      ctx.fillStyle = end ? "#889" : "#fff";
      ctx.beginPath(); ctx.arc(px, py, end ? 3 : 4.5, 0, 2 * Math.PI); ctx.fill();
    }
  }
}
