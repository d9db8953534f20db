// Rows of the weight matrices, without the page: setting one bone weight with the row
// kept summing to 1 (locked bones untouched), the four-heaviest layout the shader
// draws (I4, W4, E4), and the log of rows a stroke changed (for its undo). Pure: no
// DOM, no WebGL. W and E are n x b Float32Arrays, row-major.

/**
 * W[v, i] = t with row v summing to 1, locked bones' weights kept bit for bit.
 *
 * The unlocked share of the row is 1 - (the locked bones' weights). t is clamped to
 * it; the other unlocked bones are scaled by (share - t) / (their sum), so they keep
 * their proportions. Where they have nothing (and t < share), share - t goes to the
 * unlocked other bones in the proportions of the vertex's neighbours' weights for
 * them; if those have none either, to the bone's parent, else its first child, else
 * the next bone (the first unlocked of these). Painting a locked bone, a row whose
 * unlocked share is 0, or one with no other unlocked bone changes nothing.
 *
 * @param W     n x b weights (changed in place)
 * @param b     bones
 * @param v     vertex
 * @param i     bone painted
 * @param t     its new weight, in [0, 1]
 * @param opts  {locked?: Uint8Array(b), nbrs?: {start, ids} (brush.adjacency),
 *               parents?: Int32Array(b), scratch?: Float64Array(2 b)}
 * @returns whether the row changed
 */
export function setBoneWeight(W, b, v, i, t, opts = {}) {
  const { locked = null, nbrs = null, parents = null } = opts;
  if (b === 1 || (locked && locked[i])) return false;
  const o = v * b;
  let lockedSum = 0, others = 0, freeOthers = 0;
  for (let j = 0; j < b; j++) {
    if (j === i) continue;
    if (locked && locked[j]) lockedSum += W[o + j];
    else { others += W[o + j]; freeOthers++; }
  }
  const share = 1 - lockedSum;
  if (!(share > 0) || freeOthers === 0) return false;
  if (t > share) t = share;
  if (t < 0) t = 0;
  if (Math.fround(t) === W[o + i]) return false;
  const row = opts.scratch && opts.scratch.length >= 2 * b ? opts.scratch : new Float64Array(2 * b);
  for (let j = 0; j < b; j++) row[j] = W[o + j];
  row[i] = t;
  const free = (j) => j !== i && !(locked && locked[j]);
  if (others > 0) {
    const k = (share - t) / others;
    for (let j = 0; j < b; j++) if (free(j)) row[j] *= k;
  } else if (t < share) {
    const part = row.subarray(b, 2 * b);
    part.fill(0);
    let total = 0;
    if (nbrs) {
      for (let p = nbrs.start[v]; p < nbrs.start[v + 1]; p++) {
        const u = nbrs.ids[p] * b;
        for (let j = 0; j < b; j++) if (free(j)) { part[j] += W[u + j]; total += W[u + j]; }
      }
    }
    if (!(total > 0)) {
      const cands = [];
      if (parents && parents[i] >= 0) cands.push(parents[i]);
      if (parents) { const c = Array.prototype.indexOf.call(parents, i); if (c >= 0) cands.push(c); }
      for (let s = 1; s < b; s++) cands.push((i + s) % b);
      const j = cands.find(free);
      part[j] = 1;
      total = 1;
    }
    for (let j = 0; j < b; j++) if (free(j)) row[j] = (share - t) * part[j] / total;
  }
  // the unlocked entries to float32, scaled so that they sum to the share (the locked
  // ones are written back as they were)
  let sum = 0;
  for (let j = 0; j < b; j++) if (!(locked && locked[j])) sum += row[j];
  const k = sum > 0 ? share / sum : 1;
  let same = true;
  for (let j = 0; j < b; j++) {
    if (locked && locked[j]) continue;
    const w = Math.fround(row[j] * k);
    if (w !== W[o + j]) { same = false; W[o + j] = w; }
  }
  return !same;
}

/**
 * The four heaviest bones of rows (heaviest first, ties to the lower bone index, as
 * stbs.skinning.top_k), their weights renormalised and their endpoint weights f(E)
 * clamped to [0, 1], written into I4, W4, E4 (n x 4). A row whose W equals `loaded.W`
 * keeps the layout `loaded.I4`, `loaded.W4` (the server's, made from the rig's float64
 * weights, where near-ties among the heaviest bones fall as the library's).
 *
 * @param rows   vertex ids (Int32Array or array); `count` of them are used
 * @param filters  per bone null or f(e) (the endpoint curve previewed)
 * @returns nothing; I4, W4, E4 changed in place
 */
export function layoutRows(W, E, b, rows, count, I4, W4, E4, loaded = null, filters = null) {
  const top = [0, 0, 0, 0], tw = [0, 0, 0, 0];
  const endOf = (r, j) => {
    const e = E[r * b + j], f = filters && filters[j];
    const x = f ? f(e) : e;
    return x < 0 ? 0 : x > 1 ? 1 : x;
  };
  for (let q = 0; q < count; q++) {
    const r = rows[q], o = r * b;
    if (loaded) {
      let same = true;
      for (let j = 0; j < b && same; j++) same = W[o + j] === loaded.W[o + j];
      if (same) {
        for (let c = 0; c < 4; c++) {
          const s = 4 * r + c;
          I4[s] = loaded.I4[s]; W4[s] = loaded.W4[s];
          E4[s] = W4[s] > 0 ? endOf(r, I4[s]) : 0;
        }
        continue;
      }
    }
    let k = 0;
    for (let j = 0; j < b; j++) {          // insertion into the 4 heaviest, earlier bone first on ties
      const w = W[o + j];
      if (!(w > 0)) continue;
      if (k === 4 && w <= tw[3]) continue;
      let p = k < 4 ? k++ : 3;
      while (p > 0 && tw[p - 1] < w) { tw[p] = tw[p - 1]; top[p] = top[p - 1]; p--; }
      tw[p] = w; top[p] = j;
    }
    let s = 0;
    for (let c = 0; c < k; c++) s += tw[c];
    for (let c = 0; c < 4; c++) {
      const x = 4 * r + c;
      if (c < k) { I4[x] = top[c]; W4[x] = tw[c] / s; E4[x] = endOf(r, top[c]); } else { I4[x] = 0; W4[x] = 0; E4[x] = 0; }
    }
  }
}

/**
 * The rows of W and E as they were before a change (a stroke, a recompute), kept the
 * first time each row is touched, in one growing buffer: a dab allocates nothing once
 * the buffer is large enough.
 */
export class RowLog {
  constructor(n, b) {
    this.n = n;
    this.b = b;
    this.slot = new Int32Array(n).fill(-1);
    this.rows = new Int32Array(256);
    this.saved = new Float32Array(256 * 2 * b);
    this.count = 0;
  }

  /** Keep row v of W and E unless it is kept already. */
  keep(W, E, v) {
    if (this.slot[v] >= 0) return;
    const b = this.b, k = this.count;
    if (k === this.rows.length) {
      const rows = new Int32Array(2 * k), saved = new Float32Array(2 * k * 2 * b);
      rows.set(this.rows); saved.set(this.saved);
      this.rows = rows; this.saved = saved;
    }
    this.slot[v] = k;
    this.rows[k] = v;
    this.saved.set(W.subarray(v * b, (v + 1) * b), 2 * b * k);
    this.saved.set(E.subarray(v * b, (v + 1) * b), 2 * b * k + b);
    this.count = k + 1;
  }

  /**
   * The change since the rows were kept, as {rows (sorted), Wb, Eb, Wa, Ea} (before and
   * after, m x b each) over the rows that differ, or null; the log is then empty.
   */
  take(W, E) {
    const b = this.b, changed = [];
    for (let k = 0; k < this.count; k++) {
      const v = this.rows[k], o = 2 * b * k;
      for (let j = 0; j < b; j++) {
        if (this.saved[o + j] !== W[v * b + j] || this.saved[o + b + j] !== E[v * b + j]) { changed.push(k); break; }
      }
    }
    changed.sort((p, q) => this.rows[p] - this.rows[q]);
    const m = changed.length;
    let out = null;
    if (m) {
      out = { rows: new Int32Array(m), Wb: new Float32Array(m * b), Eb: new Float32Array(m * b),
              Wa: new Float32Array(m * b), Ea: new Float32Array(m * b) };
      changed.forEach((k, q) => {
        const v = this.rows[k], o = 2 * b * k;
        out.rows[q] = v;
        out.Wb.set(this.saved.subarray(o, o + b), q * b);
        out.Eb.set(this.saved.subarray(o + b, o + 2 * b), q * b);
        out.Wa.set(W.subarray(v * b, (v + 1) * b), q * b);
        out.Ea.set(E.subarray(v * b, (v + 1) * b), q * b);
      });
    }
    for (let k = 0; k < this.count; k++) this.slot[this.rows[k]] = -1;
    this.count = 0;
    return out;
  }
}

/** Write a change's rows back: which = "before" or "after". */
export function restoreRows(W, E, b, change, which) {
  const Wx = which === "before" ? change.Wb : change.Wa, Ex = which === "before" ? change.Eb : change.Ea;
  for (let q = 0; q < change.rows.length; q++) {
    const v = change.rows[q];
    W.set(Wx.subarray(q * b, (q + 1) * b), v * b);
    E.set(Ex.subarray(q * b, (q + 1) * b), v * b);
  }
}

/**
 * Sorted vertex ids -> ranges [start, end) of vertex ids to upload, runs closer than
 * `gap` merged and at most `most` ranges (the closest runs merged first).
 */
export function rowRanges(rows, count, gap = 64, most = 32) {
  const out = [];
  for (let q = 0; q < count; q++) {
    const v = rows[q], last = out[out.length - 1];
    if (last && v < last[1] + gap) { if (v + 1 > last[1]) last[1] = v + 1; } else out.push([v, v + 1]);
  }
  if (out.length <= most) return out;
  // merge across the smallest gaps: every gap up to the one that leaves `most` ranges
  const gaps = new Float64Array(out.length - 1);
  for (let k = 1; k < out.length; k++) gaps[k - 1] = out[k][0] - out[k - 1][1];
  const limit = gaps.slice().sort()[out.length - most - 1];
  const merged = [out[0]];
  for (let k = 1; k < out.length; k++) {
    if (gaps[k - 1] <= limit) merged[merged.length - 1][1] = out[k][1]; else merged.push(out[k]);
  }
  return merged;
}
