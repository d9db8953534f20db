import { test } from "node:test";
import assert from "node:assert/strict";
import { centreX, mirrorBones, mirrorVertices, sideSwapped } from "../src/mirror.js";
import { VertexGrid, hits } from "../src/grid.js";

function rng(seed) {        // a small seeded generator (mulberry32)
  let s = seed >>> 0;
  return () => {
    s = (s + 0x6d2b79f5) >>> 0;
    let t = s;
    t = Math.imul(t ^ (t >>> 15), t | 1);
    t ^= t + Math.imul(t ^ (t >>> 7), t | 61);
    return ((t ^ (t >>> 14)) >>> 0) / 4294967296;
  };
}

function bruteNearest(V, dim, p) {
  let best = -1, bd = Infinity;
  for (let v = 0; v < V.length / dim; v++) {
    let d2 = 0;
    for (let c = 0; c < dim; c++) d2 += (V[v * dim + c] - p[c]) ** 2;
    if (d2 < bd) { bd = d2; best = v; }
  }
  return best;
}

test("the grid's ball and nearest queries agree with brute force", () => {
  const r = rng(1);
  for (const dim of [2, 3]) {
    const n = 3000, V = new Float64Array(n * dim);
    // points on a sphere's surface (3D) or in a square (2D), plus a far cluster
    for (let v = 0; v < n; v++) {
      if (dim === 3) {
        const z = 2 * r() - 1, t = 2 * Math.PI * r(), s = Math.sqrt(1 - z * z);
        V.set([s * Math.cos(t), s * Math.sin(t), z], 3 * v);
      } else {
        V.set([r(), r()], 2 * v);
      }
      if (v % 100 === 0) V[v * dim] += 5;
    }
    const grid = new VertexGrid(V, dim), out = hits(4);
    for (let q = 0; q < 200; q++) {
      const p = [3 * r() - 1, 3 * r() - 1, 3 * r() - 1];
      const want = bruteNearest(V, dim, p);
      const got = grid.nearest(p);
      const dist = (v) => Math.hypot(...Array.from({ length: dim }, (_, c) => V[v * dim + c] - p[c]));
      assert.equal(dist(got), dist(want), `nearest to ${p}`);
      const radius = 0.3 * r();
      const m = grid.within(p, radius, out);
      const inside = [];
      for (let v = 0; v < n; v++) if (dist(v) < radius) inside.push(v);
      assert.deepEqual(Array.from(out.ids.subarray(0, m)).sort((a, b) => a - b), inside);
      for (let k = 0; k < m; k++) assert.ok(Math.abs(out.d2[k] - dist(out.ids[k]) ** 2) < 1e-12);
    }
  }
  assert.throws(() => new VertexGrid([0, 0, 1], 2), /grid: V: expected n x 2 values, got 3/);
  assert.throws(() => new VertexGrid([0, NaN], 2), /expected finite values, got NaN at vertex 0/);
});

test("mirrorVertices of a mesh symmetric about x = 1 pairs each vertex with its reflection", () => {
  const r = rng(2), half = 500, V = new Float64Array(2 * half * 3 + 3 * 3);
  for (let v = 0; v < half; v++) {
    const p = [1 + 0.1 + r(), r(), r()];
    V.set(p, 3 * v);
    V.set([2 - p[0], p[1], p[2]], 3 * (half + v));           // its reflection, at v + half
  }
  for (let k = 0; k < 3; k++) V.set([1, k, 0], 3 * (2 * half + k));   // on the plane: itself
  assert.equal(centreX(V, 3), 1);
  const m = mirrorVertices(V, 3);
  for (let v = 0; v < half; v++) {
    assert.equal(m[v], v + half);
    assert.equal(m[v + half], v);
  }
  for (let k = 0; k < 3; k++) assert.equal(m[2 * half + k], 2 * half + k);
  // an explicit plane off the mesh: the nearest vertex of each reflection, as brute force
  const far = mirrorVertices(V, 3, { centre: 1.7 });
  for (let v = 0; v < V.length / 3; v++) {
    const p = [3.4 - V[3 * v], V[3 * v + 1], V[3 * v + 2]];
    const d = (u) => Math.hypot(V[3 * u] - p[0], V[3 * u + 1] - p[1], V[3 * u + 2] - p[2]);
    assert.equal(d(far[v]), d(bruteNearest(V, 3, p)));
  }
  // 2D
  const V2 = [-1, 0, 1, 0, -2, 3, 2, 3.01, 0, 5];
  assert.deepEqual(Array.from(mirrorVertices(V2, 2)), [1, 0, 3, 2, 4]);
});

test("mirrorBones pairs bones by left/right names, else by reflected rest joints", () => {
  assert.deepEqual(sideSwapped("mixamorig:LeftArm"), ["mixamorig:RightArm"]);
  assert.deepEqual(sideSwapped("upper_arm.L"), ["upper_arm.R"]);
  assert.deepEqual(sideSwapped("r_hand"), ["l_hand"]);
  assert.deepEqual(sideSwapped("spine"), []);
  // joints: 0 hips (x = 0), 1 chest, 2/3 left shoulder/hand (x > 0), 4/5 right (x < 0),
  // 6/7 a left leg, 8/9 a right leg 1% off the left's reflection
  const C = [0, 0, 0, 0, 1, 0, 0.3, 1, 0, 0.8, 0.9, 0, -0.3, 1, 0, -0.8, 0.9, 0,
             0.2, 0, 0, 0.25, -1, 0, -0.2, 0, 0, -0.25, -1.02, 0];
  const BE = [0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 1, 2, 1, 4];
  const rig = { dim: 3, C, BE, names: ["spine", "arm.L", "arm.R", "thigh_a", "thigh_b", "clav", "clavicle"] };
  const m = mirrorBones(rig);
  // names pair the arms; positions pair the thighs and the clavicles (names unrelated)
  assert.deepEqual(Array.from(m), [0, 2, 1, 4, 3, 6, 5]);
  for (let i = 0; i < m.length; i++) assert.equal(m[m[i]], i);
  // names win over positions: swapped names for the thighs
  const named = mirrorBones(Object.assign({}, rig, { names: ["spine", "arm.L", "arm.R", "LeftLeg", "RightLeg", "c1", "c2"] }));
  assert.deepEqual(Array.from(named), [0, 2, 1, 4, 3, 6, 5]);
  // without names the same pairs by position; a tight tolerance leaves the thighs alone
  assert.deepEqual(Array.from(mirrorBones({ dim: 3, C, BE })), [0, 2, 1, 4, 3, 6, 5]);
  assert.deepEqual(Array.from(mirrorBones({ dim: 3, C, BE }, { tol: 1e-3 })), [0, 2, 1, 3, 4, 6, 5]);
  // a plane given that no bone reflects onto: every bone its own mirror
  assert.deepEqual(Array.from(mirrorBones({ dim: 3, C, BE }, { centre: 10 })), [0, 1, 2, 3, 4, 5, 6]);
  // 2D, and the plane taken from V when the rig has vertices
  const rig2 = { dim: 2, C: [1, 0, 2, 0, 0, 0], BE: [0, 1, 0, 2], V: [-1, 0, 3, 0] };
  assert.deepEqual(Array.from(mirrorBones(rig2)), [1, 0]);
  assert.throws(() => mirrorBones({ dim: 4, C, BE }), /rig.dim: expected 2 or 3, got 4/);
  assert.throws(() => mirrorBones({ dim: 3, C, BE: [0, 99] }), /rig.BE: expected joint ids 0..9, got 99/);
  assert.throws(() => mirrorBones(Object.assign({}, rig, { names: ["a"] })), /rig.names: expected 7 names, got 1/);
});
