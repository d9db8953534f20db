// The page's structure, checked on viewer/src's source:
//
// 1. No import circle among the modules (relative imports, "./x.js").
// 2. No module writes another's fields. Precisely: in a module, a *borrowed* name is
//    (a) a parameter of a class's constructor or the constructor's alias of one
//    (`const v = viewer`, `const { view } = ctx`), (b) a field `this.F` the constructor sets
//    to a parameter or to a parameter's member (`this.v = viewer`, `this.store =
//    ctx.store`), (c) a local bound to a borrowed field or one of its members (`const
//    v = this.view`, `const { camera } = this.view`). An assignment (=, op=, ++, --)
//    to a member of a borrowed name (`this.v.lastSent = ...`, `this.store.mode = ...`,
//    `v.camera.zoom = ...`) is a write into another module's object: the module must
//    call a method of it instead (the store's setters, view.setOrbit, ...). A page
//    element handed to a module to draw in (a constructor parameter named `canvas` or
//    `element`) is that module's: it sizes it. The store's weight arrays W and E are
//    edited in place (`this.E[k] = e` on `this.E = store.E`), announced with
//    store.weightsChanged(rows).

import { test } from "node:test";
import assert from "node:assert/strict";
import { readdirSync, readFileSync } from "node:fs";
import { dirname, join } from "node:path";
import { fileURLToPath } from "node:url";

const SRC = join(dirname(fileURLToPath(import.meta.url)), "..", "src");

const ID = "[A-Za-z_$][\\w$]*";
const DRAWN_IN = ["canvas", "element"];

/** Source without comments and string contents (quotes kept, so offsets stay sane). */
export function strip(src) {
  let out = "", i = 0;
  while (i < src.length) {
    const c = src[i], d = src[i + 1];
    if (c === "/" && d === "/") { while (i < src.length && src[i] !== "\n") i++; continue; }
    if (c === "/" && d === "*") { const e = src.indexOf("*/", i + 2); i = e < 0 ? src.length : e + 2; continue; }
    if (c === "\"" || c === "'" || c === "`") {
      let j = i + 1;
      while (j < src.length && src[j] !== c) j += src[j] === "\\" ? 2 : 1;
      out += c + c;
      i = j + 1;
      continue;
    }
    out += c;
    i++;
  }
  return out;
}

function balanced(s, open) {          // index just past the bracket closing the one at `open`
  const pairs = { "(": ")", "{": "}", "[": "]" }, stack = [];
  for (let i = open; i < s.length; i++) {
    if (pairs[s[i]]) stack.push(pairs[s[i]]);
    else if (s[i] === stack[stack.length - 1]) { stack.pop(); if (!stack.length) return i + 1; }
  }
  return s.length;
}

function paramNames(text) {           // identifiers a parameter list binds (defaults dropped)
  let depth = 0, out = "", skipping = false;
  for (const c of text) {
    if ("([{".includes(c)) depth++;
    if (")]}".includes(c)) depth--;
    if (c === "=" && !skipping) { skipping = true; continue; }
    if (skipping && (c === "," || (c === "}" && depth < 1))) skipping = false;
    if (!skipping) out += c;
  }
  return new Set(out.match(new RegExp(ID, "g")) || []);
}

/** The writes into borrowed objects in a module's source: [{line, target}]. */
export function foreignWrites(source) {
  const s = strip(source);
  const borrowedFields = new Set(), borrowed = new Set(), inPlace = new Set();
  const re = /\bconstructor\s*\(/g;
  let m;
  while ((m = re.exec(s))) {
    const open = m.index + m[0].length - 1, close = balanced(s, open);
    const params = paramNames(s.slice(open + 1, close - 1));
    for (const own of DRAWN_IN) params.delete(own);
    params.forEach((p) => borrowed.add(p));
    const bodyOpen = s.indexOf("{", close), body = s.slice(bodyOpen, balanced(s, bodyOpen));
    for (const a of body.matchAll(new RegExp(`\\b(?:const|let|var)\\s+(${ID}|\\{[^}]*\\})\\s*=\\s*(${ID})((?:\\.${ID})*)\\s*[;,\\n]`, "g"))) {
      if (!params.has(a[2])) continue;           // an alias: const v = viewer, const { view } = ctx
      for (const name of a[1].startsWith("{") ? paramNames(a[1].slice(1, -1)) : [a[1]]) {
        params.add(name);
        borrowed.add(name);
      }
    }
    for (const f of body.matchAll(new RegExp(`this\\.(${ID})\\s*=\\s*(${ID})((?:\\.${ID})*)\\s*[;\\n]`, "g"))) {
      if (!params.has(f[2])) continue;
      // the store's weight arrays are edited in place, element by element, then announced
      // with store.weightsChanged(rows), the store's setter for them
      if (/\.store\.(W|E)$|^\.(W|E)$/.test(f[3]) && f[3].endsWith(`.${f[1]}`)) inPlace.add(f[1]);
      borrowedFields.add(f[1]);
    }
  }
  const fieldAlt = [...borrowedFields].join("|");
  if (fieldAlt) {
    const local = new RegExp(`\\b(?:const|let|var)\\s+(${ID}|\\{[^}]*\\})\\s*=\\s*this\\.(?:${fieldAlt})\\b(?:\\.${ID})*\\s*[;,\\n]`, "g");
    for (const l of s.matchAll(local)) {
      for (const name of l[1].startsWith("{") ? paramNames(l[1].slice(1, -1)) : [l[1]]) borrowed.add(name);
    }
  }
  const out = [];
  const target = new RegExp(`(^|[^\\w$.])((?:this\\.)?${ID}(?:\\.${ID}|\\[[^\\]\\n]*\\])+)\\s*` +
                            "(?:(?:[-+*/%&|^]|\\*\\*|<<|>>>?|&&|\\|\\||\\?\\?)?=(?![=>])|\\+\\+|--)", "g");
  for (const t of s.matchAll(target)) {
    const chain = t[2];
    const parts = chain.replace(/\[[^\]]*\]/g, ".[]").split(".");
    const foreign = parts[0] === "this"
      ? parts.length >= 3 && borrowedFields.has(parts[1]) &&
        !(parts.length === 3 && parts[2] === "[]" && inPlace.has(parts[1]))
      : borrowed.has(parts[0]);
    if (foreign) out.push({ line: s.slice(0, t.index).split("\n").length, target: chain });
  }
  return out;
}

/** The relative imports of each module: {file: [files]}. */
function importGraph() {
  const g = {};
  for (const f of readdirSync(SRC).filter((x) => x.endsWith(".js"))) {
    const src = readFileSync(join(SRC, f), "utf8");
    g[f] = [...src.matchAll(/^\s*import\s[^;]*?from\s+"\.\/([\w.-]+\.js)"/gm)].map((x) => x[1]);
  }
  return g;
}

test("the page's modules import each other without a circle", () => {
  const g = importGraph(), state = {}, circles = [];
  const visit = (f, path) => {
    if (state[f] === 2) return;
    if (state[f] === 1) { circles.push([...path.slice(path.indexOf(f)), f].join(" -> ")); return; }
    state[f] = 1;
    for (const d of g[f] || []) {
      assert.ok(g[d], `${f} imports ./${d}, which is not in viewer/src`);
      visit(d, [...path, f]);
    }
    state[f] = 2;
  };
  Object.keys(g).forEach((f) => visit(f, []));
  assert.deepEqual(circles, []);
  assert.ok(g["main.js"].includes("store.js") && g["main.js"].includes("keys.js"));
});

test("no module writes into another's objects (only through their methods and the store's setters)", () => {
  const found = [];
  for (const f of readdirSync(SRC).filter((x) => x.endsWith(".js"))) {
    for (const w of foreignWrites(readFileSync(join(SRC, f), "utf8"))) found.push(`${f}:${w.line}: ${w.target}`);
  }
  assert.deepEqual(found, []);
});

test("the check finds the writes the page's old timeline, editor and painter made", () => {
  // as timeline.js set the viewer's pose object and edit.js the viewer's orbit controls
  const old = `export class Timeline {
    constructor(viewer, api, status) {
      this.v = viewer;
      this.api = api;
      this.list = [];
    }
    show(t) {
      this.v.lastSent = copy(reply.pose);   // the Viewer's field
      this.list[0] = 1;                      // its own
      this.time = t;
    }
    exportClip() {
      const v = this.v, saved = v.camera.clone();
      v.camera.zoom = 2;
    }
  }
  class Editor {
    constructor(ctx, { gizmo, painting = () => false }) {
      const { view } = ctx;
      this.view = view;
      this.store = ctx.store;
      this.E = ctx.store.E;
      this.drag = null;
      ctx.view.controls.enabled = false;
    }
    up() { this.E[0] = 1; this.E.buffer = null; this.view.controls.enabled = true; this.store.mode = "paint"; this.drag = {}; this.drag.moved = true; gizmo.bone = 3; this.store.count++; }
  }`;
  const found = foreignWrites(old).map((w) => w.target);
  assert.deepEqual(found, ["this.v.lastSent", "v.camera.zoom", "ctx.view.controls.enabled",
                           "this.E.buffer", "this.view.controls.enabled", "this.store.mode", "gizmo.bone", "this.store.count"]);
});
