// Side by side: the canvas split into two viewports sharing the camera, the same
// mesh and material drawn twice (scissor test), the left half in the page's method,
// the right half in a second one (only the material's uMethod uniform changes).

import * as THREE from "three";

export class Compare {
  /**
   * ctx: {view, ...}; the view's methodIndex is the left half's method, its methods
   * the server's names in the shader's order.
   */
  constructor(ctx) {
    this.view = ctx.view;
    this.methods = ctx.view.methods;
    this.index = -1;                       // the right half's method; -1: one view
    this.size = new THREE.Vector2();
    const sel = document.getElementById("compare");
    if (sel) {
      for (const m of this.methods) {
        const o = document.createElement("option");
        o.value = o.textContent = m;
        sel.appendChild(o);
      }
      sel.value = "";
      sel.addEventListener("change", () => this.set(sel.value || null));
    }
    this.labels = document.getElementById("compare-labels");
  }

  get active() { return this.index >= 0; }

  /** The second method's name, or null when the view is not split. */
  method() { return this.active ? this.methods[this.index] : null; }

  /** Split the view with `name` on the right, or back to one view with null. */
  set(name) {
    if (name === null || name === undefined || name === "") {
      this.index = -1;
    } else {
      const i = this.methods.indexOf(name);
      if (i < 0) {
        throw new Error(`compare: the second method must be one of ${this.methods.join(", ")} or null, ` +
                        `got ${JSON.stringify(name)}`);
      }
      this.index = i;
    }
    const sel = document.getElementById("compare");
    if (sel) sel.value = this.active ? this.methods[this.index] : "";
    this.showLabels();
    this.view.resize();             // the camera's aspect follows the viewport's
    return this.method();
  }

  showLabels() {
    const el = this.labels;
    if (!el) return;
    el.hidden = !this.active;
    if (!this.active) return;
    const [l, r] = el.querySelectorAll("span");
    if (l) l.textContent = this.methods[this.view.methodIndex];
    if (r) r.textContent = this.methods[this.index];
  }

  /**
   * Viewport k (0: left, the page's method; 1: right) in CSS pixels on the page:
   * {left, top, width, height}. One view: the whole canvas for k = 0.
   */
  rect(k = 0) {
    const c = this.view.renderer.domElement.getBoundingClientRect();
    if (!this.active) return { left: c.left, top: c.top, width: c.width, height: c.height };
    const half = Math.floor(c.width / 2);
    return k === 0 ? { left: c.left, top: c.top, width: half, height: c.height }
                   : { left: c.left + half, top: c.top, width: c.width - half, height: c.height };
  }

  /** The viewport under a page point (the left one outside both). */
  rectAt(x, y) {
    if (this.active) {
      const r = this.rect(1);
      if (x >= r.left && x <= r.left + r.width && y >= r.top && y <= r.top + r.height) return r;
    }
    return this.rect(0);
  }

  /** Draw both halves: the same scene, camera and material, two uMethod values. */
  render() {
    const { renderer, scene, camera } = this.view;
    renderer.getSize(this.size);
    const w = this.size.x, h = this.size.y, half = Math.floor(w / 2);
    const primary = this.view.methodIndex;
    renderer.setScissorTest(true);
    try {
      for (const [x, width, method] of [[0, half, primary], [half, w - half, this.index]]) {
        renderer.setViewport(x, 0, width, h);
        renderer.setScissor(x, 0, width, h);
        this.view.setUniform("uMethod", method);
        renderer.render(scene, camera);
      }
    } finally {
      this.view.setUniform("uMethod", primary);
      renderer.setScissorTest(false);
      renderer.setViewport(0, 0, w, h);
    }
    this.showLabels();
  }
}
