// One undo history for the page (after three.js's editor, History.js with Command
// objects): pose edits, paint strokes, key edits and weight recomputes are commands,
// each with execute() and undo(). Commands may be async; they run one after another.

/**
 * A command: { name, execute(), undo() }. execute() is called when the command is
 * first run (History.execute) and on redo; undo() reverts it. A command already applied
 * (a paint stroke, done dab by dab) is recorded with History.push instead.
 */
export class History {
  /** events (optional): emits "history" {undo, redo} after each change. */
  constructor(events = null, limit = 200) {
    this.events = events;
    this.limit = limit;
    this.undos = [];
    this.redos = [];
    this.queue = Promise.resolve();
  }

  get canUndo() { return this.undos.length > 0; }
  get canRedo() { return this.redos.length > 0; }

  /** Run a command and record it; resolves to what execute() returned. */
  execute(cmd) {
    return this.run(async () => {
      const out = await cmd.execute();
      this.record(cmd);
      return out;
    });
  }

  /** Record a command that has already been applied. */
  push(cmd) {
    this.record(cmd);
  }

  /** Undo the last command; resolves to its name, or null when there is none. */
  undo() { return this.run(() => this.step(this.undos, this.redos, "undo")); }

  /** Redo the last undone command; resolves to its name, or null when there is none. */
  redo() { return this.run(() => this.step(this.redos, this.undos, "execute")); }

  /** Forget every command. */
  clear() {
    this.undos.length = 0;
    this.redos.length = 0;
    this.changed();
  }

  /** Resolves once every queued undo, redo and execute has finished. */
  idle() { return this.queue.then(() => undefined, () => undefined); }

  // ------------------------------------------------------------------ inside
  record(cmd) {
    if (!cmd || typeof cmd.undo !== "function" || typeof cmd.execute !== "function") {
      throw new TypeError("history: a command needs execute() and undo()");
    }
    this.undos.push(cmd);
    if (this.undos.length > this.limit) this.undos.shift();
    this.redos.length = 0;
    this.changed();
  }

  async step(from, to, how) {
    const cmd = from.pop();
    if (!cmd) return null;
    try {
      await cmd[how]();
    } catch (err) {
      from.push(cmd);          // not done: stays where it was
      this.changed();
      throw err;
    }
    to.push(cmd);
    this.changed();
    return cmd.name ?? null;
  }

  run(f) {
    const mine = this.queue.catch(() => {}).then(f);
    this.queue = mine;
    return mine;
  }

  changed() {
    if (this.events) this.events.emit("history", { undo: this.undos.length, redo: this.redos.length });
  }
}
