// The skinning methods: the page takes their names from the server and checks them
// against the order of the shader's uMethod values (skin.js checkMethods).

import { test } from "node:test";
import assert from "node:assert/strict";
import { SHADER_METHODS, SKIN_GLSL, checkMethods } from "../src/skin.js";

test("the server's methods in the shader's order are taken as they are, as a copy", () => {
  const sent = ["lbs", "dqs", "stbs-lbs", "stbs-dqs"];
  const got = checkMethods(sent);
  assert.deepEqual(got, sent);
  assert.notEqual(got, sent);
});

test("another order, a missing or an unknown method is refused naming both lists", () => {
  for (const bad of [["dqs", "lbs", "stbs-lbs", "stbs-dqs"], ["lbs", "dqs", "stbs-lbs"],
                     ["lbs", "dqs", "stbs-lbs", "stbs-dqs", "cor"], ["lbs", "dqs", "stbs-lbs", "x"],
                     undefined, "lbs"]) {
    assert.throws(() => checkMethods(bad), (e) => {
      assert.match(e.message, /"methods" of \/api\/rig/);
      assert.ok(e.message.includes(JSON.stringify(SHADER_METHODS)), e.message);
      assert.ok(e.message.includes(`got ${JSON.stringify(bad)}`), e.message);
      return true;
    });
  }
});

test("the shader's branches are the indices of its order", () => {
  // lbs and stbs-lbs blend matrices (uMethod 0 or 2), lbs alone at 0, dqs alone at 1
  assert.match(SKIN_GLSL, /uMethod == 0 \|\| uMethod == 2/);
  assert.equal(SHADER_METHODS.indexOf("lbs"), 0);
  assert.equal(SHADER_METHODS.indexOf("dqs"), 1);
  assert.equal(SHADER_METHODS.indexOf("stbs-lbs"), 2);
});
