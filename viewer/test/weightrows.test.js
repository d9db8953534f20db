import { test } from "node:test";
import assert from "node:assert/strict";
import { RowLog, layoutRows, restoreRows, rowRanges, setBoneWeight } from "../src/weightrows.js";

const f = Math.fround;
const row = (W, b, v) => Array.from(W.subarray(v * b, (v + 1) * b));
const sum = (a) => a.reduce((s, x) => s + x, 0);
const near = (got, want, tol = 1e-7) => {
  assert.equal(got.length, want.length);
  got.forEach((x, k) => assert.ok(Math.abs(x - want[k]) <= tol, `${Array.from(got)} vs ${want}`));
};

test("setting a bone weight scales the other bones to keep the row summing to 1", () => {
  const W = Float32Array.from([0.5, 0.3, 0.2, 0]);
  assert.equal(setBoneWeight(W, 4, 0, 0, 0.8), true);
  // the others had 0.5 and get 0.2, in proportion 3 : 2
  near(row(W, 4, 0), [0.8, 0.3 * 0.4, 0.2 * 0.4, 0]);
  assert.ok(Math.abs(sum(row(W, 4, 0)) - 1) < 1e-6);
  assert.equal(setBoneWeight(W, 4, 0, 0, W[0]), false);     // no change
  assert.equal(setBoneWeight(Float32Array.from([1]), 1, 0, 0, 0.5), false);   // one bone
});

test("locked bones keep their weights bit for bit; the rest goes to unlocked bones", () => {
  const W = Float32Array.from([0.4, 0.3, 0.2, 0.1]);
  const locked = Uint8Array.from([0, 1, 0, 0]);
  assert.equal(setBoneWeight(W, 4, 0, 0, 0.5, { locked }), true);
  const r = row(W, 4, 0);
  assert.equal(r[1], f(0.3));
  // unlocked share 0.7: bone 0 gets 0.5, bones 2 and 3 share 0.2 as 2 : 1
  assert.ok(Math.abs(r[0] - 0.5) < 1e-7 && Math.abs(r[2] - 0.2 * 2 / 3) < 1e-7 && Math.abs(r[3] - 0.2 / 3) < 1e-7);
  // asking for more than the unlocked share gives the share
  setBoneWeight(W, 4, 0, 0, 1, { locked });
  assert.deepEqual(row(W, 4, 0).map((x) => Math.round(x * 1e6) / 1e6), [0.7, 0.3, 0, 0]);
  assert.equal(W[1], f(0.3));
  // painting a locked bone changes nothing
  const before = W.slice();
  assert.equal(setBoneWeight(W, 4, 0, 1, 0.9, { locked }), false);
  assert.deepEqual(W, before);
  // a row whose unlocked share is 0 does not change
  const W2 = Float32Array.from([0, 1, 0]);
  assert.equal(setBoneWeight(W2, 3, 0, 0, 0.5, { locked: Uint8Array.from([0, 1, 0]) }), false);
  assert.deepEqual(Array.from(W2), [0, 1, 0]);
  // no other unlocked bone: nothing to take the rest, no change
  const W3 = Float32Array.from([0.6, 0.4]);
  assert.equal(setBoneWeight(W3, 2, 0, 0, 0.2, { locked: Uint8Array.from([0, 1]) }), false);
});

test("weight taken from a bone that had it all goes by the neighbours, else parent, child, next", () => {
  const b = 3;
  // vertex 0 has all on bone 0; its neighbour 1 has bones 1 : 2 as 1 : 3
  const W = Float32Array.from([1, 0, 0, 0, 0.25, 0.75]);
  const nbrs = { start: Int32Array.from([0, 1, 2]), ids: Int32Array.from([1, 0]) };
  setBoneWeight(W, b, 0, 0, 0.6, { nbrs });
  assert.deepEqual(row(W, b, 0), [f(0.6), f(0.1), f(0.3)]);
  // no neighbours: the parent (bone 2 here)
  const W2 = Float32Array.from([1, 0, 0]);
  setBoneWeight(W2, b, 0, 0, 0.6, { parents: Int32Array.from([2, -1, -1]) });
  assert.deepEqual(row(W2, b, 0), [f(0.6), 0, f(0.4)]);
  // a root: its first child (bone 1 is the child of 0)
  const W3 = Float32Array.from([1, 0, 0]);
  setBoneWeight(W3, b, 0, 0, 0.5, { parents: Int32Array.from([-1, 0, 1]) });
  assert.deepEqual(row(W3, b, 0), [0.5, 0.5, 0]);
  // the parent locked: the next unlocked candidate
  const W4 = Float32Array.from([1, 0, 0]);
  setBoneWeight(W4, b, 0, 0, 0.5, { parents: Int32Array.from([2, -1, -1]), locked: Uint8Array.from([0, 0, 1]) });
  assert.deepEqual(row(W4, b, 0), [0.5, 0.5, 0]);
});

test("the four heaviest layout: heaviest first, ties to the lower bone, renormalised", () => {
  const b = 6;
  const W = Float32Array.from([0.1, 0.3, 0.1, 0.2, 0.2, 0.1,   0, 1, 0, 0, 0, 0]);
  const E = Float32Array.from([0.1, 0.2, 0.3, 0.4, 0.5, 0.6,   0, 0.7, 0, 0, 0, 0]);
  const I4 = new Float32Array(8), W4 = new Float32Array(8), E4 = new Float32Array(8);
  layoutRows(W, E, b, [0, 1], 2, I4, W4, E4);
  assert.deepEqual(Array.from(I4), [1, 3, 4, 0, 1, 0, 0, 0]);
  const s = 0.3 + 0.2 + 0.2 + 0.1;
  near(Array.from(W4), [0.3 / s, 0.2 / s, 0.2 / s, 0.1 / s, 1, 0, 0, 0]);
  assert.deepEqual(Array.from(E4), [0.2, 0.4, 0.5, 0.1, 0.7, 0, 0, 0].map(f));
  // a curve on bone 1 and a row as loaded: the loaded layout, E4 of its slots
  const loaded = { W: W.slice(), I4: Float32Array.from([4, 3, 1, 0, 1, 0, 0, 0]), W4: Float32Array.from([0.25, 0.25, 0.25, 0.25, 1, 0, 0, 0]) };
  const filters = [null, (e) => e * e, null, null, null, null];
  layoutRows(W, E, b, [0, 1], 2, I4, W4, E4, loaded, filters);
  assert.deepEqual(Array.from(I4), [4, 3, 1, 0, 1, 0, 0, 0]);
  near(Array.from(E4), [0.5, 0.4, 0.04, 0.1, 0.49, 0, 0, 0]);
});

test("the row log gives the changed rows before and after, and restores them bit for bit", () => {
  const n = 600, b = 3, W = new Float32Array(n * b), E = new Float32Array(n * b);
  for (let k = 0; k < n * b; k++) { W[k] = (k % 7) / 7; E[k] = (k % 5) / 5; }
  const W0 = W.slice(), E0 = E.slice(), log = new RowLog(n, b);
  for (const v of [500, 3, 3, 42, 7]) {              // more than its first buffer's rows later
    log.keep(W, E, v);
    W[v * b] += 0.5;
  }
  for (let v = 100; v < 400; v++) log.keep(W, E, v);       // kept, never changed
  E[42 * b + 2] = 0.125;
  const c = log.take(W, E);
  assert.deepEqual(Array.from(c.rows), [3, 7, 42, 500]);
  const W1 = W.slice(), E1 = E.slice();
  restoreRows(W, E, b, c, "before");
  assert.deepEqual(W, W0);
  assert.deepEqual(E, E0);
  restoreRows(W, E, b, c, "after");
  assert.deepEqual(W, W1);
  assert.deepEqual(E, E1);
  assert.equal(log.take(W, E), null);                      // emptied
  log.keep(W, E, 3);
  assert.equal(log.take(W, E), null);                      // kept again, unchanged
});

test("rows to upload ranges: near runs merged, at most `most` ranges", () => {
  assert.deepEqual(rowRanges([1, 2, 3, 10, 200], 5, 8), [[1, 11], [200, 201]]);
  assert.deepEqual(rowRanges([1, 2, 3, 10, 200], 4, 4), [[1, 4], [10, 11]]);
  const rows = Array.from({ length: 100 }, (_, k) => k * 100 + (k > 50 ? 5000 : 0));
  const r = rowRanges(rows, rows.length, 1, 2);
  assert.deepEqual(r, [[0, 5001], [10100, 14901]]);
  for (const v of rows) assert.ok(r.some(([a, e]) => v >= a && v < e));
});
