// The painter's talks with the server, through api.js: endpoint weights recomputed as a
// job (POST /api/jobs/endpoint, followed to its end), and the page's W and E saved into
// the rig file (POST /api/save-rig). The methods offered are the server's: /api/rig's
// endpoint_methods, those that can work on this rig's mesh, in the server's order.
// No DOM, no WebGL.

import { cancelJob, jobResult, jobStatus, saveRig as postRig, startEndpointJob } from "./api.js";
import { bad } from "./paintsettings.js";

/** How often a running job's status is asked for (ms). */
export const POLL_MS = 100;

function sameArray(a, b) {
  if (a.length !== b.length) return false;
  for (let k = 0; k < a.length; k++) if (a[k] !== b[k]) return false;
  return true;
}

export class EndpointJobs {
  /**
   * @param ctx  the page's context; its store holds the rig (with summary, the
   *             /api/rig answer) and W and E (n x b Float32Arrays, read here)
   */
  constructor(ctx) {
    const { store } = ctx;
    this.W = store.W;
    this.E = store.E;
    this.n = store.rig.n;
    this.b = store.rig.b;
    const methods = (store.rig.summary || {}).endpoint_methods;
    if (!Array.isArray(methods) || !methods.every((m) => typeof m === "string")) {
      throw bad("/api/rig: endpoint_methods", "a list of method names", methods ?? null);
    }
    this.endpointMethods = methods.slice();
    this.serverW = this.W.slice();       // the weights the server has (sent with a job when not)
    this.job = null;                     // the job running: {id, method}
  }

  /** The endpoint methods this rig's mesh can compute (the server's list). */
  methods() {
    return this.endpointMethods.slice();
  }

  /**
   * Recompute bone i's endpoint weights by `method` on the server as a job, following
   * its progress until done. `onProgress({state, stage, done, total})` is called as the
   * job reports, `onColumn(col)` with the result while the job still counts as running.
   * Resolves to the column (Float32Array n); rejects when the job fails or is
   * cancelled (cancel()), or when one is running already.
   */
  async run(i, method, options = {}, { onProgress = null, onColumn = null } = {}) {
    const can = this.endpointMethods;
    if (!can.includes(method)) throw bad("endpoint method", `one of ${can.join(", ")}`, method);
    if (options === null || typeof options !== "object" || Array.isArray(options)) {
      throw bad("endpoint options", "an object", options);
    }
    if (this.job) throw new Error(`an endpoint recompute is running (${this.job.method}); cancel it first`);
    let W = null;
    if (!sameArray(this.W, this.serverW)) {     // painted since loaded or saved: send ours
      const b = this.b;
      W = [];
      for (let r = 0; r < this.n; r++) W.push(Array.from(this.W.subarray(r * b, (r + 1) * b)));
    }
    const id = await startEndpointJob(i, method, { W, options });
    this.job = { id, method };
    try {
      let st = await jobStatus(id);
      while (st.state === "running") {
        if (onProgress) onProgress(st);
        await new Promise((ok) => setTimeout(ok, POLL_MS));
        st = await jobStatus(id);
      }
      if (onProgress) onProgress(st);
      if (st.state === "cancelled") throw new Error(`recompute (${method}): cancelled`);
      if (st.state !== "done") throw new Error(`recompute (${method}): ${st.error || st.state}`);
      const col = await jobResult(id);
      if (col.length !== this.n) throw new Error(`/api/jobs/${id}/result: expected ${this.n} values, got ${col.length}`);
      if (onColumn) onColumn(col);
      return col;
    } finally {
      this.job = null;
    }
  }

  /** Cancel the running job; resolves to whether one was running. */
  async cancel() {
    const job = this.job;
    if (!job) return false;
    await cancelJob(job.id);
    return true;
  }

  /**
   * POST /api/save-rig with W and E. The server answers 409 (the promise rejects, with
   * .status) when the file exists and `overwrite` is false; resolves to its answer.
   */
  async save(overwrite = false) {
    if (typeof overwrite !== "boolean") throw bad("overwrite", "true or false", overwrite);
    const sent = this.W.slice();
    const reply = await postRig(this.W, this.E, { overwrite });
    this.serverW = sent;          // the rig served now has these weights
    return reply;
  }
}
