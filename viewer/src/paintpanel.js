// The weights panel of the page (index.html's #weights-panel and the colour menu): its
// menus, sliders and buttons call the weight editor's methods (paint.js), and the
// editor asks the panel to show what changed (showSettings, showCurve, showBone,
// showColorMode). Built here: the recompute's progress bar and cancel button, the lock
// and X-mirror checkboxes, the endpoint curve's editor (spline.js). Every element is
// optional: the panel fills in what the page has.

import { SplineEditor } from "./spline.js";
import { COLOR_MODES, FALLOFFS, PAINT_MODES, PAINT_OPS } from "./paintsettings.js";

const $ = (id) => document.getElementById(id);

/** Fill a <select> (when there) with options. */
function fill(sel, items, labels) {
  if (!sel) return;
  items.forEach((m, k) => {
    const o = document.createElement("option");
    o.value = m; o.textContent = labels ? labels[k] : m;
    sel.appendChild(o);
  });
}

export class PaintPanel {
  /**
   * @param ctx     the page's context {store, history, view}
   * @param editor  the WeightEditor (paint.js) whose methods the controls call
   */
  constructor(ctx, editor) {
    this.store = ctx.store;
    this.history = ctx.history;
    this.view = ctx.view;
    this.editor = editor;
    this.curve = null;
    const ed = editor, diag = ctx.view.diag;
    fill($("color-mode"), COLOR_MODES, ["shaded", "bones", "endpoint weight (heat)", "bone weight (heat)"]);
    fill($("paint-mode"), PAINT_MODES, ["off", "bone weights", "endpoint weights"]);
    fill($("paint-op"), PAINT_OPS);
    fill($("paint-falloff"), FALLOFFS);
    fill($("endpoint-method"), ed.endpointMethods());
    const on = (id, type, f) => $(id)?.addEventListener(type, f);
    on("color-mode", "change", () => ed.setColorMode($("color-mode").value));
    on("paint-mode", "change", () => ed.setPaint({ mode: $("paint-mode").value }));
    on("paint-op", "change", () => ed.setPaint({ op: $("paint-op").value }));
    on("paint-falloff", "change", () => ed.setPaint({ falloff: $("paint-falloff").value }));
    const radius = $("paint-radius");
    if (radius) {
      radius.min = String(diag / 200); radius.max = String(diag / 2);
      radius.step = String(diag / 1000);
      radius.addEventListener("input", () => ed.setPaint({ radius: Number(radius.value) }));
    }
    on("paint-strength", "input", () => ed.setPaint({ strength: Number($("paint-strength").value) }));
    on("paint-undo", "click", () => ed.undo());
    on("paint-redo", "click", () => ed.redo());
    ctx.history.events?.on("history", () => this.updateButtons());
    on("save-rig", "click", () => this.uiCall(() => this.saveAsking(),
      (r) => (r ? `saved ${r.path}` : "not saved")));
    const progress = this.buildProgress($("endpoint-recompute"));
    on("endpoint-recompute", "click", () => {
      const m = $("endpoint-method").value, bone = ed.paintSettings().bone;
      progress.show(true);
      this.uiCall(() => ed.recompute(bone, m, {}, (st) => progress.set(st)),
                  () => `${this.store.rig.names[bone]}: endpoint weights by ${m}`, `computing (${m})...`)
        .finally(() => progress.show(false));
    });
    on("bone", "change", () => ed.selectBone(Number($("bone").value) || 0, false));
    this.buildLockAndMirror($("paint-mode"));
    const canvas = $("spline");
    if (canvas) {
      this.curve = new SplineEditor(canvas, (inner) => {
        try { ed.setSpline(ed.paintSettings().bone, inner); } catch (err) { this.say(err.message, true); }
      });
    }
    // the canvas has no size while the box is closed: draw it when it opens
    on("weights-panel", "toggle", () => this.curve && this.curve.draw());
    on("spline-apply", "click", () => ed.applySpline(ed.paintSettings().bone));
    on("spline-reset", "click", () => ed.setSpline(ed.paintSettings().bone, []));
    const save = (ctx.store.rig.summary || {}).save;
    if ($("save-rig") && !(save && save.rig)) {
      $("save-rig").disabled = true;
      $("save-rig").title = "start stbs view with --save-as PATH to save the rig";
    }
    this.showSettings();
    this.updateButtons();
  }

  /** A progress bar and a cancel button for the endpoint recompute, after `button`. */
  buildProgress(button) {
    const bar = document.createElement("progress"), cancel = document.createElement("button");
    bar.id = "endpoint-progress";
    bar.max = 1;
    bar.value = 0;
    cancel.id = "endpoint-cancel";
    cancel.type = "button";
    cancel.textContent = "cancel";
    cancel.addEventListener("click", () => this.editor.cancelRecompute().catch((err) => this.say(err.message, true)));
    const show = (on) => { bar.hidden = cancel.hidden = !on; if (button) button.disabled = on; };
    show(false);
    if (button && button.parentNode) button.parentNode.insertBefore(cancel, button.nextSibling);
    if (button && button.parentNode) button.parentNode.insertBefore(bar, button.nextSibling);
    return {
      show,
      set: (st) => {
        if (st.total > 0) { bar.max = st.total; bar.value = st.done; } else bar.removeAttribute("value");
        bar.title = `${st.stage || st.state}: ${st.done ?? 0} of ${st.total ?? "?"}`;
      },
    };
  }

  /** The lock (selected bone) and X-mirror checkboxes, after the paint menu's row. */
  buildLockAndMirror(after) {
    const row = document.createElement("div");
    row.className = "row";
    row.id = "paint-locks";
    const box = (id, text, title) => {
      const label = document.createElement("label"), input = document.createElement("input");
      input.type = "checkbox";
      input.id = id;
      label.title = title;
      label.append(input, ` ${text}`);
      row.appendChild(label);
      return input;
    };
    const lock = box("paint-lock", "lock", "lock the selected bone's weights: painting other bones leaves them");
    const mirror = box("paint-mirror", "X-mirror", "each dab also paints the mirror bone on the mirror side (x = centre)");
    const list = document.createElement("span");
    list.id = "paint-locked";
    list.className = "muted";
    row.appendChild(list);
    lock.addEventListener("change", () => this.editor.setLock(this.editor.paintSettings().bone, lock.checked));
    mirror.addEventListener("change", () => this.store.setMirror(mirror.checked));
    const anchor = after && after.closest ? after.closest("label") || after : null;
    if (anchor && anchor.parentNode) anchor.parentNode.insertBefore(row, anchor.nextSibling);
    else ($("weights-panel") || document.body).appendChild(row);
  }

  /** The save button: save; where the file exists, ask before writing over it. */
  async saveAsking() {
    try {
      return await this.editor.saveRig(false);
    } catch (err) {
      if (err.status !== 409) throw err;
      if (!window.confirm(`${err.message}\n\nWrite over it?`)) return null;
      return this.editor.saveRig(true);
    }
  }

  /** Run f, saying `busy` meanwhile, then done(its result) or its error in the status line. */
  async uiCall(f, done, busy) {
    if (busy) this.say(busy);
    try { const r = await f(); this.say(done(r)); } catch (err) { this.say(`stbs view: ${err.message}`, true); }
  }

  say(text, isError = false) {
    const el = $("status");
    if (el) { el.textContent = text; el.classList.toggle("error", isError); }
  }

  /** The editor's settings, locks and X-mirror in the controls. */
  showSettings() {
    const s = this.editor.paintSettings(), names = this.store.rig.names;
    const set = (id, key, value) => { const el = $(id); if (el) el[key] = value; };
    set("paint-mode", "value", s.mode);
    set("paint-op", "value", s.op);
    set("paint-falloff", "value", s.falloff);
    set("paint-radius", "value", String(s.radius));
    set("paint-radius-value", "textContent", s.radius.toPrecision(3));
    set("paint-strength", "value", String(s.strength));
    set("paint-strength-value", "textContent", s.strength.toFixed(2));
    set("paint-lock", "checked", s.locked.includes(s.bone));
    set("paint-mirror", "checked", this.store.mirror);
    set("paint-locked", "textContent", s.locked.length ? `locked: ${s.locked.map((i) => names[i]).join(", ")}` : "");
    this.view.renderer.domElement.classList.toggle("painting", s.mode !== "off");
  }

  updateButtons() {
    const u = $("paint-undo"), r = $("paint-redo");
    if (u) u.disabled = !this.history.canUndo;
    if (r) r.disabled = !this.history.canRedo;
  }

  showColorMode(name) {
    const sel = $("color-mode");
    if (sel) sel.value = name;
  }

  /** Bone i chosen by the API: the bone menu follows, and tells the page it changed. */
  showBone(i) {
    const sel = $("bone");
    if (sel && sel.value !== String(i)) {
      sel.value = String(i);
      sel.dispatchEvent(new Event("change"));
    }
  }

  /** The selected bone's curve (its inner points) in the curve editor. */
  showCurve(inner) {
    if (this.curve) this.curve.set(inner);
  }
}
