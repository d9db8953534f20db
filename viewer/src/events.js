// The page's events: modules subscribe to what they show and emit what they change,
// instead of reaching into each other (after three.js's editor, Signals).

export class Events {
  constructor() { this.handlers = new Map(); }

  /** Call fn(payload) on each emit of name; returns a function that unsubscribes. */
  on(name, fn) {
    if (typeof fn !== "function") throw new TypeError(`events.on(${JSON.stringify(name)}): expected a function`);
    if (!this.handlers.has(name)) this.handlers.set(name, new Set());
    this.handlers.get(name).add(fn);
    return () => this.handlers.get(name)?.delete(fn);
  }

  /** Call every handler of name with payload, in the order they subscribed. */
  emit(name, payload) {
    const hs = this.handlers.get(name);
    if (!hs) return;
    for (const fn of [...hs]) fn(payload);
  }
}
