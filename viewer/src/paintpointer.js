// The pointer while weight painting: a press on the mesh starts a stroke (the camera's
// orbit waits), moves a quarter radius apart add dabs, the release ends it; between
// strokes the brush's ring follows the pointer, placed once a frame. The strokes
// themselves are the editor's (paint.js): this module only calls it.
//
// It listens on window in the capture phase, so it runs before the canvas' own
// listeners (joint drags, the orbit controls), and takes a press only in a paint mode,
// with the left button, without Alt (Alt+drag orbits, as in every mode), on the mesh.

export class PaintPointer {
  /**
   * @param ctx     the page's context (its view: the canvas, setOrbit)
   * @param editor  the WeightEditor: settings, stroke, pick, beginStroke, dab, endStroke,
   *                showRing, hideRing
   */
  constructor(ctx, editor) {
    this.view = ctx.view;
    this.editor = editor;
    this.canvas = ctx.view.renderer.domElement;
    this.hoverAt = null;
    this.hoverFrame = 0;
    window.addEventListener("pointerdown", (e) => this.down(e), { capture: true });
    window.addEventListener("pointermove", (e) => this.move(e), { capture: true });
    window.addEventListener("pointerup", (e) => this.up(e), { capture: true });
    window.addEventListener("pointercancel", (e) => this.up(e), { capture: true });
    this.canvas.addEventListener("pointerleave", () => editor.hideRing());
  }

  down(e) {
    const ed = this.editor;
    if (ed.settings.mode === "off" || e.target !== this.canvas || e.button !== 0 || e.altKey ||
        ed.stroke) return;
    const hit = ed.pick(e.clientX, e.clientY);
    if (!hit) return;                          // off the mesh: the orbit controls have it
    e.stopImmediatePropagation();
    e.preventDefault();
    this.view.setOrbit(false);
    try { this.canvas.setPointerCapture(e.pointerId); } catch (_) { /* synthetic */ }
    ed.beginStroke(e.pointerId);
    ed.dab(hit, e.clientX, e.clientY);
  }

  move(e) {
    const ed = this.editor, st = ed.stroke;
    if (!st) { this.hover(e); return; }
    if (e.pointerId !== st.id) return;
    e.stopImmediatePropagation();
    e.preventDefault();
    const hit = ed.pick(e.clientX, e.clientY);
    if (!hit) return;
    const last = st.last;
    const dist = last ? Math.hypot(hit.rest[0] - last[0], hit.rest[1] - last[1], hit.rest[2] - last[2]) : Infinity;
    if (dist < 0.25 * ed.settings.radius) return;     // dabs a quarter radius apart
    ed.dab(hit, e.clientX, e.clientY);
  }

  up(e) {
    const ed = this.editor;
    if (!ed.stroke || e.pointerId !== ed.stroke.id) return;
    e.stopImmediatePropagation();
    try { this.canvas.releasePointerCapture(e.pointerId); } catch (_) { /* synthetic */ }
    this.view.setOrbit(true);
    ed.endStroke();
  }

  /** Pointer over the canvas in a paint mode: the ring follows (once a frame). */
  hover(e) {
    const ed = this.editor;
    if (ed.settings.mode === "off" || e.target !== this.canvas) { ed.hideRing(); return; }
    this.hoverAt = [e.clientX, e.clientY];
    if (this.hoverFrame) return;
    this.hoverFrame = requestAnimationFrame(() => {
      this.hoverFrame = 0;
      if (ed.stroke || ed.settings.mode === "off" || !this.hoverAt) return;
      const hit = ed.pick(...this.hoverAt);
      if (hit) ed.showRing(hit); else ed.hideRing();
    });
  }
}
