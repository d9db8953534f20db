import { test } from "node:test";
import assert from "node:assert/strict";
import { hangSegments, packBones, posedSegments, PoseLink, restFrames, restPose } from "../src/pose.js";
import { Events } from "../src/events.js";
import { Store } from "../src/store.js";
import { TEXELS_PER_BONE } from "../src/skin.js";

const close = (a, b, tol = 1e-12) => assert.ok(Math.abs(a - b) <= tol, `${a} != ${b}`);

// one 3D bone from (1, 0, 0) to (1, 2, 0)
const rest = restFrames(Float64Array.from([1, 0, 0, 1, 2, 0]), [0, 1], 3);
const quarter = { rotations: [[[0, -1, 0], [1, 0, 0], [0, 0, 1]]], origins: [[0, 0, 3]],
                  stretch: [1.5], twist: [[0.25, 0.5]] };   // a quarter turn about z

test("rest frames: start, end, unit direction and length of each bone", () => {
  assert.deepEqual(Array.from(rest.a), [1, 0, 0]);
  assert.deepEqual(Array.from(rest.u), [0, 1, 0]);
  assert.equal(rest.len[0], 2);
  const p = restPose(rest, 3);
  assert.deepEqual(p.rotations[0], [[1, 0, 0], [0, 1, 0], [0, 0, 1]]);
  assert.deepEqual(p.origins[0], [1, 0, 0]);
});

test("the bone texture row: R by columns, the unit quaternion and the dual part of the bone's map", () => {
  const out = packBones(rest, quarter, 3, new Float32Array(4 * TEXELS_PER_BONE));
  assert.deepEqual(Array.from(out.subarray(0, 3)), [0, 1, 0]);            // R's first column
  assert.equal(out[3], 1.5);
  close(out[7], 0.25, 1e-7);
  close(out[11], 0.5, 1e-7);
  const [x, y, z, w] = out.subarray(24, 28);                                // (x, y, z, w)
  close(x, 0); close(y, 0); close(z, Math.SQRT1_2, 1e-7); close(w, Math.SQRT1_2, 1e-7);
  // dual part qd = (t, 0) q / 2 with t = a' - R a = (0, 0, 3) - (0, 1, 0) = (0, -1, 3):
  // the map x -> q x q* + t, written out by hand
  const s = Math.SQRT1_2, t = [0, -1, 3];
  const want = [0.5 * (s * t[0] + t[1] * s - t[2] * 0), 0.5 * (s * t[1] + t[2] * 0 - t[0] * s),
                0.5 * (s * t[2] + t[0] * 0 - t[1] * 0), -0.5 * (t[2] * s)];
  Array.from(out.subarray(28, 32)).forEach((v, k) => close(v, want[k], 1e-6));
});

test("posed segments: a' and a' + sigma R (b - a); links from where a child hangs", () => {
  const segs = posedSegments(rest, quarter, 3, new Float64Array(6));
  assert.deepEqual(Array.from(segs), [0, 0, 3, -3, 0, 3]);
  const links = hangSegments([[0, 0, 0.5]], Float64Array.from([0, 0, 0, 2, 0, 0]), new Float64Array(6));
  assert.deepEqual(Array.from(links), [1, 0, 0, 0, 0, 0]);
});

test("the pose link: the latest pose wins, one request at a time, the store gets what the server made", async () => {
  const store = new Store(new Events());
  store.setRig({ dim: 3, n: 0, b: 1 });
  const calls = [];
  let open = 0, most = 0;
  const apiJSON = async (path, options) => {
    open++; most = Math.max(most, open);
    calls.push([path, options && options.body]);
    await new Promise((r) => setTimeout(r, 5));
    open--;
    return { pose: JSON.parse(options.body) };
  };
  const poseBones = async () => { calls.push(["bones"]); return quarter; };
  const setWorldPose = async (world) => { calls.push(["world", JSON.stringify(world)]); return { pose: { world: true }, bones: quarter }; };
  assert.throws(() => new PoseLink(store, { apiJSON }), /the client needs poseBones\(\), got undefined/);
  const link = new PoseLink(store, { apiJSON, poseBones, setWorldPose });
  link.send({ stretch: { a: 1.1 } });
  link.send({ stretch: { a: 1.2 } });
  const done = link.send({ stretch: { a: 1.3 } });
  await done;
  assert.equal(most, 1);
  assert.deepEqual(calls.map(([p]) => p), ["/api/pose", "bones", "/api/pose", "bones"]);
  assert.deepEqual(store.poseObject, { stretch: { a: 1.3 } });
  await link.send({ world: { R: [], A: [], S: [], T: [] } });
  assert.deepEqual(store.poseObject, { world: true });
  assert.equal(store.pose, quarter);
  assert.equal(calls.at(-1)[0], "world");
  assert.equal(JSON.parse(calls.at(-1)[1]).R.length, 0);
});

test("idle() waits for an edit whose pose is still being made (track)", async () => {
  const store = new Store(new Events());
  const fail = async () => { throw new Error("no request expected"); };
  const link = new PoseLink(store, { apiJSON: fail, poseBones: fail, setWorldPose: fail });
  let done = false;
  link.track(new Promise((r) => setTimeout(r, 20)).then(() => { done = true; }));
  link.track(Promise.reject(new Error("a failed one does not stop idle()")));
  assert.equal(link.preparing, true);
  await link.idle();
  assert.equal(done, true);
  assert.equal(link.preparing, false);
});
