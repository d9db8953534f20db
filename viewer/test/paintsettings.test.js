import { test } from "node:test";
import assert from "node:assert/strict";
import { PAINT_KEYS, boneIndex, mergeSettings, scaledRadius } from "../src/paintsettings.js";

const NAMES = ["root", "arm.L", "arm.R"];
const S = { mode: "off", bone: 0, op: "add", radius: 0.5, strength: 0.25, falloff: "smooth" };

test("a bone is an index, a name or an index written as a string", () => {
  assert.equal(boneIndex(2, NAMES), 2);
  assert.equal(boneIndex("arm.L", NAMES), 1);
  assert.equal(boneIndex("2", NAMES), 2);
  for (const key of [3, -1, 1.5, "3", "leg", null, [1]]) {
    assert.throws(() => boneIndex(key, NAMES), (err) =>
      err.message === `bone: expected an index 0..2 or a bone name, got ${JSON.stringify(key)}`);
  }
});

test("setPaint's options make new settings; the old ones stay as they were", () => {
  const before = Object.assign({}, S);
  const s = mergeSettings(S, { mode: "bone", bone: "arm.R", op: "smooth", radius: 2, strength: 1,
                               falloff: "linear", mirror: true }, NAMES);
  assert.deepEqual(s, { mode: "bone", bone: 2, op: "smooth", radius: 2, strength: 1, falloff: "linear" });
  assert.deepEqual(S, before);
  assert.notEqual(mergeSettings(S, {}, NAMES), S);
  assert.deepEqual(mergeSettings(S, {}, NAMES), S);
  assert.deepEqual(mergeSettings(S, { strength: 0 }, NAMES), Object.assign({}, S, { strength: 0 }));
});

test("a bad option is an error naming it, the expectation and what arrived", () => {
  const cases = [
    [null, `setPaint: expected an object {${PAINT_KEYS.join(", ")}}, got null`],
    [[1], `setPaint: expected an object {${PAINT_KEYS.join(", ")}}, got [1]`],
    [{ size: 1 }, `setPaint: expected keys among ${PAINT_KEYS.join(", ")}, got "size"`],
    [{ mode: "pose" }, 'paint mode: expected one of off, bone, endpoint, got "pose"'],
    [{ bone: "leg" }, 'bone: expected an index 0..2 or a bone name, got "leg"'],
    [{ op: "blur" }, 'brush op: expected one of add, subtract, smooth, got "blur"'],
    [{ radius: 0 }, "brush radius: expected a positive number (the rig's units), got 0"],
    [{ radius: Infinity }, "brush radius: expected a positive number (the rig's units), got null"],
    [{ radius: "1" }, `brush radius: expected a positive number (the rig's units), got "1"`],
    [{ strength: 1.5 }, "brush strength: expected a number in [0, 1], got 1.5"],
    [{ strength: NaN }, "brush strength: expected a number in [0, 1], got null"],
    [{ falloff: "gauss" }, 'brush falloff: expected one of smooth, linear, constant, got "gauss"'],
    [{ mirror: 1 }, "mirror: expected true or false, got 1"],
    // every option is checked before any is taken: a good mode and a bad radius fail
    [{ mode: "bone", radius: -1 }, "brush radius: expected a positive number (the rig's units), got -1"],
  ];
  for (const [opts, message] of cases) {
    assert.throws(() => mergeSettings(S, opts, NAMES), (err) => err.message === message, JSON.stringify(opts));
  }
});

test("[ and ] scale the radius within [diag / 200, diag / 2]", () => {
  assert.equal(scaledRadius(1, 2, 10), 2);
  assert.equal(scaledRadius(4, 2, 10), 5);
  assert.equal(scaledRadius(0.06, 0.5, 10), 0.05);
});
