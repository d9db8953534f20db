import { test } from "node:test";
import assert from "node:assert/strict";
import { Brush, FALLOFF, adjacency } from "../src/brush.js";

// a 5 x 5 grid of vertices, spacing 1, two triangles per square; v = 5 y + x
function plate() {
  const V = [], F = [];
  for (let y = 0; y < 5; y++) for (let x = 0; x < 5; x++) V.push(x, y);
  for (let y = 0; y < 4; y++) {
    for (let x = 0; x < 4; x++) {
      const a = 5 * y + x;
      F.push(a, a + 1, a + 6, a, a + 6, a + 5);
    }
  }
  return { V: Float64Array.from(V), F: Int32Array.from(F) };
}

test("adjacency lists each neighbour once, sorted", () => {
  const { F } = plate();
  const nb = adjacency(F, 25);
  const of = (v) => Array.from(nb.ids.subarray(nb.start[v], nb.start[v + 1]));
  assert.deepEqual(of(0), [1, 5, 6]);
  assert.deepEqual(of(12), [6, 7, 11, 13, 17, 18]);
  assert.deepEqual(of(24), [18, 19, 23]);
  assert.deepEqual(Array.from(adjacency([0, 1, 1], 3).ids), [1, 0]);   // degenerate: no self loop
  assert.throws(() => adjacency([0, 1, 7], 3), /adjacency: F: expected vertex ids 0..2, got 7/);
});

test("falloffs by hand", () => {
  assert.equal(FALLOFF.smooth(0.5), 0.5625);
  assert.equal(FALLOFF.linear(0.25), 0.75);
  assert.equal(FALLOFF.constant(0.9), 1);
});

test("a dab covers the ball in rest space and adds, subtracts or smooths one column", () => {
  const { V, F } = plate(), b = 2;
  const brush = new Brush(V, 2, adjacency(F, 25));
  const X = new Float32Array(25 * b);
  for (let v = 0; v < 25; v++) { X[v * b] = 0.5; X[v * b + 1] = v / 24; }
  // centre (2, 2), radius 1.5: the centre, its 4 edge neighbours (d 1) and 4 diagonal (d 1.414)
  const m = brush.cover([2, 2], { radius: 1.5, strength: 0.4, falloff: "linear" });
  assert.equal(m, 9);
  const amt = new Map();
  for (let k = 0; k < m; k++) amt.set(brush.ids[k], brush.amount[k]);
  assert.equal(amt.get(12), 0.4);
  assert.ok(Math.abs(amt.get(7) - 0.4 * (1 - 1 / 1.5)) < 1e-15);
  assert.ok(Math.abs(amt.get(6) - 0.4 * (1 - Math.SQRT2 / 1.5)) < 1e-15);
  // add on column 0: 0.5 + a
  const k = brush.apply(X, b, 0, "add");
  assert.equal(k, 9);
  for (let q = 0; q < k; q++) assert.equal(brush.values[q], Math.fround(0.5 + amt.get(brush.ids[q])));
  // subtract clamps at 0: strength 1 at the centre takes 0.5 to 0
  brush.cover([2, 2], { radius: 0.5, strength: 1, falloff: "constant" });
  assert.equal(brush.apply(X, b, 0, "subtract"), 1);
  assert.deepEqual([brush.ids[0], brush.values[0]], [12, 0]);
  // smooth column 1 at vertex 0 with strength 1: the mean of its neighbours 1, 5, 6
  brush.cover([0, 0], { radius: 0.5, strength: 1, falloff: "constant" });
  assert.equal(brush.apply(X, b, 1, "smooth"), 1);
  assert.equal(brush.values[0], Math.fround((1 + 5 + 6) / 3 / 24));
  // a value already at the clamp does not count as a change
  X[12 * b] = 1;
  brush.cover([2, 2], { radius: 0.5, strength: 0.3, falloff: "constant" });
  assert.equal(brush.apply(X, b, 0, "add"), 0);
  assert.throws(() => brush.cover([0, 0], { radius: 1, strength: 1, falloff: "cubic" }),
                /brush falloff: expected one of smooth, linear, constant, got "cubic"/);
  assert.throws(() => brush.apply(X, b, 0, "blur"), /brush op: expected one of add, subtract, smooth, got "blur"/);
});

test("smoothing reads the values from before the dab", () => {
  const { V, F } = plate(), b = 1;
  const brush = new Brush(V, 2, adjacency(F, 25));
  const X = new Float32Array(25);
  X[12] = 1;
  brush.cover([2, 2], { radius: 1.1, strength: 1, falloff: "constant" });   // 12 and 7, 11, 13, 17
  const k = brush.apply(X, b, 0, "smooth");
  const got = new Map();
  for (let q = 0; q < k; q++) got.set(brush.ids[q], brush.values[q]);
  assert.equal(got.get(12), 0);                            // its neighbours were all 0
  assert.equal(got.get(7), Math.fround(1 / 6));            // 7's 6 neighbours: 12 had 1
  assert.equal(got.get(13), Math.fround(1 / 6));
});
