import { test } from "node:test";
import assert from "node:assert/strict";
import { castRay } from "../src/pick.js";

// the unit square at z = 0 (two triangles), posed; at rest the same square moved by
// (10, 20, 30) and doubled, so that the rest point tells the barycentric coordinates
const U = Float32Array.from([0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0]);
const F = Uint32Array.from([0, 1, 2, 0, 2, 3]);
const R = Float32Array.from(Array.from(U, (x, k) => 2 * x + [10, 20, 30][k % 3]));
const down = { x: 0, y: 0, z: -1 };

test("a ray down onto the square hits the triangle under it, at rest and posed", () => {
  const hit = castRay({ x: 0.75, y: 0.25, z: 5 }, down, U, F, R);
  assert.equal(hit.face, 0);                 // (0.75, 0.25) lies in 0-1-2: below the diagonal
  assert.equal(hit.t, 5);
  // on 0-1-2: p = (1 - u - v) P0 + u P1 + v P2 = (u + v, v): u = 0.5, v = 0.25
  assert.equal(hit.u, 0.5);
  assert.equal(hit.v, 0.25);
  assert.deepEqual(hit.posed, [0.75, 0.25, 0]);
  assert.deepEqual(hit.rest, [11.5, 20.5, 30]);
  assert.deepEqual(hit.normal, [0, 0, 1]);   // (P1 - P0) x (P2 - P0)
  const other = castRay({ x: 0.25, y: 0.75, z: 5 }, down, U, F, R);
  assert.equal(other.face, 1);
  assert.deepEqual(other.posed, [0.25, 0.75, 0]);
});

test("both sides are hit; t counts in the direction's units", () => {
  const hit = castRay({ x: 0.5, y: 0.25, z: -2 }, { x: 0, y: 0, z: 4 }, U, F, R);
  assert.equal(hit.face, 0);
  assert.equal(hit.t, 0.5);
  assert.deepEqual(hit.posed, [0.5, 0.25, 0]);
});

test("misses: beside the square, behind the origin, along its plane", () => {
  assert.equal(castRay({ x: 1.5, y: 0.5, z: 5 }, down, U, F, R), null);
  assert.equal(castRay({ x: 0.5, y: 0.25, z: -5 }, down, U, F, R), null);
  assert.equal(castRay({ x: -1, y: 0.5, z: 0 }, { x: 1, y: 0, z: 0 }, U, F, R), null);
  assert.equal(castRay({ x: 0.5, y: 0.5, z: 5 }, down, U, new Uint32Array(0), R), null);
});

test("of two layers the nearer is hit, whichever comes first in F", () => {
  // a second square at z = 1 (vertices 4..7), listed before and after the first
  const U2 = Float32Array.from([...U, ...Array.from(U, (x, k) => (k % 3 === 2 ? 1 : x))]);
  const R2 = Float32Array.from([...R, ...R]);
  const top = [4, 5, 6, 4, 6, 7];
  for (const [Fs, face] of [[[...F, ...top], 2], [[...top, ...F], 0]]) {
    const hit = castRay({ x: 0.75, y: 0.25, z: 5 }, down, U2, Uint32Array.from(Fs), R2);
    assert.equal(hit.face, face);
    assert.equal(hit.t, 4);
    assert.deepEqual(hit.posed, [0.75, 0.25, 1]);
  }
});
