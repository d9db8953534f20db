// The timeline: keyed poses (a clip, docs/clips.md), a scrubber, playback at the
// clip's fps, saving and loading clip files, and export to an animated GIF.
//
// The page never interpolates poses itself: the server reads the clip with
// stbs.io.read_clip and answers Clip.pose as per-bone arrays (POST /api/clip/sample
// for playback, one request per clip change; POST /api/clip/pose for a seek, which
// also makes that pose the server's current pose, so edits start from it).

import { packBones, posedSegments } from "./pose.js";

const DEFAULT_FPS = 30;
const INTERPOLATIONS = ["linear", "step"];
const MAX_EXPORT_WIDTH = 480;    // px: GIF frames are scaled down to at most this width
const MAX_EXPORT_FRAMES = 600;   // what POST /api/export takes

function copy(x) { return JSON.parse(JSON.stringify(x)); }

function finite(name, x) {
  if (typeof x !== "number" || !Number.isFinite(x)) {
    throw new Error(`${name} must be a finite number of seconds, got ${JSON.stringify(x)}`);
  }
  return x;
}

export class Timeline {
  /** apiJSON(path, options) and status(text, isError) are the page's own. */
  constructor(viewer, apiJSON, status) {
    this.v = viewer;
    this.apiJSON = apiJSON;
    this.status = status;
    this.fps = DEFAULT_FPS;
    this.interpolation = "linear";
    this.list = [];              // [{time, pose}] sorted by time; pose: a pose-file object
    this.time = 0;
    this.loop = true;
    this.version = 0;            // bumped on every clip change
    this.cache = null;           // {version, reply} of POST /api/clip/sample
    this.playing = false;
    this.raf = 0;
    this.buildBar();
  }

  // ------------------------------------------------------------------ the clip
  /** The clip file object of the keys, or null when there are none. */
  clip() {
    if (!this.list.length) return null;
    return { fps: this.fps, interpolation: this.interpolation, keys: copy(this.list) };
  }

  keys() { return copy(this.list); }

  changed() {
    this.version += 1;
    this.cache = null;
    this.updateBar();
  }

  /** Add (or replace) the key at `time` with `pose` (default: the current pose, GET /api/pose). */
  async addKey(time = this.time, pose = null) {
    finite("time", time);
    await this.v.idle();
    if (pose === null || pose === undefined) pose = await this.apiJSON("/api/pose");
    if (typeof pose !== "object" || Array.isArray(pose)) {
      throw new Error(`pose must be a pose object (either form of a pose file), got ${JSON.stringify(pose)}`);
    }
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

  clearKeys() {
    this.stop();
    this.list = [];
    this.time = 0;
    this.changed();
    return [];
  }

  /** Replace the clip by a clip file object (checked by the server); resolves to getClip(). */
  async setClip(obj) {
    if (!obj || typeof obj !== "object" || Array.isArray(obj)) {
      throw new Error(`clip must be a clip object {fps, interpolation, keys}, got ${JSON.stringify(obj)}`);
    }
    if ("times" in obj) throw new Error('clip: unexpected key "times"; a clip has fps, interpolation, keys');
    const reply = await this.apiJSON("/api/clip/sample", this.post(obj));   // the server's read_clip
    this.stop();
    this.fps = reply.fps;
    this.interpolation = reply.interpolation;
    this.list = obj.keys.map((k) => ({ time: Number(k.time), pose: copy(k.pose) }))
      .sort((a, b) => a.time - b.time);
    this.changed();
    this.cache = { version: this.version, reply };
    this.time = reply.start;
    await this.show(this.time);
    return this.clip();
  }

  setFps(fps) {
    if (typeof fps !== "number" || !Number.isFinite(fps) || fps <= 0) {
      throw new Error(`fps must be a number > 0, got ${JSON.stringify(fps)}`);
    }
    this.fps = fps;
    this.changed();
    return fps;
  }

  setInterpolation(name) {
    if (!INTERPOLATIONS.includes(name)) {
      throw new Error(`interpolation must be one of ${INTERPOLATIONS.join(", ")}, got ${JSON.stringify(name)}`);
    }
    this.interpolation = name;
    this.changed();
    return name;
  }

  post(body) {
    return { method: "POST", headers: { "Content-Type": "application/json" }, body: JSON.stringify(body) };
  }

  needKeys(what) {
    if (!this.list.length) throw new Error(`${what}: the clip has no keys (add a key first)`);
  }

  /** The clip sampled at its fps (cached until the clip changes). */
  async sample() {
    this.needKeys("sample");
    if (!this.cache || this.cache.version !== this.version) {
      const version = this.version;
      const reply = await this.apiJSON("/api/clip/sample", this.post(this.clip()));
      if (version === this.version) this.cache = { version, reply };
      return reply;
    }
    return this.cache.reply;
  }

  // ------------------------------------------------------------------ showing a time
  /** Upload one frame's bone arrays (as fetchPose does) and draw. */
  draw(frame) {
    const v = this.v;
    v.poseArrays = frame;
    packBones(v.rest, frame, v.dim, v.boneData);
    v.boneTexture.needsUpdate = true;
    const segs = v.skeletonLines.geometry.attributes.position;
    posedSegments(v.rest, frame, v.dim, segs.array);
    segs.needsUpdate = true;
    v.render();
  }

  /**
   * Show the clip's pose at t exactly and make it the server's current pose. Shows run
   * one after another in the order asked for, so the last one asked for is what stays.
   */
  show(t) {
    const clip = this.clip();
    const run = async () => {
      const reply = await this.apiJSON("/api/clip/pose", this.post({ clip, time: t }));
      this.v.lastSent = copy(reply.pose);
      await this.v.fetchPose();
      this.v.render();
      this.time = t;
      this.updateBar();
      return reply;
    };
    const mine = (this.showing || Promise.resolve()).catch(() => {}).then(run);
    this.showing = mine;
    mine.finally(() => { if (this.showing === mine) this.showing = null; }).catch(() => {});
    return mine;
  }

  /** Stop playing and show the clip at t (seconds); resolves to {time, exact} once drawn. */
  async seek(t) {
    finite("t", t);
    this.needKeys("seek");
    this.stop();
    await this.v.idle();
    const reply = await this.show(t);
    return { time: t, exact: reply.exact };
  }

  /** Play from the current time (from the start when at or past the end); resolves once playing. */
  async play() {
    this.needKeys("play");
    if (this.playing) return this.state();
    await this.v.idle();
    const reply = await this.sample();
    const n = reply.times.length;
    let k0 = Math.round((this.time - reply.start) * reply.fps);
    if (!(k0 >= 0 && k0 < n - 1)) k0 = 0;
    const wall0 = performance.now();
    this.playing = true;
    this.updateBar();
    const version = this.version;
    const tick = () => {
      if (!this.playing) return;
      if (this.version !== version || this.v.sending) { this.stop(); return; }   // edited: stop
      let k = k0 + Math.floor((performance.now() - wall0) * reply.fps / 1000);
      if (k >= n) {
        if (this.loop && n > 1) k %= n;
        else { k = n - 1; this.playing = false; }
      }
      this.time = reply.times[k];
      this.draw(reply.frames[k]);
      this.updateBar();
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
  /** Save the clip into the rig's folder (POST /api/save-clip); resolves to {path, name, keys}. */
  async saveClip(name = null, overwrite = false) {
    this.needKeys("save clip");
    const body = { clip: this.clip() };
    if (name !== null && name !== undefined) body.name = name;
    if (overwrite) body.overwrite = true;
    const out = await this.apiJSON("/api/save-clip", this.post(body));
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
   * Draw every sampled frame, scaled to at most `width` px wide, and send them to
   * POST /api/export, which writes an animated GIF into the rig's folder. With `frame`
   * (default) the camera frames the whole clip while drawing, then goes back.
   * Resolves to {path, name, frames, width, height, fps}.
   */
  async exportClip({ name = null, format = "gif", width = MAX_EXPORT_WIDTH, loop = this.loop,
                     overwrite = false, frame = true } = {}) {
    if (format !== "gif") throw new Error(`format must be "gif", got ${JSON.stringify(format)}`);
    this.needKeys("export");
    this.stop();
    await this.v.idle();
    const reply = await this.sample();
    if (reply.frames.length > MAX_EXPORT_FRAMES) {
      throw new Error(`export: ${reply.frames.length} frames; at most ${MAX_EXPORT_FRAMES} (lower the fps)`);
    }
    const src = this.v.renderer.domElement;
    const w = Math.max(1, Math.min(Math.round(width), src.width));
    const h = Math.max(1, Math.round(src.height * w / src.width));
    const out = document.createElement("canvas");
    out.width = w; out.height = h;
    const ctx = out.getContext("2d");
    const frames = [];
    const v = this.v, saved = v.camera.clone(), target = v.controls.target.clone();
    try {
      if (frame) {                  // frame the whole clip: every frame's mesh and joints
        const points = [];
        for (const f of reply.frames) {
          this.draw(f);
          points.push(v.skinned()[0].slice(), v.skeletonLines.geometry.attributes.position.array.slice());
        }
        v.frame(points);
      }
      for (const f of reply.frames) {
        this.draw(f);
        ctx.drawImage(src, 0, 0, w, h);
        frames.push(out.toDataURL("image/png"));
      }
    } finally {
      if (frame) {                  // give the user's view back
        v.camera.copy(saved);
        v.camera.updateProjectionMatrix();
        v.controls.target.copy(target);
        v.controls.update();
      }
      await v.fetchPose();          // back to the server's current pose
      v.render();
    }
    const body = { frames, fps: reply.fps, format, loop };
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
      try { this.deleteKey(); if (this.list.length) this.show(this.time).catch(report("delete key")); }
      catch (err) { report("delete key")(err); }
    });
    this.el("tl-play")?.addEventListener("click", () =>
      (this.playing ? this.pause() : this.play()).catch(report("play")));
    const slider = this.el("tl-time");
    slider?.addEventListener("input", () => this.scrub(Number(slider.value)));
    const fps = this.el("tl-fps");
    fps?.addEventListener("change", () => {
      try { this.setFps(Number(fps.value)); } catch (err) { report("fps")(err); fps.value = String(this.fps); }
    });
    const interp = this.el("tl-interp");
    interp?.addEventListener("change", () => {
      try { this.setInterpolation(interp.value); } catch (err) { report("interpolation")(err); }
    });
    const loop = this.el("tl-loop");
    loop?.addEventListener("change", () => { this.loop = loop.checked; });
    const saving = !!(this.v.summary.save && this.v.summary.save.pose);
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
