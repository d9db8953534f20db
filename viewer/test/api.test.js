import { test } from "node:test";
import assert from "node:assert/strict";
import { bonesFromRows } from "../src/api.js";

test("binary bone rows read as the JSON form of a pose's bones (3D: 15 values a bone)", () => {
  // bone 0: a quarter turn about z, a' = (1, 2, 3), sigma 1.5, twist (0.25, -0.5);
  // bone 1: the identity at the origin
  const rows = Float64Array.from([0, -1, 0, 1, 0, 0, 0, 0, 1, 1, 2, 3, 1.5, 0.25, -0.5,
                                  1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0]);
  const got = bonesFromRows(rows.buffer, 2);
  assert.deepEqual(got.rotations[0], [[0, -1, 0], [1, 0, 0], [0, 0, 1]]);
  assert.deepEqual(got.origins, [[1, 2, 3], [0, 0, 0]]);
  assert.deepEqual(got.stretch, [1.5, 1]);
  assert.deepEqual(got.twist, [[0.25, -0.5], [0, 0]]);
});

test("2D rows have 9 values a bone; a wrong length is an error naming it", () => {
  const rows = Float64Array.from([0, -1, 1, 0, 4, 5, 2, 0, 0]);
  const got = bonesFromRows(rows.buffer, 1);
  assert.deepEqual(got.rotations, [[[0, -1], [1, 0]]]);
  assert.deepEqual(got.origins, [[4, 5]]);
  assert.deepEqual(got.stretch, [2]);
  assert.throws(() => bonesFromRows(new Float64Array(10).buffer, 1), /expected 1 rows of 9 or 15/);
});
