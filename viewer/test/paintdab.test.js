import { test } from "node:test";
import assert from "node:assert/strict";
import { DabPainter } from "../src/paintdab.js";
import { RowLog } from "../src/weightrows.js";

// a 5 x 5 plate, spacing 1, v = 5 y + x, symmetric about x = 2; bones root (on the
// plane), arm.L and arm.R (mirror images); W[v] = (0.5, x / 8, (4 - x) / 8), so that
// arm.L at a vertex weighs what arm.R weighs at its mirror vertex (x -> 4 - x)
function page() {
  const V = [], F = [];
  for (let y = 0; y < 5; y++) for (let x = 0; x < 5; x++) V.push(x, y);
  for (let y = 0; y < 4; y++) {
    for (let x = 0; x < 4; x++) {
      const a = 5 * y + x;
      F.push(a, a + 1, a + 6, a, a + 6, a + 5);
    }
  }
  const n = 25, b = 3;
  const rig = { dim: 2, n, b, V: Float64Array.from(V), F, C: [2, 0, 2, 2, 0, 2, 4, 2], BE: [0, 1, 1, 2, 1, 3],
                names: ["root", "arm.L", "arm.R"], parents: [-1, 0, 0] };
  const W = new Float32Array(n * b), E = new Float32Array(n * b);
  for (let v = 0; v < n; v++) { const x = v % 5; W.set([0.5, x / 8, (4 - x) / 8], v * b); }
  const rest = new Float32Array(3 * n);
  for (let v = 0; v < n; v++) { rest[3 * v] = V[2 * v]; rest[3 * v + 1] = V[2 * v + 1]; }
  const log = new RowLog(n, b), locked = new Uint8Array(b);
  const painter = new DabPainter({ store: { rig, W, E } }, { rest, faces: Uint32Array.from(F) }, log, locked);
  return { painter, W, E, log, locked, n, b };
}

const BRUSH = { op: "add", radius: 1.5, strength: 0.5, falloff: "smooth" };
const at = (x, y) => 5 * y + x;
// the dab at (1, 2), radius 1.5 covers the centre (d = 0), its 4 edge neighbours (d = 1)
// and 4 diagonal ones (d^2 = 2); a = strength (1 - (d / r)^2)^2
const amount = (d2) => 0.5 * (1 - d2 / 2.25) ** 2;
const COVER = [[1, 2, 0], [0, 2, 1], [2, 2, 1], [1, 1, 1], [1, 3, 1], [0, 1, 2], [2, 1, 2], [0, 3, 2], [2, 3, 2]];
const sorted = (xs) => Array.from(xs).sort((p, q) => p - q);

test("a bone dab raises the bone in the ball, keeps rows summing to 1 and logs them", () => {
  const { painter, W, E, log, n, b } = page();
  const W0 = W.slice(), E0 = E.slice();
  const { rows, count, covered } = painter.dab([1, 2, 0], "bone", 1, BRUSH, false);
  assert.equal(covered, 9);
  assert.deepEqual(Array.from(rows.subarray(0, count)), sorted(COVER.map(([x, y]) => at(x, y))));
  for (const [x, y, d2] of COVER) {
    const v = at(x, y), t = x / 8 + amount(d2), rest = 1 - t;
    assert.equal(W[v * b + 1], Math.fround(t));
    // the other bones keep their proportions (root 0.5, arm.R (4 - x) / 8)
    assert.ok(Math.abs(W[v * b] - rest * 0.5 / (1 - x / 8)) < 1e-6);
    assert.ok(Math.abs(W[v * b + 2] - rest * ((4 - x) / 8) / (1 - x / 8)) < 1e-6);
  }
  for (let v = 0; v < n; v++) {
    assert.ok(Math.abs(W[v * b] + W[v * b + 1] + W[v * b + 2] - 1) < 1e-6);
    if (!rows.subarray(0, count).includes(v)) assert.deepEqual(W.subarray(v * b, v * b + b), W0.subarray(v * b, v * b + b));
  }
  assert.deepEqual(E, E0);
  const change = log.take(W, E);
  assert.deepEqual(Array.from(change.rows), Array.from(rows.subarray(0, count)));
  assert.deepEqual(change.Wb, Float32Array.from(Array.from(change.rows).flatMap((v) => Array.from(W0.subarray(v * b, v * b + b)))));
});

test("a locked bone keeps its weights bit for bit", () => {
  const { painter, W, locked, b } = page();
  const W0 = W.slice();
  locked[0] = 1;
  const { count } = painter.dab([1, 2, 0], "bone", 1, BRUSH, false);
  assert.equal(count, 9);
  for (let v = 0; v < 25; v++) {
    assert.equal(W[v * b], W0[v * b]);
    assert.ok(Math.abs(W[v * b] + W[v * b + 1] + W[v * b + 2] - 1) < 1e-6);
  }
});

test("an endpoint dab changes E's column only, and W not at all", () => {
  const { painter, W, E, b } = page();
  const W0 = W.slice();
  const { count } = painter.dab([1, 2, 0], "endpoint", 2, BRUSH, false);
  assert.equal(count, 9);
  const want = new Float32Array(E.length);
  for (const [x, y, d2] of COVER) want[at(x, y) * b + 2] = amount(d2);
  assert.deepEqual(E, want);
  assert.deepEqual(W, W0);
});

test("X-mirror paints the mirror bone at the mirror vertices by as much", () => {
  const { painter, W, b } = page();
  const { rows, count } = painter.dab([1, 2, 0], "bone", 1, BRUSH, true);
  // the ball's columns x = 0, 1, 2 and their mirrors x = 4, 3 (x = 2 is its own)
  const want = COVER.map(([x, y]) => at(x, y)).concat(COVER.filter(([x]) => x < 2).map(([x, y]) => at(4 - x, y)));
  assert.deepEqual(Array.from(rows.subarray(0, count)), sorted(want));
  for (let v = 0; v < 25; v++) {
    const x = v % 5, u = at(4 - x, Math.floor(v / 5));
    if (x !== 2) assert.deepEqual([W[v * b], W[v * b + 1], W[v * b + 2]], [W[u * b], W[u * b + 2], W[u * b + 1]]);
  }
  // on the plane both arms were painted, arm.L by the dab, arm.R by its mirror
  for (const y of [1, 2, 3]) assert.ok(W[at(2, y) * b + 1] > 0.25 && W[at(2, y) * b + 2] > 0.25);
});

test("X-mirror of a bone on the plane paints a vertex on the plane once", () => {
  const one = page(), two = page();
  one.painter.dab([1, 2, 0], "bone", 0, BRUSH, false);
  const { count } = two.painter.dab([1, 2, 0], "bone", 0, BRUSH, true);
  assert.equal(count, 15);
  for (const [x, y] of COVER) {
    const v = at(x, y);
    assert.deepEqual(two.W.subarray(v * 3, v * 3 + 3), one.W.subarray(v * 3, v * 3 + 3));
  }
});
