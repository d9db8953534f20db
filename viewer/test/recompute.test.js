import { test, afterEach } from "node:test";
import assert from "node:assert/strict";
import { EndpointJobs } from "../src/recompute.js";

// a fake server behind fetch: answers by path, records every request
const realFetch = globalThis.fetch;
afterEach(() => { globalThis.fetch = realFetch; });

const json = (x, status = 200) => new Response(JSON.stringify(x), { status, headers: { "Content-Type": "application/json" } });

function serve(states, column, extra = () => null) {
  const calls = [];
  let k = 0;
  globalThis.fetch = async (path, opts = {}) => {
    calls.push({ path, method: opts.method || "GET", headers: opts.headers, body: opts.body });
    const other = extra(path, opts);
    if (other) return other;
    if (path === "/api/jobs/endpoint") return json({ job: "j1" });
    if (path === "/api/jobs/j1") return json(states[Math.min(k++, states.length - 1)]);
    if (path === "/api/jobs/j1/result") return new Response(Float32Array.from(column).buffer);
    if (path === "/api/jobs/j1/cancel") return json({ state: "cancelled" });
    return json({ error: `no route ${path}` }, 404);
  };
  return calls;
}

// n = 3 vertices, b = 2 bones
function jobs(methods = ["heat", "projection", "idw"]) {
  const W = Float32Array.from([1, 0, 0.5, 0.5, 0, 1]), E = new Float32Array(6);
  const rig = { n: 3, b: 2, summary: { endpoint_methods: methods } };
  return { jobs: new EndpointJobs({ store: { rig, W, E } }), W, E };
}

const DONE = [{ state: "running", stage: "solve", done: 1, total: 2 }, { state: "done", stage: "solve", done: 2, total: 2 }];

test("the methods are the server's (/api/rig endpoint_methods), in its order", async () => {
  const { jobs: j } = jobs(["idw", "heat", "future"]);
  assert.deepEqual(j.methods(), ["idw", "heat", "future"]);
  j.methods().push("bbw");                                     // a copy
  assert.deepEqual(j.methods(), ["idw", "heat", "future"]);
  serve(DONE, [0, 0.5, 1]);
  await assert.rejects(j.run(0, "projection"), (err) =>
    err.message === 'endpoint method: expected one of idw, heat, future, got "projection"');
  assert.deepEqual(Array.from(await j.run(0, "future")), [0, 0.5, 1]);   // one the page never heard of
  for (const summary of [{}, { endpoint_methods: "idw" }, { endpoint_methods: [1] }]) {
    const rig = { n: 3, b: 2, summary };
    assert.throws(() => new EndpointJobs({ store: { rig, W: new Float32Array(6), E: new Float32Array(6) } }),
                  /^Error: \/api\/rig: endpoint_methods: expected a list of method names, got/);
  }
});

test("a job is followed to its end; the column comes while it still counts as running", async () => {
  const { jobs: j } = jobs();
  const calls = serve(DONE, [0, 0.5, 1]);
  const seen = [];
  let running = null;
  const col = await j.run(1, "heat", { k: 2 }, { onProgress: (st) => seen.push(st.done),
                                               onColumn: (c) => { running = j.job; seen.push(Array.from(c)); } });
  assert.ok(col instanceof Float32Array);
  assert.deepEqual(Array.from(col), [0, 0.5, 1]);
  assert.deepEqual(seen, [1, 2, [0, 0.5, 1]]);
  assert.deepEqual(running, { id: "j1", method: "heat" });
  assert.equal(j.job, null);
  assert.deepEqual(JSON.parse(calls[0].body), { bone: 1, method: "heat", options: { k: 2 } });   // no W: unpainted
  assert.deepEqual(calls.map((c) => c.path), ["/api/jobs/endpoint", "/api/jobs/j1", "/api/jobs/j1", "/api/jobs/j1/result"]);
});

test("painted weights go with the job until they are saved", async () => {
  const { jobs: j, W } = jobs();
  let calls = serve(DONE, [0, 0, 0]);
  W[0] = 0.75; W[1] = 0.25;                    // painted in place
  await j.run(0, "idw");
  assert.deepEqual(JSON.parse(calls[0].body).W, [[0.75, 0.25], [0.5, 0.5], [0, 1]]);
  calls = serve(DONE, [0, 0, 0], (path) => (path === "/api/save-rig" ? json({ path: "r.npz" }) : null));
  assert.deepEqual(await j.save(), { path: "r.npz" });
  assert.equal(calls[0].headers["X-Stbs-Arrays"], "W,E");
  assert.equal(calls[0].headers["X-Stbs-Overwrite"], "false");
  await j.run(0, "idw");
  assert.equal(JSON.parse(calls[1].body).W, undefined);
  await assert.rejects(j.save("yes"), (err) => err.message === 'overwrite: expected true or false, got "yes"');
});

test("a refused save (409) leaves the weights to be sent", async () => {
  const { jobs: j, W } = jobs();
  W[0] = 0.75; W[1] = 0.25;
  const calls = serve(DONE, [0, 0, 0], (path) => (path === "/api/save-rig" ? json({ error: "r.npz exists" }, 409) : null));
  await assert.rejects(j.save(false), (err) => err.status === 409 && err.message === "/api/save-rig: r.npz exists");
  await j.run(0, "idw");
  assert.deepEqual(JSON.parse(calls[1].body).W, [[0.75, 0.25], [0.5, 0.5], [0, 1]]);
});

test("failed, cancelled and short jobs reject, naming why; the next job may start", async () => {
  const { jobs: j } = jobs();
  serve([{ state: "failed", error: "no volume" }], [0, 0, 0]);
  await assert.rejects(j.run(0, "heat"), (err) => err.message === "recompute (heat): no volume");
  serve([{ state: "cancelled" }], [0, 0, 0]);
  await assert.rejects(j.run(0, "heat"), (err) => err.message === "recompute (heat): cancelled");
  serve(DONE, [0, 1]);
  await assert.rejects(j.run(0, "heat"), (err) => err.message === "/api/jobs/j1/result: expected 3 values, got 2");
  await assert.rejects(j.run(0, "heat", null), (err) => err.message === "endpoint options: expected an object, got null");
  serve(DONE, [0, 0, 0]);
  assert.equal((await j.run(0, "heat")).length, 3);
});

test("one job at a time; cancel() asks the server to stop it", async () => {
  const { jobs: j } = jobs();
  const calls = serve([{ state: "running", done: 0, total: 2 }, { state: "cancelled" }], [0, 0, 0]);
  assert.equal(await j.cancel(), false);         // none running
  const first = j.run(0, "idw");
  await new Promise((ok) => setTimeout(ok, 20));
  await assert.rejects(j.run(1, "heat"), (err) =>
    err.message === "an endpoint recompute is running (idw); cancel it first");
  assert.equal(await j.cancel(), true);
  assert.ok(calls.some((c) => c.path === "/api/jobs/j1/cancel" && c.method === "POST"));
  await assert.rejects(first, /cancelled/);
  assert.equal(j.job, null);
});
