import { test } from "node:test";
import assert from "node:assert/strict";
import { Keys, parseKey, typing } from "../src/keys.js";

function press(key, mods = {}, target = { tagName: "CANVAS" }) {
  let prevented = false;
  return { key, target, ctrlKey: !!mods.ctrl, metaKey: !!mods.meta, shiftKey: !!mods.shift,
           altKey: !!mods.alt, repeat: false, defaultPrevented: false,
           preventDefault: () => { prevented = true; }, get prevented() { return prevented; } };
}

test("one handler: each registered shortcut runs on its key and modifiers only", () => {
  const k = new Keys(), ran = [];
  k.register({ key: "Ctrl+Z", label: "undo", run: () => ran.push("undo") });
  k.register({ key: "Ctrl+Shift+Z", label: "redo", run: () => ran.push("redo") });
  k.register({ key: "Space", label: "play", run: () => ran.push("play") });
  k.register({ key: "X", label: "mirror", run: () => ran.push("mirror") });
  k.register({ key: "[", label: "smaller", run: () => ran.push("[") });
  const e = press("z", { ctrl: true });
  assert.equal(k.handle(e), true);
  assert.equal(e.prevented, true);
  k.handle(press("Z", { ctrl: true, shift: true }));
  k.handle(press("z", { meta: true }));          // Cmd-Z on a Mac
  k.handle(press(" "));
  k.handle(press("x"));
  k.handle(press("X", { shift: true }));         // Shift+X is another key
  k.handle(press("x", { ctrl: true }));
  k.handle(press("["));
  assert.deepEqual(ran, ["undo", "redo", "undo", "play", "mirror", "["]);
});

test("nothing runs while typing in a field; a slider or a checkbox does not count", () => {
  const k = new Keys(), ran = [];
  k.register({ key: "Ctrl+Z", label: "undo", run: () => ran.push("undo") });
  k.register({ key: "F", label: "frame", run: () => ran.push("frame") });
  for (const target of [{ tagName: "INPUT", type: "text" }, { tagName: "INPUT", type: "number" },
                        { tagName: "TEXTAREA" }, { tagName: "SELECT" }, { tagName: "DIV", isContentEditable: true }]) {
    assert.equal(typing(target), true);
    assert.equal(k.handle(press("f", {}, target)), false);
    assert.equal(k.handle(press("z", { ctrl: true }, target)), false);
  }
  assert.deepEqual(ran, []);
  for (const type of ["range", "checkbox"]) {
    assert.equal(k.handle(press("f", {}, { tagName: "INPUT", type })), true);
  }
  assert.deepEqual(ran, ["frame", "frame"]);
});

test("when() gates a shortcut; the list names every shortcut; clashes and bad specs are errors", () => {
  const k = new Keys(), ran = [];
  let on = false;
  k.register({ key: "Tab", label: "switch mode", run: () => ran.push("tab"), when: () => on });
  assert.equal(k.handle(press("Tab")), false);
  on = true;
  assert.equal(k.handle(press("Tab")), true);
  assert.deepEqual(ran, ["tab"]);
  const listed = k.shortcuts().map((s) => s.key);
  assert.deepEqual(listed, ["?", "Escape", "Tab"]);
  k.register({ key: "F", label: "frame", run: () => {} });
  assert.throws(() => k.register({ key: "F", label: "again", run: () => {} }),
                /shortcut F: already registered for "frame"/);
  assert.throws(() => parseKey("Hyper+F"), /modifiers are Ctrl, Alt, Shift, got "Hyper"/);
  assert.throws(() => k.register({ key: "G", label: "g", run: 3 }), /run must be a function/);
  const off = k.register({ key: "G", label: "g", run: () => ran.push("g") });
  off();
  assert.equal(k.handle(press("g")), false);
});

test("? shows and hides the help overlay; Esc closes it (a minimal document)", () => {
  const made = [];
  const el = (tag) => {
    const node = { tagName: tag, children: [], hidden: false, textContent: "", ownerDocument: doc,
                   setAttribute() {}, addEventListener() {},
                   append(...c) { this.children.push(...c); }, appendChild(c) { this.children.push(c); },
                   replaceChildren(...c) { this.children = c; } };
    made.push(node);
    return node;
  };
  const doc = { createElement: el, body: { appendChild() {} } };
  const k = new Keys(null, doc);
  k.register({ key: "F", label: "frame the view", run: () => {} });
  assert.equal(k.helpShown(), false);
  k.handle(press("?", { shift: true }));
  assert.equal(k.helpShown(), true);
  const text = JSON.stringify(k.overlay.children, (key, v) => (key === "ownerDocument" ? undefined : v));
  assert.match(text, /frame the view/);
  assert.match(text, /"F"/);
  k.handle(press("Escape"));
  assert.equal(k.helpShown(), false);
  assert.equal(k.handle(press("Escape")), false);   // nothing to close: Esc is free
});
