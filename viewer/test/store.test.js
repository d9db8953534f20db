import { test } from "node:test";
import assert from "node:assert/strict";
import { Events } from "../src/events.js";
import { Store } from "../src/store.js";

function store(b = 3) {
  const events = new Events(), seen = [];
  for (const name of ["rig", "select", "mode", "mirror", "brush", "weights", "pose"]) {
    events.on(name, (p) => seen.push([name, p]));
  }
  const s = new Store(events);
  s.setRig({ dim: 3, n: 2, b });
  seen.length = 0;
  return { s, seen };
}

test("each setter changes its field and emits its event once per change", () => {
  const { s, seen } = store();
  assert.equal(s.select(2), 2);
  s.select(2);                                 // no change: no event
  s.setMode("paint");
  s.setMirror(true);
  s.setBrush({ radius: 0.5 });
  assert.deepEqual(s.selection, { bone: 2 });
  assert.equal(s.mode, "paint");
  assert.equal(s.mirror, true);
  assert.equal(s.brush.radius, 0.5);
  assert.equal(s.brush.op, "add");
  assert.deepEqual(seen.map(([n]) => n), ["select", "mode", "mirror", "brush"]);
  assert.deepEqual(seen[0][1], { bone: 2 });
  assert.deepEqual(seen[1][1], { mode: "paint" });
  assert.deepEqual(seen[2][1], { on: true });
  s.select(null);
  assert.deepEqual(seen.at(-1), ["select", { bone: null }]);
});

test("bad values are errors naming the input and what arrived, and change nothing", () => {
  const { s, seen } = store(3);
  assert.throws(() => s.select(3), /bone: expected a bone index 0\.\.2 or null, got 3/);
  assert.throws(() => s.select("hip"), /got "hip"/);
  assert.throws(() => s.setMode("sculpt"), /mode: expected one of pose, paint, got "sculpt"/);
  assert.throws(() => s.setMirror(1), /mirror: expected true or false, got 1/);
  assert.throws(() => s.setBrush({ size: 1 }), /brush: expected settings among .*got "size"/);
  assert.throws(() => s.setPose({}), /store.setPose/);
  assert.throws(() => s.setWeights(new Float32Array(5), new Float32Array(6)),
                /W: expected a Float32Array of 6 values, got "Float32Array of 5"/);
  assert.equal(s.selection.bone, null);
  assert.equal(s.mode, "pose");
  assert.equal(s.mirror, false);
  assert.deepEqual(seen, []);
});

test("setPose keeps its own copy of the pose object; weights announce their rows", () => {
  const { s, seen } = store();
  const object = { rotate: { a: { angle: 10 } } };
  const arrays = { rotations: [], origins: [], stretch: [], twist: [] };
  s.setPose(arrays, object);
  object.rotate.a.angle = 20;
  assert.equal(s.poseObject.rotate.a.angle, 10);
  assert.equal(s.pose, arrays);
  s.setPose(arrays);                          // arrays alone (a played frame): object kept
  assert.equal(s.poseObject.rotate.a.angle, 10);
  const W = new Float32Array(6), E = new Float32Array(6);
  s.setWeights(W, E);
  s.weightsChanged([1]);
  assert.deepEqual(seen.filter(([n]) => n === "weights").map(([, p]) => p), [{ rows: null }, { rows: [1] }]);
});
