// The page's one client of the server's API (docs/viewer-api.md): every request carries
// the page's token, and an error answer throws with the server's one-line message.

const DTYPES = { float32: Float32Array, float64: Float64Array, uint8: Uint8Array,
                 uint16: Uint16Array, uint32: Uint32Array, int32: Int32Array,
                 int16: Int16Array, int8: Int8Array };

const OCTET = "application/octet-stream";

/** The page's token, from its address (?token=...). */
export const TOKEN = typeof location === "undefined" ? ""
  : new URLSearchParams(location.search).get("token") || "";

/** fetch(path, options) with the token; throws Error("path: message") with .status. */
export async function api(path, options = {}) {
  const headers = Object.assign({ "X-Stbs-Token": TOKEN }, options.headers || {});
  const r = await fetch(path, Object.assign({}, options, { headers, cache: "no-store" }));
  if (!r.ok) {
    let msg = `${r.status}`;
    try { msg = (await r.json()).error || msg; } catch (_) { /* not JSON */ }
    const err = new Error(`${path}: ${msg}`);
    err.status = r.status;
    throw err;
  }
  return r;
}

/** api(path, options), its answer read as JSON. */
export async function apiJSON(path, options) {
  return (await api(path, options)).json();
}

/** A binary array the server describes as {url, dtype, shape}: a typed array. */
export async function loadArray(desc) {
  const r = await api(desc.url);
  const Type = DTYPES[desc.dtype];
  if (!Type) throw new Error(`${desc.url}: unsupported dtype ${desc.dtype}`);
  return new Type(await r.arrayBuffer());
}

/** Options for a POST of a JSON body. */
export function postJSON(body, headers = {}) {
  return { method: "POST", headers: Object.assign({ "Content-Type": "application/json" }, headers),
           body: JSON.stringify(body) };
}

// ------------------------------------------------------------------ pose bones, binary
/**
 * A pose's binary bone rows (docs/viewer-api.md, "Pose bones on the wire"): per bone
 * R row-major (d*d), a' (d), sigma, theta_a, theta_b as little-endian float64, shape
 * (b, m) with m = d*d + d + 3, as {rotations, origins, stretch, twist} (the JSON form
 * of GET /api/pose/bones: nested arrays, twists in radians).
 */
export function bonesFromRows(buffer, b) {
  const a = new Float64Array(buffer);
  const m = b > 0 ? a.length / b : 0;
  const d = m === 15 ? 3 : 2;
  if (b > 0 && m !== d * d + d + 3) throw new Error(`bone rows: expected ${b} rows of 9 or 15 values, got ${a.length} values`);
  const rotations = [], origins = [], stretch = [], twist = [];
  for (let i = 0; i < b; i++) {
    const row = a.subarray(i * m, (i + 1) * m);
    const R = [];
    for (let r = 0; r < d; r++) R.push(Array.from(row.subarray(r * d, (r + 1) * d)));
    rotations.push(R);
    origins.push(Array.from(row.subarray(d * d, d * d + d)));
    stretch.push(row[d * d + d]);
    twist.push([row[d * d + d + 1], row[d * d + d + 2]]);
  }
  return { rotations, origins, stretch, twist };
}

async function bonesReply(r) {
  const shape = (r.headers.get("X-Stbs-Shape") || "").split(",").map(Number);
  return bonesFromRows(await r.arrayBuffer(), shape[0]);
}

/** GET /api/pose/bones as binary: the current pose as {rotations, origins, stretch, twist}. */
export async function poseBones() {
  return bonesReply(await api("/api/pose/bones", { headers: { Accept: OCTET } }));
}

/** POST /api/clip/ID/seek: the clip's pose at `time` (seconds) becomes the current pose;
 * resolves to {pose (the pose object), bones {rotations, origins, stretch, twist}, time},
 * one request (the JSON answer: a pose's rows are a few numbers a bone). */
export async function seekClip(id, time) {
  return apiJSON(`/api/clip/${id}/seek`, postJSON({ time }, { Accept: "application/json" }));
}

/** POST /api/pose/bones: the page's world transforms {R, A, S, T} (ik.js Bones.world())
 * in; the server makes the forward-kinematics pose of them the current pose and
 * resolves to {pose (the pose object), bones {rotations, origins, stretch, twist}}. */
export async function setWorldPose(world) {
  return apiJSON("/api/pose/bones", postJSON({ R: world.R, A: world.A, S: world.S, T: world.T }));
}

// ------------------------------------------------------------------ endpoint jobs
/** POST /api/jobs/endpoint: recompute bone's endpoint weights by `method` in a worker on
 * the server (W: the page's bone weights as n rows, or null for the rig's; options as
 * stbs.weights.endpoint_weights takes them). Resolves to the job's id. */
export async function startEndpointJob(bone, method, { W = null, options = {} } = {}) {
  const body = { bone, method, options };
  if (W) body.W = W;
  return (await apiJSON("/api/jobs/endpoint", postJSON(body))).job;
}

/** GET /api/jobs/ID: {state: running|done|failed|cancelled, stage, done, total, error?}. */
export async function jobStatus(id) {
  return apiJSON(`/api/jobs/${id}`);
}

/** GET /api/jobs/ID/result of an endpoint job: the bone's column as a Float32Array. */
export async function jobResult(id) {
  const r = await api(`/api/jobs/${id}/result`, { headers: { Accept: OCTET } });
  return new Float32Array(await r.arrayBuffer());
}

/** POST /api/jobs/ID/cancel: the job stops at its next step; resolves to its status. */
export async function cancelJob(id) {
  return apiJSON(`/api/jobs/${id}/cancel`, { method: "POST" });
}

// ------------------------------------------------------------------ saves
/** POST /api/save-rig with the page's weights (Float32Arrays of n x b, either may be
 * null); a file already there is replaced only with {overwrite: true} (else the promise
 * rejects with status 409 and the server's one line). Resolves to {path, vertices,
 * bones, has_E}. */
export async function saveRig(W, E, { overwrite = false } = {}) {
  const names = [], parts = [];
  if (W) { names.push("W"); parts.push(W); }
  if (E) { names.push("E"); parts.push(E); }
  if (!parts.length) return apiJSON("/api/save-rig", postJSON({ overwrite }));
  const n = parts.reduce((s, p) => s + p.length, 0);
  const body = new Float32Array(n);
  let at = 0;
  for (const p of parts) { body.set(p, at); at += p.length; }
  return apiJSON("/api/save-rig", {
    method: "POST", body: body.buffer,
    headers: { "Content-Type": OCTET, "X-Stbs-Arrays": names.join(","), "X-Stbs-Dtype": "float32",
               "X-Stbs-Overwrite": overwrite ? "true" : "false" },
  });
}
