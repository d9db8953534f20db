import { test } from "node:test";
import assert from "node:assert/strict";
import { EndpointCurves, rowsWith } from "../src/paintcurve.js";

test("a bone's curve is the identity until one is set; the identity is kept as none", () => {
  const c = new EndpointCurves(3);
  assert.deepEqual(c.points(1), [[0, 0], [1, 1]]);
  assert.deepEqual(c.values(1, [0, 0.3, 1]), [0, 0.3, 1]);
  const f = c.set(1, [[0.5, 0.25]]);
  assert.deepEqual(f.points, [[0, 0], [0.5, 0.25], [1, 1]]);
  assert.deepEqual(c.points(1), [[0, 0], [0.5, 0.25], [1, 1]]);
  assert.equal(c.filters[1], f);
  assert.equal(c.filters[0], null);
  // through its points, whatever is between them
  assert.deepEqual(c.values(1, [0, 0.5, 1]), [0, 0.25, 1]);
  c.set(1, [[0.5, 0.5]]);                      // on the diagonal: the identity
  assert.equal(c.filters[1], null);
  assert.throws(() => c.set(0, [[0.2, 0.5], [0.6, 0.1]]), /monotone/);
  assert.equal(c.filters[0], null);
});

test("points() gives copies: changing them changes no curve", () => {
  const c = new EndpointCurves(1);
  c.set(0, [[0.5, 0.25]]);
  c.points(0)[1][1] = 0.9;
  assert.deepEqual(c.points(0)[1], [0.5, 0.25]);
});

test("baking gives f of the bone's column of E and drops the curve", () => {
  const c = new EndpointCurves(2), b = 2;
  // E rows (bone 0, bone 1): bone 1's column is 0, 0.5, 1
  const E = Float32Array.from([0.7, 0, 0.7, 0.5, 0.7, 1]);
  assert.equal(c.bake(1, E, 3, b), null);      // no curve: nothing to bake
  c.set(1, [[0.5, 0.25]]);
  const col = c.bake(1, E, 3, b);
  assert.ok(col instanceof Float64Array);
  assert.deepEqual(Array.from(col), [0, 0.25, 1]);
  assert.deepEqual(E, Float32Array.from([0.7, 0, 0.7, 0.5, 0.7, 1]));   // E is the editor's to write
  assert.equal(c.filters[1], null);
  assert.equal(c.bake(1, E, 3, b), null);
});

test("rowsWith: the rows where a bone has weight", () => {
  const W = Float32Array.from([1, 0, 0.5, 0.5, 0, 1, 0.25, 0.75]);
  assert.deepEqual(rowsWith(W, 4, 2, 0), Int32Array.from([0, 1, 3]));
  assert.deepEqual(rowsWith(W, 4, 2, 1), Int32Array.from([1, 2, 3]));
});
