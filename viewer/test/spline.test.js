import { test } from "node:test";
import assert from "node:assert/strict";
import { splineFilter, splinePoints } from "../src/spline.js";

test("the curve passes through its points, ends fixed at 0 and 1, and is monotone", () => {
  const pts = [[0.2, 0.05], [0.5, 0.3], [0.8, 0.95]];
  const f = splineFilter(pts);
  assert.equal(f.identity, false);
  for (const [x, y] of pts) assert.ok(Math.abs(f(x) - y) < 1e-12, `f(${x}) = ${f(x)}, not ${y}`);
  assert.equal(f(0), 0);
  assert.equal(f(1), 1);
  assert.equal(f(-3), 0);
  assert.equal(f(7), 1);
  let prev = -1;
  for (let k = 0; k <= 1000; k++) {
    const v = f(k / 1000);
    assert.ok(v >= prev && v >= 0 && v <= 1, `not monotone in [0, 1] at ${k / 1000}`);
    prev = v;
  }
  // a flat run between equal values stays flat (PCHIP's zero slope at a local extremum)
  const g = splineFilter([[0.3, 0.4], [0.6, 0.4]]);
  for (const x of [0.35, 0.45, 0.55]) assert.ok(Math.abs(g(x) - 0.4) < 1e-12, `g(${x}) = ${g(x)}`);
  assert.equal(splineFilter([]).identity, true);
  assert.equal(splineFilter([[0.3, 0.3]])(0.7), 0.7);
});

test("bad control points are errors naming the point and the rule", () => {
  assert.throws(() => splinePoints("x"), /expected an array of \[x, y\] pairs, got "x"/);
  assert.throws(() => splinePoints([[0.5]]), /point 0 must be \[x, y\]/);
  assert.throws(() => splinePoints([[1.5, 0.5]]), /must lie in \[0, 1\]\^2, got \[1.5,0.5\]/);
  assert.throws(() => splinePoints([[0.5, 0.1], [0.5, 0.2]]), /distinct x, got x = 0.5 twice/);
  assert.throws(() => splinePoints([[0, 0.2]]), /f\(0\) must be 0/);
  assert.deepEqual(splinePoints([[0.6, 0.7], [0.2, 0.1]]), [[0, 0], [0.2, 0.1], [0.6, 0.7], [1, 1]]);
});
