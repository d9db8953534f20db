// The timeline: keyed poses (a clip, docs/clips.md), a scrubber, playback at the
// clip's fps, saving and loading clip files, and export to an animated GIF.
//
// The page never interpolates poses itself: the server holds the clip (POST /api/clip
// registers the page's keys once per edit; a character's own animation or a retargeted
// capture is held from the start) and evaluates it with stbs.Clip.arrays, so what is
// shown is Clip.pose exactly, step and cubic channels included. Playback asks for the
// frames ahead in batches (GET /api/clip/ID/frames?t=...); a seek makes the clip's
// pose at t the server's current pose (POST /api/clip/ID/seek {time}, its bone rows back), so edits start
// from it. Neither sends the clip again. One implementation of clips (the library's)
// is why: the page's own would have to follow every kind of channel the readers make.

const DEFAULT_FPS = 30;
const MIN_OPEN_FPS = 24;         // a clip opened from the server keyed less often plays at 30
const INTERPOLATIONS = ["linear", "step"];
const MAX_EXPORT_WIDTH = 480;    // px: GIF frames are scaled down to at most this width
const MAX_EXPORT_FRAMES = 600;   // what POST /api/export takes
const MAX_BATCH = 240;           // frames a frames request asks for (the server takes 2000)
const GRID_TOL = 1e-9;           // as stbs.Clip.sample_times

function copy(x) { return JSON.parse(JSON.stringify(x)); }

function finite(name, x) {
  if (typeof x !== "number" || !Number.isFinite(x)) {
    throw new Error(`${name} must be a finite number of seconds, got ${JSON.stringify(x)}`);
  }
  return x;
}

export class Timeline {
  /** ctx: {store, history, view, poses, ...}; api(path, options) (a fetch that throws
   * with the server's message), status(text, isError) and seekClip(id, time) (the clip's
   * pose at a time made current, its bone rows back) are the page's own. */
  constructor(ctx, api, status, seekClip) {
    this.seekClip = seekClip;
    this.store = ctx.store;
    this.history = ctx.history;
    this.view = ctx.view;
    this.poses = ctx.poses;
    this.api = api;
    this.status = status;
    this.fps = DEFAULT_FPS;
    this.interpolation = "linear";
    // [{time, pose}] sorted by time; pose: a pose-file object, or null for a key of a
    // clip the server holds whose pose the page has not needed yet (source)
    this.list = [];
    this.source = null;          // id of the server's clip the null poses are keys of
    this.held = null;            // id of the server's clip that is these keys now, or null
    this.time = 0;
    this.loop = true;
    this.version = 0;            // bumped on every change of the clip
    this.playing = false;
    this.raf = 0;
    this.buildBar();
  }

  async apiJSON(path, options) { return (await this.api(path, options)).json(); }

  // ------------------------------------------------------------------ the clip
  /** The clip object of the keys (null poses where not fetched), or null without keys. */
  clip() {
    if (!this.list.length) return null;
    return { fps: this.fps, interpolation: this.interpolation, keys: copy(this.list) };
  }

  /** The clip object with every key's pose (fetched once from the server where needed). */
  async fullClip() {
    if (this.list.some((k) => k.pose === null)) {
      const { clip } = await this.apiJSON(`/api/clip/${this.source}/keys`);
      const byTime = new Map(clip.keys.map((k) => [k.time, k.pose]));
      for (const k of this.list) if (k.pose === null) k.pose = byTime.get(k.time);
    }
    return this.clip();
  }

  keys() { return copy(this.list); }

  /** After a change of the keys: bump the version; `evaluated`: the poses change, so the
   * clip is registered again before it is next shown. */
  changed(evaluated = true) {
    this.version += 1;
    if (evaluated) this.held = null;
    this.updateBar();
  }

  /** The id of the server's clip for the keys as they are: registered (one POST of the
   * keys) after an edit, else the one held. */
  async clipId() {
    if (this.held) return this.held;
    const version = this.version;
    const clip = await this.fullClip();
    const reply = await this.apiJSON("/api/clip", this.post(clip));
    if (version === this.version) this.held = reply.id;
    return reply.id;
  }

  /** Run f(id) on the clip's id; a clip the server dropped (404) is registered again. */
  async withClip(f) {
    const id = await this.clipId();
    try { return await f(id); } catch (err) {
      if (err.status !== 404 || id === this.source) throw err;
      if (this.held === id) this.held = null;
      return f(await this.clipId());
    }
  }

  // ------------------------------------------------------------------ undo and redo
  /** The clip's state and the pose: what a key edit's undo gives back. */
  snapshot() {
    return copy({ list: this.list, fps: this.fps, interpolation: this.interpolation,
                  source: this.source, held: this.held, time: this.time, pose: this.store.poseObject });
  }

  async restore(s) {
    this.stop();
    const c = copy(s);
    this.list = c.list;
    this.fps = c.fps;
    this.interpolation = c.interpolation;
    this.source = c.source;
    this.changed();
    this.held = c.held;
    this.time = c.time;
    if (JSON.stringify(this.store.poseObject) !== JSON.stringify(c.pose)) await this.poses.send(c.pose);
    this.updateBar();
  }

  /** Run a key edit f() and record it on the History (one undo step, pose included). */
  async edit(name, f) {
    await this.poses.idle();
    const before = this.snapshot();
    const out = await f();
    const after = this.snapshot();
    if (JSON.stringify(after) === JSON.stringify(before)) return out;     // nothing changed
    this.history.push({ name, execute: () => this.restore(after), undo: () => this.restore(before) });
    return out;
  }

  /** Add (or replace) the key at `time` with `pose` (default: the current pose, GET /api/pose). */
  addKey(time = this.time, pose = null) {
    finite("time", time);
    if (pose !== null && pose !== undefined && (typeof pose !== "object" || Array.isArray(pose))) {
      throw new Error(`pose must be a pose object (either form of a pose file), got ${JSON.stringify(pose)}`);
    }
    return this.edit("add key", () => this.addKeyNow(time, pose));
  }

  async addKeyNow(time, pose) {
    if (pose === null || pose === undefined) pose = await this.apiJSON("/api/pose");
    const key = { time, pose: copy(pose) };
    const at = this.list.findIndex((k) => k.time === time);
    if (at >= 0) this.list[at] = key;
    else { this.list.push(key); this.list.sort((a, b) => a.time - b.time); }
    this.time = time;
    this.changed();
    return this.keys();
  }

  /** Delete the key at `time` (default: the key nearest the current time); the keys left. */
  deleteKey(time = null) {
    if (time !== null && time !== undefined) finite("time", time);
    return this.edit("delete key", () => this.deleteKeyNow(time));
  }

  deleteKeyNow(time) {
    if (!this.list.length) return this.keys();
    let at;
    if (time === null || time === undefined) {
      at = 0;
      this.list.forEach((k, i) => {
        if (Math.abs(k.time - this.time) < Math.abs(this.list[at].time - this.time)) at = i;
      });
    } else {
      finite("time", time);
      at = this.list.findIndex((k) => k.time === time);
      if (at < 0) {
        throw new Error(`no key at time ${time}; the keys are at ${this.list.map((k) => k.time).join(", ")}`);
      }
    }
    this.list.splice(at, 1);
    this.changed();
    return this.keys();
  }

  clearKeys() { return this.edit("clear keys", () => this.clearKeysNow()); }

  clearKeysNow() {
    this.stop();
    this.list = [];
    this.time = 0;
    this.changed();
    return [];
  }

  /** Replace the clip by a clip file object (checked by the server, which then holds it);
   * shows its first key; resolves to getClip(). */
  async setClip(obj) {
    if (!obj || typeof obj !== "object" || Array.isArray(obj)) {
      throw new Error(`clip must be a clip object {fps, interpolation, keys}, got ${JSON.stringify(obj)}`);
    }
    return this.edit("set clip", () => this.setClipNow(obj));
  }

  async setClipNow(obj) {
    const reply = await this.apiJSON("/api/clip", this.post(obj));    // the server's read_clip
    this.stop();
    this.fps = reply.fps;
    this.interpolation = reply.interpolation;
    this.list = obj.keys.map((k) => ({ time: Number(k.time), pose: copy(k.pose) }))
      .sort((a, b) => a.time - b.time);
    this.source = null;
    this.changed();
    this.held = reply.id;
    this.time = reply.start;
    await this.show(this.time);
    return this.clip();
  }

  /** Open a clip the server holds (GET /api/clip's summary): its keys' times now, their
   * poses when an edit needs them; shows its first key. A clip keyed less often than
   * MIN_OPEN_FPS a second (a file's few keys) plays at DEFAULT_FPS. */
  async open(summary) {
    this.stop();
    this.fps = summary.fps >= MIN_OPEN_FPS ? summary.fps : DEFAULT_FPS;
    this.interpolation = summary.interpolation;
    this.list = summary.keys.map((t) => ({ time: t, pose: null }));
    this.source = summary.id;
    this.changed();
    this.held = summary.id;
    this.time = summary.start;
    await this.show(this.time);
  }

  /** The fps playback, export and saving use (the clip's poses do not depend on it). */
  setFps(fps) {
    if (typeof fps !== "number" || !Number.isFinite(fps) || fps <= 0) {
      throw new Error(`fps must be a number > 0, got ${JSON.stringify(fps)}`);
    }
    return this.edit("set fps", () => {
      this.fps = fps;
      this.changed(false);
      return fps;
    });
  }

  setInterpolation(name) {
    if (!INTERPOLATIONS.includes(name)) {
      throw new Error(`interpolation must be one of ${INTERPOLATIONS.join(", ")}, got ${JSON.stringify(name)}`);
    }
    return this.edit("set interpolation", () => {
      if (name !== this.interpolation) {
        this.interpolation = name;
        this.changed();
      }
      return name;
    });
  }

  post(body) {
    return { method: "POST", headers: { "Content-Type": "application/json" }, body: JSON.stringify(body) };
  }

  needKeys(what) {
    if (!this.list.length) throw new Error(`${what}: the clip has no keys (add a key first)`);
  }

  /** The clip's fps grid from its first key to its last (stbs.Clip.sample_times). */
  grid() {
    const start = this.list[0].time, end = this.list[this.list.length - 1].time;
    const m = Math.floor((end - start) * this.fps + GRID_TOL) + 1;
    return { start, count: m, at: (k) => start + k / this.fps };
  }

  /**
   * The clip's poses at `times` (GET /api/clip/ID/frames, batches of MAX_BATCH), each
   * {rotations, origins, stretch, twist} as GET /api/pose/bones gives a pose.
   */
  async frames(times) {
    const out = [];
    for (let k = 0; k < times.length; k += MAX_BATCH) {
      const part = times.slice(k, k + MAX_BATCH);
      const r = await this.withClip((id) => this.api(`/api/clip/${id}/frames?t=${part.map(String).join(",")}`));
      const [n, b, m] = r.headers.get("X-Stbs-Shape").split(",").map(Number);
      const rows = new Float64Array(await r.arrayBuffer());
      const d = this.store.rig.dim, nb = this.store.rig.b;
      if (n !== part.length || b !== nb || m !== d * d + d + 3) {
        throw new Error(`frames: expected ${part.length} x ${nb} x ${d * d + d + 3} values, got ${n} x ${b} x ${m}`);
      }
      for (let f = 0; f < n; f++) {
        const rotations = [], origins = [], stretch = [], twist = [];
        for (let i = 0; i < b; i++) {
          const o = (f * b + i) * m;
          const R = [];
          for (let r0 = 0; r0 < d; r0++) R.push(Array.from(rows.subarray(o + d * r0, o + d * r0 + d)));
          rotations.push(R);
          origins.push(Array.from(rows.subarray(o + d * d, o + d * d + d)));
          stretch.push(rows[o + d * d + d]);
          twist.push([rows[o + d * d + d + 1], rows[o + d * d + d + 2]]);
        }
        out.push({ rotations, origins, stretch, twist });
      }
    }
    return out;
  }

  // ------------------------------------------------------------------ showing a time
  /** Show one frame's bone arrays (the store's pose; the pose object stays). */
  draw(frame) {
    this.store.setPose(frame);
  }

  /**
   * Show the clip's pose at t exactly and make it the server's current pose. Shows run
   * one after another in the order asked for, so the last one asked for is what stays.
   */
  show(t) {
    const run = async () => {
      const reply = await this.withClip((id) => this.seekClip(id, t));
      this.store.setPose(reply.bones, reply.pose);     // the bones and the pose object
      this.time = t;
      this.updateBar();
      return { time: t };
    };
    const mine = this.poses.track((this.showing || Promise.resolve()).catch(() => {}).then(run));
    this.showing = mine;
    mine.finally(() => { if (this.showing === mine) this.showing = null; }).catch(() => {});
    return mine;
  }

  /** Stop playing and show the clip at t (seconds); resolves to {time} once drawn. */
  async seek(t) {
    finite("t", t);
    this.needKeys("seek");
    this.stop();
    await this.poses.idle();
    await this.show(t);
    return { time: t };
  }

  /**
   * Play from the current time (from the start when at or past the end) on the fps
   * grid, by the wall clock; the frames come in batches, each asked for while the one
   * before plays. Resolves once the first frame is drawn.
   */
  async play() {
    this.needKeys("play");
    if (this.playing) return this.state();
    await this.poses.idle();
    const grid = this.grid(), n = grid.count, fps = this.fps;
    const batch = Math.min(MAX_BATCH, Math.max(16, Math.ceil(fps)));
    let k0 = Math.round((this.time - grid.start) * fps);
    if (!(k0 >= 0 && k0 < n - 1)) k0 = 0;
    const cache = new Map();                  // frame index -> frame
    let asked = null;                         // the batch in flight
    const fetchFrom = (k) => {                // the batch of frames from k (wrapping)
      const ks = [];
      for (let j = 0; j < Math.min(batch, n); j++) {
        const kk = (k + j) % n;
        if (kk < k && !this.loop) break;
        if (!cache.has(kk)) ks.push(kk);
      }
      if (!ks.length) return Promise.resolve();
      asked = this.frames(ks.map(grid.at)).then((fs) => {
        fs.forEach((f, j) => cache.set(ks[j], f));
      }).finally(() => { asked = null; });
      return asked;
    };
    await fetchFrom(k0);
    const version = this.version;
    const wall0 = performance.now();
    this.playing = true;
    this.updateBar();
    let shown = -1;
    const tick = () => {
      if (!this.playing) return;
      if (this.version !== version || this.poses.sending) { this.stop(); return; }   // edited: stop
      let k = k0 + Math.floor((performance.now() - wall0) * fps / 1000);
      if (k >= n) {
        if (this.loop && n > 1) k %= n;
        else { k = n - 1; this.playing = false; }
      }
      if (cache.has(k) && k !== shown) {
        this.time = grid.at(k);
        this.draw(cache.get(k));
        shown = k;
        this.updateBar();
        if (cache.size > 4 * batch) {       // keep what is ahead, drop what was shown
          for (const kk of cache.keys()) if ((kk - k + n) % n >= 2 * batch) cache.delete(kk);
        }
      }
      if (!asked && this.playing) {
        let ahead = 0;                      // keep a batch ahead of the frame shown
        while (ahead < batch && cache.has((k + ahead) % n)) ahead++;
        if (ahead < batch && ahead < n && (this.loop || k + ahead < n)) {
          fetchFrom((k + ahead) % n).catch((err) => { this.stop(); this.status(`timeline: ${err.message}`, true); });
        }
      }
      if (this.playing) this.raf = requestAnimationFrame(tick);
      else this.show(this.time).catch((err) => this.status(`timeline: ${err.message}`, true));
    };
    tick();
    return this.state();
  }

  stop() {
    this.playing = false;
    if (this.raf) cancelAnimationFrame(this.raf);
    this.raf = 0;
    this.updateBar();
  }

  /** Stop playing; the pose shown becomes the server's current pose. Resolves once drawn. */
  async pause() {
    const was = this.playing;
    this.stop();
    if (was && this.list.length) await this.show(this.time);
    return this.state();
  }

  state() {
    const end = this.list.length ? this.list[this.list.length - 1].time : 0;
    const start = this.list.length ? this.list[0].time : 0;
    return { time: this.time, playing: this.playing, keys: this.list.length, fps: this.fps,
             interpolation: this.interpolation, start, end, duration: end - start, loop: this.loop };
  }

  // ------------------------------------------------------------------ files
  /** Save the clip into the rig's folder (POST /api/save-clip of the clip the server
   * holds, at the page's fps); resolves to {path, name, keys}. */
  async saveClip(name = null, overwrite = false) {
    this.needKeys("save clip");
    const out = await this.withClip((id) => {
      const body = { id, fps: this.fps };
      if (name !== null && name !== undefined) body.name = name;
      if (overwrite) body.overwrite = true;
      return this.apiJSON("/api/save-clip", this.post(body));
    });
    this.status(`saved ${out.name} (${out.keys} keys)`);
    return out;
  }

  async loadFile(file) {
    let obj;
    try { obj = JSON.parse(await file.text()); } catch (err) {
      throw new Error(`${file.name}: not valid JSON (${err.message})`);
    }
    try { return await this.setClip(obj); } catch (err) {
      throw new Error(`${file.name}: ${err.message}`);
    }
  }

  /**
   * Draw every frame of the fps grid, scaled to at most `width` px wide, and send them
   * to POST /api/export, which writes an animated GIF into the rig's folder. With
   * `frame` (default) the camera frames the whole clip while drawing, then goes back.
   * Resolves to {path, name, frames, width, height, fps}.
   */
  async exportClip({ name = null, format = "gif", width = MAX_EXPORT_WIDTH, loop = this.loop,
                     overwrite = false, frame = true } = {}) {
    if (format !== "gif") throw new Error(`format must be "gif", got ${JSON.stringify(format)}`);
    this.needKeys("export");
    this.stop();
    await this.poses.idle();
    const grid = this.grid();
    if (grid.count > MAX_EXPORT_FRAMES) {
      throw new Error(`export: ${grid.count} frames; at most ${MAX_EXPORT_FRAMES} (lower the fps)`);
    }
    const poses = await this.frames(Array.from({ length: grid.count }, (_, k) => grid.at(k)));
    const src = this.view.renderer.domElement;
    const w = Math.max(1, Math.min(Math.round(width), src.width));
    const h = Math.max(1, Math.round(src.height * w / src.width));
    const out = document.createElement("canvas");
    out.width = w; out.height = h;
    const ctx = out.getContext("2d");
    const frames = [];
    const v = this.view, saved = v.saveCamera();
    try {
      if (frame) {                  // frame the whole clip: every frame's mesh and joints
        const points = [];
        for (const f of poses) {
          this.draw(f);
          points.push(v.skinned()[0].slice(), v.segments().slice());
        }
        v.frame(points);
      }
      for (const f of poses) {
        this.draw(f);
        ctx.drawImage(src, 0, 0, w, h);
        frames.push(out.toDataURL("image/png"));
      }
    } finally {
      if (frame) v.restoreCamera(saved);     // give the user's view back
      await this.poses.fetch();     // back to the server's current pose
    }
    const body = { frames, fps: this.fps, format, loop };
    if (name !== null && name !== undefined) body.name = name;
    if (overwrite) body.overwrite = true;
    const done = await this.apiJSON("/api/export", this.post(body));
    this.status(`exported ${done.name} (${done.frames} frames)`);
    return done;
  }

  // ------------------------------------------------------------------ the bar
  el(id) { return document.getElementById(id); }

  buildBar() {
    const bar = this.el("timeline");
    if (!bar) return;
    const report = (what) => (err) => this.status(`${what}: ${err.message}`, true);
    this.el("tl-add")?.addEventListener("click", () => this.addKey().catch(report("add key")));
    this.el("tl-delete")?.addEventListener("click", () => {
      this.deleteKey().then(() => (this.list.length ? this.show(this.time) : null)).catch(report("delete key"));
    });
    this.el("tl-play")?.addEventListener("click", () =>
      (this.playing ? this.pause() : this.play()).catch(report("play")));
    const slider = this.el("tl-time");
    slider?.addEventListener("input", () => this.scrub(Number(slider.value)));
    const fps = this.el("tl-fps");
    fps?.addEventListener("change", () => {
      Promise.resolve().then(() => this.setFps(Number(fps.value)))
        .catch((err) => { report("fps")(err); fps.value = String(this.fps); });
    });
    const interp = this.el("tl-interp");
    interp?.addEventListener("change", () => {
      Promise.resolve().then(() => this.setInterpolation(interp.value)).catch(report("interpolation"));
    });
    const loop = this.el("tl-loop");
    loop?.addEventListener("change", () => { this.loop = loop.checked; });
    const summary = this.store.rig.summary;
    const saving = !!(summary.save && summary.save.pose);
    for (const [id, what, act] of [["tl-save", "save clip", () => this.saveClip()],
                                   ["tl-export", "export GIF", () => this.exportClip()]]) {
      const b = this.el(id);
      if (!b) continue;
      b.disabled = !saving;
      if (!saving) b.title = `${what} is off: start stbs view with a rig file or --save-as`;
      b.addEventListener("click", () => act().catch(report(what)));
    }
    const input = this.el("tl-load");
    input?.addEventListener("change", () => {
      const file = input.files && input.files[0];
      if (file) this.loadFile(file).catch(report("load clip")).finally(() => { input.value = ""; });
    });
    this.updateBar();
  }

  /** Slider drags: the latest time wins; one seek in flight at a time. */
  scrub(t) {
    this.time = t;
    if (!this.list.length) { this.updateBar(); return; }
    this.stop();
    this.scrubTo = t;
    if (this.scrubbing) return;
    this.scrubbing = (async () => {
      try {
        while (this.scrubTo !== null) {
          const s = this.scrubTo;
          this.scrubTo = null;
          await this.show(s);
        }
      } catch (err) {
        this.status(`timeline: ${err.message}`, true);
      } finally { this.scrubbing = null; this.scrubTo = null; }
    })();
  }

  /** The slider spans [lo, hi]: 0 (or the first key, if earlier) to the last key and one more second. */
  range() {
    const n = this.list.length;
    const lo = n ? Math.min(0, Math.floor(this.list[0].time)) : 0;
    const hi = Math.max(lo + 2, Math.ceil((n ? this.list[n - 1].time : 0) + 1));
    return [lo, hi];
  }

  updateBar() {
    const slider = this.el("tl-time");
    if (!slider) return;
    const [lo, hi] = this.range();
    slider.min = String(lo);
    slider.max = String(hi);
    slider.step = String(1 / Math.max(this.fps, 1));
    if (document.activeElement !== slider) slider.value = String(this.time);
    const label = this.el("tl-label");
    if (label) label.textContent = `${this.time.toFixed(2)} s`;
    const play = this.el("tl-play");
    if (play) {
      play.textContent = this.playing ? "pause" : "play";
      play.disabled = !this.list.length;
    }
    const del = this.el("tl-delete");
    if (del) del.disabled = !this.list.length;
    const fps = this.el("tl-fps");
    if (fps && document.activeElement !== fps) fps.value = String(this.fps);
    const interp = this.el("tl-interp");
    if (interp) interp.value = this.interpolation;
    const marks = this.el("tl-marks");
    if (marks) {
      marks.replaceChildren(...this.list.map((k) => {
        const m = document.createElement("span");
        m.className = "tl-mark";
        m.style.left = `${(100 * (k.time - lo)) / (hi - lo)}%`;
        m.title = `key at ${k.time.toFixed(2)} s`;
        return m;
      }));
    }
    const count = this.el("tl-count");
    if (count) count.textContent = `${this.list.length} key${this.list.length === 1 ? "" : "s"}`;
  }
}
