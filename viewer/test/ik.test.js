import { test } from "node:test";
import assert from "node:assert/strict";
import { Vector3 } from "three";
import { axisAngle, Bones, copyWorld, fabrik, minRotation, mirrorEdit, rows, worldJSON } from "../src/ik.js";
import { restFrames, restPose } from "../src/pose.js";

const close = (a, b, tol = 1e-9) => assert.ok(Math.abs(a - b) <= tol, `${a} != ${b}`);
const closeV = (u, v, tol = 1e-9) => [0, 1, 2].forEach((k) => close(u.getComponent(k), v.getComponent(k), tol));

/** A store holding a rig (C j x dim, BE, parents) at its rest pose. */
function store(C, BE, parents, dim, names = null) {
  const b = BE.length / 2, rest = restFrames(C, BE, dim);
  return { rig: { dim, b, n: 0, C, BE, restC: C, rest, parents, connected: null, hang: null,
                  names: names || Array.from({ length: b }, (_, i) => String(i)) },
           pose: restPose(rest, dim) };
}

// a 3D chain of three bones along x: joints 0-1-2-3
const chain = () => store(Float64Array.from([0, 0, 0, 1, 0, 0, 2, 0, 0, 3, 0, 0]), [0, 1, 1, 2, 2, 3], [-1, 0, 1], 3);

test("minRotation takes one direction to another; opposite directions in the plane turn about z", () => {
  const u = new Vector3(0.3, -1.2, 0.5), v = new Vector3(-2, 0.1, 0.7);
  const got = u.clone().applyMatrix3(minRotation(u, v)).normalize();
  closeV(got, v.clone().normalize(), 1e-12);
  const M = rows(minRotation(new Vector3(1, 2, 0), new Vector3(-1, -2, 0)));
  assert.deepEqual([M[0][2], M[1][2], M[2][0], M[2][1], M[2][2]], [0, 0, 0, 0, 1]);
  closeV(new Vector3(1, 2, 0).applyMatrix3(minRotation(new Vector3(1, 2, 0), new Vector3(-1, -2, 0))),
         new Vector3(-1, -2, 0), 1e-12);
  // axisAngle: a quarter turn about z takes x to y
  closeV(new Vector3(1, 0, 0).applyMatrix3(axisAngle([0, 0, 2], Math.PI / 2)), new Vector3(0, 1, 0), 1e-15);
});

test("a stretch drag moves one joint; the bones at it turn and stretch, the other joints stay", () => {
  const s = chain(), bones = new Bones(s), w = bones.world();
  const at = new Vector3(1.5, 1, 0.25);
  const out = bones.stretchJoint(copyWorld(w), 2, at);
  const J = bones.joints(out);
  closeV(J[2], at);
  closeV(J[0], new Vector3(0, 0, 0));
  closeV(J[1], new Vector3(1, 0, 0));
  closeV(J[3], new Vector3(3, 0, 0));
  close(out.S[1], at.distanceTo(new Vector3(1, 0, 0)));          // rest length 1
  close(out.S[2], at.distanceTo(new Vector3(3, 0, 0)));
  assert.equal(bones.stretchJoint(copyWorld(w), 2, new Vector3(1, 0, 0)), null);   // bone 1 to nothing
});

test("an IK drag keeps every bone's length and reaches a reachable target; a root drag moves all", () => {
  const s = chain(), bones = new Bones(s), w = bones.world();
  const target = new Vector3(1.2, 1.9, 0.4);                      // within reach (3)
  const out = bones.ikJoint(copyWorld(w), 3, target);
  const J = bones.joints(out);
  closeV(J[3], target, 1e-8);
  closeV(J[0], new Vector3(0, 0, 0));
  for (let i = 0; i < 3; i++) close(J[i].distanceTo(J[i + 1]), 1, 1e-12);
  assert.deepEqual(out.S, [1, 1, 1]);
  const moved = bones.joints(bones.ikJoint(copyWorld(w), 0, new Vector3(0, 0, 5)));
  closeV(moved[3], new Vector3(3, 0, 5));
  // FABRIK alone: out of reach, the chain points at the target
  const P = [new Vector3(0, 0, 0), new Vector3(1, 0, 0)], Q = fabrik(P, [1], new Vector3(0, 4, 0));
  closeV(Q[1], new Vector3(0, 1, 0));
});

test("turning a bone turns its subtree about its start; the world form is what the server reads", () => {
  const s = chain(), bones = new Bones(s);
  const out = bones.rotateBone(bones.world(), 1, [0, 0, 1], Math.PI / 2);
  const J = bones.joints(out);
  closeV(J[2], new Vector3(1, 1, 0), 1e-15);
  closeV(J[3], new Vector3(1, 2, 0), 1e-15);
  const json = worldJSON(out);
  assert.deepEqual(Object.keys(json), ["R", "A", "S", "T"]);
  close(json.R[1][1][0], 1, 1e-15);           // row 1, column 0 of a quarter turn about z
  close(json.R[1][0][1], -1, 1e-15);
  assert.deepEqual(json.A[2].map((x) => Math.round(x * 1e12) / 1e12), [1, 1, 0]);
});

test("X-mirror: an edit of a bone also makes the reflected edit of its mirror bone", () => {
  // a 2D T: spine 0-1, arm.L 1-2 (+x), arm.R 1-3 (-x)
  const C = Float64Array.from([0, -1, 0, 1, 1, 1, -1, 1]);
  const s = store(C, [0, 1, 1, 2, 1, 3], [-1, 0, 0], 2, ["spine", "arm.L", "arm.R"]);
  const bones = new Bones(s), w0 = bones.world();
  const w = mirrorEdit(w0, bones.rotateBone(copyWorld(w0), 1, [0, 0, 1], 0.4), [0, 2, 1]);
  const J = bones.joints(w);
  closeV(J[3], new Vector3(-J[2].x, J[2].y, 0), 1e-15);          // mirror images across x = 0
  close(J[2].y, 1 + Math.sin(0.4), 1e-15);
  // a bone edited with its mirror (here, the spine with both arms) is left as edited
  const both = mirrorEdit(w0, bones.rotateBone(copyWorld(w0), 0, [0, 0, 1], 0.3), [0, 2, 1]);
  const K = bones.joints(both), ref = bones.joints(bones.rotateBone(copyWorld(w0), 0, [0, 0, 1], 0.3));
  K.forEach((p, k) => closeV(p, ref[k]));
  // a stretch and a twist mirror too (3D)
  const s3 = store(Float64Array.from([0, 0, 0, 1, 0, 0, -1, 0, 0]), [0, 1, 0, 2], [-1, -1], 3);
  const b3 = new Bones(s3), v0 = b3.world(), v = copyWorld(v0);
  v.S[0] = 1.5; v.T[0] = [0.1, 0.3];
  const m = mirrorEdit(v0, v, [1, 0]);
  assert.equal(m.S[1], 1.5);
  assert.deepEqual(m.T[1], [-0.1, -0.3]);
});
