// Pose files from the page: save the current pose on the server (POST /api/save-pose,
// into the rig's pose folder), download it as JSON, load a pose file from this machine.

export class PoseFiles {
  /** apiJSON(path, options) and status(text, isError) are the page's own. */
  constructor(viewer, apiJSON, status) {
    this.v = viewer;
    this.apiJSON = apiJSON;
    this.status = status;
    const save = document.getElementById("save-pose");
    const saving = !!(viewer.summary.save && viewer.summary.save.pose);
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
  async save(name = null, overwrite = false) {
    await this.v.settled();
    const body = { pose: this.v.lastSent };
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
    await this.v.settled();
    return JSON.stringify(await this.v.getPose(), null, 1) + "\n";
  }

  async download() {
    const blob = new Blob([await this.text()], { type: "application/json" });
    const url = URL.createObjectURL(blob);
    const a = document.createElement("a");
    a.href = url;
    a.download = this.name() || `${this.v.summary.name || "rig"}-pose.json`;
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
    await this.v.settled();
    const before = this.v.lastSent, v = this.v;
    try {
      const back = await v.setPose(obj);
      const after = v.lastSent;
      v.history.push({ name: "load pose", execute: () => v.send(after), undo: () => v.send(before) });
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
