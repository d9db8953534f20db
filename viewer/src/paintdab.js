// One dab of the weight brush on the store's W or E, without the page: the brush's cover
// (brush.js), a bone weight set with the row kept summing to 1 and locked bones kept
// (weightrows.js setBoneWeight), and with X-mirror the same dab on the mirror bone at
// the mirror vertices (mirror.js). Every row is logged (RowLog.keep) before it changes,
// so the editor can take the stroke's change as one History command. No DOM, no WebGL:
// the editor uploads the rows a dab returns.

import { Brush, adjacency } from "./brush.js";
import { setBoneWeight } from "./weightrows.js";
import { centreX, mirrorBones, mirrorVertices } from "./mirror.js";

export class DabPainter {
  /**
   * @param ctx   the page's context; its store holds the rig and W and E (n x b
   *              Float32Arrays, row-major), edited here in place
   * @param mesh  {rest: n x 3 rest positions (flat), faces: f x 3 vertex ids (flat)}
   * @param log   the editor's RowLog: each row is kept in it before it changes
   * @param locked  the editor's locks (Uint8Array b, read here): a locked bone's
   *              weight never changes
   */
  constructor(ctx, { rest, faces }, log, locked) {
    const { store } = ctx;
    this.rig = store.rig;
    this.W = store.W;
    this.E = store.E;
    this.n = store.rig.n;
    this.b = store.rig.b;
    this.rest = rest;
    this.log = log;
    this.locked = locked;
    this.parents = Int32Array.from(store.rig.parents || new Array(this.b).fill(-1));
    this.nbrs = adjacency(faces, this.n);
    this.brush = new Brush(rest, 3, this.nbrs);
    this.scratch = new Float64Array(2 * this.b);
    this.changed = new Int32Array(1024);      // the rows a dab changed (reused, grown)
    this.stamp = new Int32Array(this.n);      // per vertex: the dab that last took it
    this.dabCount = 0;
    this.mirrorMaps = null;
  }

  /** The X-mirror's maps (made when first needed): bone -> bone, vertex -> vertex. */
  mirror() {
    if (!this.mirrorMaps) {
      const rig = this.rig, centre = centreX(rig.V, rig.dim);
      this.mirrorMaps = { bones: mirrorBones(rig, { centre }),
                          vertices: mirrorVertices(this.rest, 3, { centre, grid: this.brush.grid }) };
    }
    return this.mirrorMaps;
  }

  /**
   * One dab at a rest point on column i of W (mode "bone") or E.
   *
   * @param centre  the dab's centre at rest [x, y, z]
   * @param mode    "bone" or "endpoint"
   * @param i       the bone painted
   * @param brush   {op, radius, strength, falloff}
   * @param mirror  also paint the mirror bone at the mirror vertices
   * @returns {rows, count, covered}: the changed rows (sorted, each once; rows[0..count),
   *   a view the next dab reuses) and how many vertices the brush covered
   */
  dab(centre, mode, i, brush, mirror) {
    const stamp = ++this.dabCount, cover = this.brush;
    const covered = cover.cover(centre, brush);
    let mids = null, mamt = null, mcount = 0, j = i;
    if (mirror) {
      // the mirror vertices of the cover, each once (the largest amount), for the mirror
      // bone; where that is the same bone, vertices the dab covers itself are left out
      const maps = this.mirror();
      j = maps.bones[i];
      mids = new Int32Array(cover.count); mamt = new Float64Array(cover.count);
      const own = j === i ? stamp : -1, slot = new Map();
      if (own > 0) for (let q = 0; q < cover.count; q++) this.stamp[cover.ids[q]] = own;
      for (let q = 0; q < cover.count; q++) {
        const u = maps.vertices[cover.ids[q]], a = cover.amount[q];
        if (this.stamp[u] === own) continue;
        const k = slot.get(u);
        if (k === undefined) { slot.set(u, mcount); mids[mcount] = u; mamt[mcount++] = a; } else if (a > mamt[k]) mamt[k] = a;
      }
    }
    let count = this.paintCover(mode, i, brush.op, 0);
    if (mcount) {
      cover.ids.set(mids.subarray(0, mcount));
      cover.amount.set(mamt.subarray(0, mcount));
      cover.count = mcount;
      count = this.paintCover(mode, j, brush.op, count);
    }
    const rows = this.changed.subarray(0, count).sort();
    let m = 0;                       // a vertex painted twice (mirror) counts once
    for (let q = 0; q < count; q++) if (q === 0 || rows[q] !== rows[q - 1]) rows[m++] = rows[q];
    return { rows, count: m, covered };
  }

  /**
   * Paint column i of W (mode "bone") or E with the brush's current cover (ids,
   * amount); the changed vertices are added to this.changed from `count`; returns the
   * new count.
   */
  paintCover(mode, i, op, count) {
    const cover = this.brush, b = this.b;
    const m = cover.apply(mode === "bone" ? this.W : this.E, b, i, op);
    const opts = { locked: this.locked, nbrs: this.nbrs, parents: this.parents, scratch: this.scratch };
    for (let q = 0; q < m; q++) {
      const v = cover.ids[q], t = cover.values[q];
      this.log.keep(this.W, this.E, v);
      if (mode === "bone") {
        if (setBoneWeight(this.W, b, v, i, t, opts)) count = this.mark(v, count);
      } else {
        this.E[v * b + i] = t;
        count = this.mark(v, count);
      }
    }
    return count;
  }

  /** Remember a changed vertex of this dab (growing the reusable list). */
  mark(v, count) {
    if (count === this.changed.length) {
      const c = new Int32Array(2 * count);
      c.set(this.changed);
      this.changed = c;
    }
    this.changed[count] = v;
    return count + 1;
  }
}
