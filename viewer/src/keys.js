// The page's keyboard shortcuts: one keydown handler for the page. Modules register
// their shortcuts here ({key, label, run, when?}); `?` shows a help overlay listing
// every registered one, Esc closes it. Nothing runs while typing in a field.
// Imports without a DOM (the overlay is made when first shown).

const MODIFIERS = ["Ctrl", "Alt", "Shift"];
const NAMED = { " ": "Space", Esc: "Escape" };
// inputs that take keys as text; a slider, a checkbox or a button does not
const TEXT_INPUTS = new Set(["text", "number", "search", "email", "password", "url", "tel",
                             "date", "time", "datetime-local", "month", "week", ""]);

/** A key's name as a spec writes it: "Space", "Tab", "Escape", "Z", "[", "?". */
export function keyName(key) {
  if (NAMED[key]) return NAMED[key];
  return key.length === 1 ? key.toUpperCase() : key;
}

/** Parse "Ctrl+Shift+Z" into {key, ctrl, alt, shift}; throws naming a bad spec. */
export function parseKey(spec) {
  if (typeof spec !== "string" || !spec) throw new Error(`key: expected a key such as "Ctrl+Z", got ${JSON.stringify(spec)}`);
  const parts = spec === "+" ? ["+"] : spec.split("+");
  const key = keyName(parts.pop());
  const mods = new Set(parts);
  for (const m of mods) {
    if (!MODIFIERS.includes(m)) {
      throw new Error(`key ${JSON.stringify(spec)}: modifiers are ${MODIFIERS.join(", ")}, got ${JSON.stringify(m)}`);
    }
  }
  return { key, ctrl: mods.has("Ctrl"), alt: mods.has("Alt"), shift: mods.has("Shift") };
}

/** Whether an event's target takes typed text (an input field, a text area, a select). */
export function typing(target) {
  if (!target || typeof target !== "object") return false;
  if (target.isContentEditable) return true;
  const tag = String(target.tagName || "").toUpperCase();
  if (tag === "TEXTAREA" || tag === "SELECT") return true;
  return tag === "INPUT" && TEXT_INPUTS.has(String(target.type || "").toLowerCase());
}

function matches(p, e) {
  if (p.key !== keyName(e.key)) return false;
  if (p.ctrl !== !!(e.ctrlKey || e.metaKey) || p.alt !== !!e.altKey) return false;
  // Shift counts for letters and named keys; "?" or "{" need it on most layouts anyway
  const shiftMatters = p.key.length > 1 || p.key.toLowerCase() !== p.key.toUpperCase();
  return !shiftMatters || p.shift === !!e.shiftKey;
}

export class Keys {
  /** target: what to listen on for keydown (the window; null: none, call handle()). */
  constructor(target = null, doc = null) {
    this.list = [];
    this.doc = doc;
    this.overlay = null;
    this.register({ key: "?", label: "show or hide this list of shortcuts", run: () => this.toggleHelp() });
    this.register({ key: "Escape", label: "close this list", run: () => this.hideHelp(),
                    when: () => this.helpShown() });
    if (target) target.addEventListener("keydown", (e) => this.handle(e));
  }

  /** Add a shortcut; returns a function that removes it. A key held by another
   * shortcut that is active at the same time is an error. */
  register({ key, label, run, when = null }) {
    const p = parseKey(key);
    if (typeof run !== "function") throw new Error(`shortcut ${key}: run must be a function, got ${typeof run}`);
    if (typeof label !== "string" || !label) throw new Error(`shortcut ${key}: expected a label, got ${JSON.stringify(label)}`);
    const clash = this.list.find((s) => s.p.key === p.key && s.p.ctrl === p.ctrl && s.p.alt === p.alt &&
                                        s.p.shift === p.shift && !s.when && !when);
    if (clash) throw new Error(`shortcut ${key}: already registered for "${clash.label}"`);
    const entry = { key, label, run, when, p };
    this.list.push(entry);
    if (this.overlay) this.fillHelp();
    return () => { this.list = this.list.filter((s) => s !== entry); };
  }

  /** The shortcuts as {key, label}, in the order registered. */
  shortcuts() { return this.list.map(({ key, label }) => ({ key, label })); }

  /** Run the shortcut of a keydown event, if any; returns whether one ran. */
  handle(e) {
    if (e.defaultPrevented || e.repeat && keyName(e.key) !== "[" && keyName(e.key) !== "]") return false;
    if (typing(e.target)) return false;
    const s = this.list.find((x) => matches(x.p, e) && (!x.when || x.when()));
    if (!s) return false;
    if (typeof e.preventDefault === "function") e.preventDefault();
    const out = s.run(e);
    if (out && typeof out.catch === "function") out.catch((err) => console.error(`${s.key}: ${err.message}`));
    return true;
  }

  // ------------------------------------------------------------------ the help overlay
  helpShown() { return !!this.overlay && !this.overlay.hidden; }

  toggleHelp() { return this.helpShown() ? this.hideHelp() : this.showHelp(); }

  showHelp() {
    const doc = this.doc || (typeof document === "undefined" ? null : document);
    if (!doc) return false;
    if (!this.overlay) {
      this.overlay = doc.createElement("div");
      this.overlay.id = "help";
      this.overlay.setAttribute("role", "dialog");
      this.overlay.addEventListener("click", () => this.hideHelp());
      doc.body.appendChild(this.overlay);
    }
    this.fillHelp();
    this.overlay.hidden = false;
    return true;
  }

  hideHelp() {
    if (this.overlay) this.overlay.hidden = true;
    return false;
  }

  fillHelp() {
    const doc = this.overlay.ownerDocument;
    const h = doc.createElement("h2");
    h.textContent = "shortcuts";
    const table = doc.createElement("table");
    for (const s of this.list) {
      const tr = doc.createElement("tr"), k = doc.createElement("td"), l = doc.createElement("td");
      const kbd = doc.createElement("kbd");
      kbd.textContent = s.key;
      k.appendChild(kbd);
      l.textContent = s.label;
      tr.append(k, l);
      table.appendChild(tr);
    }
    const note = doc.createElement("p");
    note.textContent = "wheel: zoom; right-drag: pan; Alt+drag or middle-drag: orbit";
    this.overlay.replaceChildren(h, table, note);
  }
}
