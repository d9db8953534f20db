import { test } from "node:test";
import assert from "node:assert/strict";
import { History } from "../src/history.js";
import { Events } from "../src/events.js";

function counter() {
  const state = { x: 0 };
  const add = (k) => ({ name: `add ${k}`, execute: () => { state.x += k; }, undo: () => { state.x -= k; } });
  return { state, add };
}

test("execute, undo and redo restore the state in order", async () => {
  const h = new History();
  const { state, add } = counter();
  await h.execute(add(1));
  await h.execute(add(10));
  assert.equal(state.x, 11);
  assert.equal(await h.undo(), "add 10");
  assert.equal(state.x, 1);
  assert.equal(await h.undo(), "add 1");
  assert.equal(await h.undo(), null);
  assert.equal(state.x, 0);
  await h.redo();
  await h.redo();
  assert.equal(state.x, 11);
  assert.equal(h.canRedo, false);
});

test("a new command drops the redos; push records an applied one", async () => {
  const h = new History();
  const { state, add } = counter();
  await h.execute(add(1));
  await h.undo();
  assert.equal(h.canRedo, true);
  state.x += 5;
  h.push(add(5));
  assert.equal(h.canRedo, false);
  await h.undo();
  assert.equal(state.x, 0);
});

test("the limit drops the oldest; events report the stacks", async () => {
  const ev = new Events(), seen = [];
  ev.on("history", (s) => seen.push([s.undo, s.redo]));
  const h = new History(ev, 2);
  const { add } = counter();
  for (let k = 0; k < 3; k++) await h.execute(add(k));
  assert.equal(h.undos.length, 2);
  await h.undo();
  assert.deepEqual(seen.at(-1), [1, 1]);
});

test("a failing undo leaves the command to undo", async () => {
  const h = new History();
  h.push({ name: "bad", execute() {}, undo() { throw new Error("no"); } });
  await assert.rejects(h.undo(), /no/);
  assert.equal(h.canUndo, true);
  assert.equal(h.canRedo, false);
});

test("async commands run one after another", async () => {
  const h = new History(), order = [];
  const slow = (k, ms) => ({ name: k, execute: () => new Promise((r) => setTimeout(() => { order.push(k); r(); }, ms)),
                             undo() {} });
  await Promise.all([h.execute(slow("a", 20)), h.execute(slow("b", 1))]);
  assert.deepEqual(order, ["a", "b"]);
});

test("events: unsubscribe, and a handler needs to be a function", () => {
  const ev = new Events();
  let n = 0;
  const off = ev.on("x", () => n++);
  ev.emit("x");
  off();
  ev.emit("x");
  assert.equal(n, 1);
  assert.throws(() => ev.on("x", 3), /expected a function/);
});
