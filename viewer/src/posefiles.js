// Pose files from the page: save the current pose on the server (POST /api/save-pose,
// into the rig's pose folder), download it as JSON, load a pose file from this machine.

export class PoseFiles {
  /** ctx: {store, history, poses, ...}; apiJSON(path, options) and status(text,
   * isError) are the page's own. */
  constructor(ctx, apiJSON, status) {
    this.store = ctx.store;
    this.history = ctx.history;
    this.poses = ctx.poses;
    this.view = ctx.view;
    this.apiJSON = apiJSON;
    this.status = status;
    const save = document.getElementById("save-pose");
    const summary = this.store.rig.summary;
    const saving = !!(summary.save && summary.save.pose);
    if (save) {
      save.disabled = !saving;
      save.title = saving ? "save the pose into the rig's folder"
        : "saving poses is off: start stbs view with a rig file or --save-as";
      save.addEventListener("click", () => this.save(this.name()).catch(() => {}));
    }
    document.getElementById("download-pose")?.addEventListener("click",
      () => this.download().catch((err) => this.status(`download pose: ${err.message}`, true)));
    const input = document.getElementById("load-pose");
    input?.addEventListener("change", () => {
      const file = input.files && input.files[0];
      if (file) this.loadFile(file).catch(() => {}).finally(() => { input.value = ""; });
    });
  }

  /** The name field's value: null when empty (the server picks NAME-pose-NNN.json). */
  name() {
    const el = document.getElementById("pose-name");
    const s = el ? el.value.trim() : "";
    if (!s) return null;
    return s.toLowerCase().endsWith(".json") ? s : `${s}.json`;
  }

  /** Save the current pose as `name` (null: the server's next free name); resolves to {path, name}. */
  async settled() {
    await this.history.idle();
    await this.poses.idle();
  }

  async save(name = null, overwrite = false) {
    await this.settled();
    const body = { pose: this.store.poseObject };
    if (name !== null && name !== undefined) body.name = name;
    if (overwrite) body.overwrite = true;
    try {
      const reply = await this.apiJSON("/api/save-pose", {
        method: "POST", headers: { "Content-Type": "application/json" }, body: JSON.stringify(body) });
      this.status(`saved the pose to ${reply.path}`);
      return reply;
    } catch (err) {
      this.status(`save pose: ${err.message}`, true);
      throw err;
    }
  }

  /** The current pose as pose-file text (the server's canonical form, bones by name). */
  async text() {
    await this.settled();
    return JSON.stringify(await this.poses.get(), null, 1) + "\n";
  }

  async download() {
    const blob = new Blob([await this.text()], { type: "application/json" });
    const url = URL.createObjectURL(blob);
    const a = document.createElement("a");
    a.href = url;
    a.download = this.name() || `${this.store.rig.summary.name || "rig"}-pose.json`;
    document.body.appendChild(a);
    a.click();
    a.remove();
    setTimeout(() => URL.revokeObjectURL(url), 1000);
  }

  /** Read a pose file's text and make it the pose (one undo step); errors go to the status line. */
  async loadText(text, label = "pose file") {
    let obj;
    try {
      obj = JSON.parse(text);
    } catch (err) {
      const e = new Error(`${label}: not valid JSON (${err.message})`);
      this.status(`load pose: ${e.message}`, true);
      throw e;
    }
    await this.settled();
    const before = this.store.poseObject, poses = this.poses;
    try {
      const back = await poses.post(obj);
      this.view.frame();
      const after = this.store.poseObject;
      this.history.push({ name: "load pose", execute: () => poses.send(after), undo: () => poses.send(before) });
      this.status(`loaded the pose from ${label}`);
      return back;
    } catch (err) {
      const msg = err.message.replace(/^\/api\/pose: /, "");
      const e = new Error(`${label}: ${msg.replace(/^pose: /, "")}`);
      this.status(`load pose: ${e.message}`, true);
      throw e;
    }
  }

  async loadFile(file) {
    return this.loadText(await file.text(), file.name);
  }
}
