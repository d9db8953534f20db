// The page's one client of the server's API (docs/viewer.md): every request carries the
// page's token, and an error answer throws with the server's one-line message.

const DTYPES = { float32: Float32Array, float64: Float64Array, uint8: Uint8Array,
                 uint16: Uint16Array, uint32: Uint32Array, int32: Int32Array,
                 int16: Int16Array, int8: Int8Array };

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
export function postJSON(body) {
  return { method: "POST", headers: { "Content-Type": "application/json" }, body: JSON.stringify(body) };
}
