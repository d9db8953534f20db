// The weight painter's settings, without the page: the colour and paint modes, a bone
// named by index or name, and setPaint's options checked one by one into new settings.
// Pure: no DOM, no WebGL (paint.js applies them, paintpanel.js shows them).

import { FALLOFFS, PAINT_OPS } from "./brush.js";

export { FALLOFFS, PAINT_OPS };
/** Colour modes, in the order of the shader's uColorMode (skin.js). */
export const COLOR_MODES = ["shaded", "bones", "endpoint", "weight"];
export const PAINT_MODES = ["off", "bone", "endpoint"];
/** The options setPaint takes. */
export const PAINT_KEYS = ["mode", "bone", "op", "radius", "strength", "falloff", "mirror"];
/** `[` and `]` scale the brush's radius by this. */
export const RADIUS_STEP = 1.25;

/** An Error naming the input, what was expected and what arrived. */
export function bad(what, expected, got) {
  return new Error(`${what}: expected ${expected}, got ${JSON.stringify(got)}`);
}

/**
 * The index of a bone given as an index 0..b-1, a bone name, or an index written as a
 * string ("3"); anything else throws.
 *
 * @param key    the bone
 * @param names  the rig's bone names (b of them)
 */
export function boneIndex(key, names) {
  const b = names.length;
  if (typeof key === "number" && Number.isInteger(key) && key >= 0 && key < b) return key;
  if (typeof key === "string") {
    const k = names.indexOf(key);
    if (k >= 0) return k;
    if (/^\d+$/.test(key) && Number(key) < b) return Number(key);
  }
  throw bad("bone", `an index 0..${b - 1} or a bone name`, key);
}

/** The brush radius scaled by k, kept within [diag / 200, diag / 2]. */
export function scaledRadius(radius, k, diag) {
  return Math.min(diag / 2, Math.max(diag / 200, radius * k));
}

/**
 * `settings` with `opts` applied, every option checked before any is taken: a new object
 * ({mode, bone, op, radius, strength, falloff}); `opts.mirror` is checked here but is the
 * store's, not a setting. Throws on an unknown key or a bad value, naming it.
 *
 * @param settings  the current {mode, bone, op, radius, strength, falloff}
 * @param opts      some of PAINT_KEYS
 * @param names     the rig's bone names (for opts.bone)
 */
export function mergeSettings(settings, opts, names) {
  if (opts === null || typeof opts !== "object" || Array.isArray(opts)) {
    throw bad("setPaint", `an object {${PAINT_KEYS.join(", ")}}`, opts);
  }
  for (const k of Object.keys(opts)) {
    if (!PAINT_KEYS.includes(k)) throw bad("setPaint", `keys among ${PAINT_KEYS.join(", ")}`, k);
  }
  const s = Object.assign({}, settings);
  const oneOf = (what, list, value) => {
    if (!list.includes(value)) throw bad(what, `one of ${list.join(", ")}`, value);
    return value;
  };
  if ("mode" in opts) s.mode = oneOf("paint mode", PAINT_MODES, opts.mode);
  if ("bone" in opts) s.bone = boneIndex(opts.bone, names);
  if ("op" in opts) s.op = oneOf("brush op", PAINT_OPS, opts.op);
  if ("radius" in opts) {
    if (typeof opts.radius !== "number" || !(opts.radius > 0) || !Number.isFinite(opts.radius)) {
      throw bad("brush radius", "a positive number (the rig's units)", opts.radius);
    }
    s.radius = opts.radius;
  }
  if ("strength" in opts) {
    if (typeof opts.strength !== "number" || !(opts.strength >= 0 && opts.strength <= 1)) {
      throw bad("brush strength", "a number in [0, 1]", opts.strength);
    }
    s.strength = opts.strength;
  }
  if ("falloff" in opts) s.falloff = oneOf("brush falloff", FALLOFFS, opts.falloff);
  if ("mirror" in opts && typeof opts.mirror !== "boolean") throw bad("mirror", "true or false", opts.mirror);
  return s;
}
