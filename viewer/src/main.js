// stbs view: the page. Loads the rig from the server's API, skins it in a vertex
// shader (skin.js: lbs, dqs, stbs-lbs, stbs-dqs), draws it lit with the skeleton
// over it, and exposes the scripting API window.stbsViewer (docs/viewer.md).

import * as THREE from "three";
import { OrbitControls } from "three/examples/jsm/controls/OrbitControls.js";
import { SkinFeedback } from "./feedback.js";
import { timeFrames } from "./timing.js";
import { LineSegments2 } from "three/examples/jsm/lines/LineSegments2.js";
import { LineSegmentsGeometry } from "three/examples/jsm/lines/LineSegmentsGeometry.js";
import { LineMaterial } from "three/examples/jsm/lines/LineMaterial.js";
import { hangSegments, packBones, posedSegments, PoseLink, restFrames } from "./pose.js";
import { Bones } from "./ik.js";
import { PoseEditor } from "./edit.js";
import { WeightEditor } from "./paint.js";
import { Compare } from "./compare.js";
import { Gizmo } from "./gizmo.js";
import { PoseFiles } from "./posefiles.js";
import { Timeline } from "./timeline.js";
import { MESH_FRAGMENT, MESH_VERTEX, TEXELS_PER_BONE, checkMethods } from "./skin.js";
import { api, apiJSON, loadArray, poseBones, seekClip, setWorldPose } from "./api.js";
import { Events } from "./events.js";
import { History } from "./history.js";
import { Store } from "./store.js";
import { Keys } from "./keys.js";

function toFloat32(a) {
  return a instanceof Float32Array ? a : Float32Array.from(a);
}

function pad3(V, dim) {   // (n, dim) -> (n, 3), z = 0 in 2D
  if (dim === 3) return toFloat32(V);
  const n = V.length / dim, out = new Float32Array(3 * n);
  for (let i = 0; i < n; i++) { out[3 * i] = V[2 * i]; out[3 * i + 1] = V[2 * i + 1]; }
  return out;
}

/** Area-weighted vertex normals of the rest surface (2D: +z). */
function restNormals(P, F, dim) {
  const n = P.length / 3, N = new Float64Array(3 * n);
  if (dim === 2 || !F || F.length === 0) {
    const out = new Float32Array(3 * n);
    for (let i = 0; i < n; i++) out[3 * i + 2] = 1;
    return out;
  }
  for (let f = 0; f < F.length; f += 3) {
    const i = F[f], j = F[f + 1], k = F[f + 2];
    const ux = P[3 * j] - P[3 * i], uy = P[3 * j + 1] - P[3 * i + 1], uz = P[3 * j + 2] - P[3 * i + 2];
    const vx = P[3 * k] - P[3 * i], vy = P[3 * k + 1] - P[3 * i + 1], vz = P[3 * k + 2] - P[3 * i + 2];
    const cx = uy * vz - uz * vy, cy = uz * vx - ux * vz, cz = ux * vy - uy * vx;
    for (const v of [i, j, k]) { N[3 * v] += cx; N[3 * v + 1] += cy; N[3 * v + 2] += cz; }
  }
  const out = new Float32Array(3 * n);
  for (let v = 0; v < n; v++) {
    const l = Math.hypot(N[3 * v], N[3 * v + 1], N[3 * v + 2]);
    if (l > 0) for (let c = 0; c < 3; c++) out[3 * v + c] = N[3 * v + c] / l;
    else out[3 * v + 2] = 1;
  }
  return out;
}

/** The status line; an error shows in full in a banner over the page (a click closes it). */
function status(text, isError = false) {
  const el = document.getElementById("status");
  if (!el) return;
  el.textContent = text;
  el.classList.toggle("error", isError);
  el.title = isError ? "click to close" : "";
  if (!el.dataset.closes) {
    el.dataset.closes = "1";
    el.addEventListener("click", () => el.classList.remove("error"));
  }
}

const SELECTED = 0xffa040;      // the selected bone's colour
const SELECTED_PX = 4;          // and its width, CSS pixels
const JOINT_RING_PX = 11;       // the ring round its start joint, radius in CSS pixels

class Viewer {
  constructor() {
    // the context every module gets (docs/viewer.md): the one store, events, history,
    // keyboard shortcuts and the drawing services (view), and the pose on the server
    this.events = new Events();
    this.store = new Store(this.events);
    this.history = new History(this.events);
    this.keys = new Keys(window);
    this.poses = new PoseLink(this.store, { apiJSON, poseBones, setWorldPose },
                              (err) => status(`stbs view: ${err.message}`, true));
    this.view = makeView(this);
    this.ctx = Object.freeze({ store: this.store, events: this.events, history: this.history,
                               keys: this.keys, view: this.view, poses: this.poses });
  }

  /** The pose object that gives the pose shown (the store's). */
  get lastSent() { return this.store.poseObject; }

  /** The pose's per-bone arrays as the store holds them. */
  get poseArrays() { return this.store.pose; }

  async load() {
    const info = await apiJSON("/api/rig");
    // the method names come from the server (typed once, in the library), in the shader's order
    this.methods = checkMethods(info.methods);
    this.summary = info;
    this.dim = info.dim;
    const want = ["V", "F", "C", "BE", "I4", "W4", "E4", "W", "E"];
    if (info.dim === 2 && info.arrays.UV && info.arrays.texture) want.push("UV", "texture");
    const arrays = {};
    await Promise.all(want.map(async (k) => {
      if (info.arrays[k]) arrays[k] = await loadArray(info.arrays[k]);
    }));
    this.arrays = arrays;
    this.n = info.vertices;
    this.b = info.bones;
    // the rest joints in float64 (the summary's) for the pose arithmetic; C.bin is float32
    const C64 = info.rest_joints ? Float64Array.from(info.rest_joints.flat()) : arrays.C;
    this.rest = restFrames(C64, arrays.BE, this.dim);
    // offset children (DESIGN §2): [child, parent, t_c], drawn as links to where they hang
    const parents = (info.parents || []).map(Number), hang = info.hang || [];
    const connected = info.connected || [];
    this.links = [];
    parents.forEach((p, i) => { if (p >= 0 && connected[i] === false) this.links.push([i, p, hang[i] ?? 0]); });
    this.store.setRig({ dim: this.dim, n: this.n, b: this.b, V: arrays.V, F: arrays.F || null,
                        C: arrays.C, BE: arrays.BE, restC: C64, rest: this.rest, parents,
                        connected: info.connected || null, hang: info.hang || null, links: this.links,
                        names: Array.from({ length: this.b }, (_, i) => (info.names && info.names[i] != null
                          ? String(info.names[i]) : String(i))),
                        summary: info });
    if (arrays.W && arrays.E) this.store.setWeights(toFloat32(arrays.W), toFloat32(arrays.E));
    this.boneData = new Float32Array(4 * TEXELS_PER_BONE * this.b);
    this.methodIndex = Math.max(0, this.methods.indexOf(info.method));
    this.buildScene();
    this.events.on("pose", ({ arrays: a }) => this.upload(a));
    this.events.on("select", () => { this.showSelected(); this.render(); });
    await this.poses.fetch(await this.poses.get());
    this.compile();
    this.buildUI();
    const ctx = this.ctx, bones = new Bones(this.store);
    this.compare = new Compare(ctx);
    this.gizmo = new Gizmo(ctx, bones);
    this.editor = new PoseEditor(ctx, { bones, gizmo: this.gizmo, painting: () => this.painting() });
    this.weights = new WeightEditor(ctx, api);
    this.poseFiles = new PoseFiles(ctx, apiJSON, status);
    this.timeline = new Timeline(ctx, api, status, seekClip);
    this.registerKeys();
    // the mode (Tab, store.mode) switches the painter on (bone weights, the brush as it
    // was) and off; the painter's own menu sets the mode the other way
    this.events.on("mode", ({ mode }) => {
      const painting = this.weights.paintSettings().mode !== "off";
      if (mode === "paint" && !painting) this.weights.setPaint({ mode: "bone" });
      if (mode === "pose" && painting) this.weights.setPaint({ mode: "off" });
    });
    this.store.select(0);
    if (info.clip) {        // started with a clip (stbs view RIG --motion FILE): on the timeline
      await this.timeline.open(await apiJSON("/api/clip"));
    }
    this.frame();
  }

  /** Whether painting has the pointer (the store's paint mode, or the weights panel's). */
  painting() {
    const w = this.weights;
    return this.store.mode === "paint" ||
      !!(w && w.settings && w.settings.mode && w.settings.mode !== "off");
  }

  buildScene() {
    const { arrays, dim } = this;
    const canvas = document.getElementById("view");
    const renderer = new THREE.WebGLRenderer({ canvas, antialias: true, preserveDrawingBuffer: true });
    renderer.setPixelRatio(window.devicePixelRatio || 1);
    const [cw, ch] = this.canvasSize();
    renderer.setSize(cw, ch, false);
    renderer.setClearColor(0x20232a, 1);
    this.renderer = renderer;
    this.gl = renderer.getContext();
    if (!(this.gl instanceof WebGL2RenderingContext)) throw new Error("WebGL2 is required");

    const position = pad3(arrays.V, dim);
    const normal = restNormals(position, arrays.F, dim);
    const index = toFloat32(arrays.I4), weight = toFloat32(arrays.W4), end = toFloat32(arrays.E4);
    this.restNormals = normal;
    const geom = new THREE.BufferGeometry();
    geom.setAttribute("position", new THREE.BufferAttribute(position, 3));
    geom.setAttribute("normal", new THREE.BufferAttribute(normal, 3));
    geom.setAttribute("stbsIndex", new THREE.BufferAttribute(index, 4));
    geom.setAttribute("stbsWeight", new THREE.BufferAttribute(weight, 4));
    geom.setAttribute("stbsEnd", new THREE.BufferAttribute(end, 4));
    if (arrays.F) geom.setIndex(new THREE.BufferAttribute(new Uint32Array(arrays.F), 1));
    geom.computeBoundingBox();
    this.bbox = geom.boundingBox.clone();
    for (let j = 0; j < arrays.C.length / dim; j++) {
      this.bbox.expandByPoint(new THREE.Vector3(arrays.C[dim * j], arrays.C[dim * j + 1],
                                                dim === 3 ? arrays.C[dim * j + 2] : 0));
    }

    this.boneTexture = new THREE.DataTexture(this.boneData, TEXELS_PER_BONE, this.b,
                                             THREE.RGBAFormat, THREE.FloatType);
    this.boneTexture.minFilter = this.boneTexture.magFilter = THREE.NearestFilter;
    this.boneTexture.generateMipmaps = false;
    this.boneTexture.flipY = false;
    this.boneTexture.needsUpdate = true;
    this.material = new THREE.ShaderMaterial({
      glslVersion: THREE.GLSL3,
      vertexShader: MESH_VERTEX,
      fragmentShader: MESH_FRAGMENT,
      side: THREE.DoubleSide,
      // 2D: no depth test, so parts that fold over each other overlap in the triangles'
      // order instead of fighting over one depth (z = 0 everywhere)
      depthTest: dim === 3,
      depthWrite: dim === 3,
      uniforms: {
        uBones: { value: this.boneTexture },
        uMethod: { value: this.methodIndex },
        uColor: { value: new THREE.Color(0.85, 0.66, 0.52) },
        uBoneTint: { value: dim === 2 ? 0.45 : 0.2 },
        uFlat: { value: dim === 2 ? 1 : 0 },
        uTextured: { value: 0 },
        uColorMode: { value: 0 },
        uPicture: { value: null },
      },
    });
    const picture = this.pictureTexture();
    if (picture) {
      geom.setAttribute("uv", new THREE.BufferAttribute(toFloat32(arrays.UV), 2));
      this.material.uniforms.uPicture.value = picture;
      this.material.uniforms.uTextured.value = 1;
    }
    this.mesh = new THREE.Mesh(geom, this.material);
    this.mesh.frustumCulled = false;     // skinned on the GPU: the rest bounds do not hold

    const scene = new THREE.Scene();
    scene.add(this.mesh);
    const segs = new Float32Array(6 * this.b);
    const lineGeom = new THREE.BufferGeometry();
    lineGeom.setAttribute("position", new THREE.BufferAttribute(segs, 3));
    this.skeletonLines = new THREE.LineSegments(lineGeom, new THREE.LineBasicMaterial(
      { color: 0x7fd4ff, depthTest: false, transparent: true }));
    this.skeletonLines.renderOrder = 1;
    this.skeletonLines.frustumCulled = false;
    this.joints = new THREE.Points(lineGeom, new THREE.PointsMaterial(
      { color: 0xffffff, size: 6, sizeAttenuation: false, depthTest: false, transparent: true }));
    this.joints.renderOrder = 2;
    this.joints.frustumCulled = false;
    scene.add(this.skeletonLines, this.joints);
    const linkGeom = new THREE.BufferGeometry();
    linkGeom.setAttribute("position", new THREE.BufferAttribute(new Float32Array(6 * Math.max(this.links.length, 1)), 3));
    linkGeom.setDrawRange(0, 2 * this.links.length);
    this.linkLines = new THREE.LineSegments(linkGeom, new THREE.LineBasicMaterial(
      { color: 0x7fd4ff, depthTest: false, transparent: true, opacity: 0.35 }));
    this.linkLines.renderOrder = 1;
    this.linkLines.frustumCulled = false;
    scene.add(this.linkLines);
    // the selected bone: drawn wider in its own colour, a ring round its start joint
    this.selectedLine = new LineSegments2(new LineSegmentsGeometry(), new LineMaterial(
      { color: SELECTED, linewidth: SELECTED_PX, depthTest: false, transparent: true }));
    this.selectedLine.renderOrder = 2;
    this.selectedLine.frustumCulled = false;
    this.selectedLine.visible = false;
    const ring = new Float32Array(3 * 48);
    for (let k = 0; k < 48; k++) { ring[3 * k] = Math.cos(k * Math.PI / 24); ring[3 * k + 1] = Math.sin(k * Math.PI / 24); }
    const ringGeom = new THREE.BufferGeometry();
    ringGeom.setAttribute("position", new THREE.BufferAttribute(ring, 3));
    this.jointRing = new THREE.LineLoop(ringGeom, new THREE.LineBasicMaterial(
      { color: SELECTED, depthTest: false, transparent: true }));
    this.jointRing.renderOrder = 2;
    this.jointRing.frustumCulled = false;
    this.jointRing.visible = false;
    scene.add(this.selectedLine, this.jointRing);
    this.scene = scene;

    const center = this.bbox.getCenter(new THREE.Vector3());
    const size = this.bbox.getSize(new THREE.Vector3());
    const diag = Math.max(size.length(), 1e-6);
    this.diag = diag;
    const aspect = cw / Math.max(ch, 1);
    if (dim === 2) {
      const h = 0.75 * diag;
      this.camera = new THREE.OrthographicCamera(-h * aspect, h * aspect, h, -h, -10 * diag, 10 * diag);
      this.camera.position.set(center.x, center.y, diag);
    } else {
      this.camera = new THREE.PerspectiveCamera(40, aspect, diag * 1e-3, diag * 100);
      this.camera.position.copy(center).add(new THREE.Vector3(0.35, 0.25, 1).normalize()
                                            .multiplyScalar(1.6 * diag));
    }
    this.camera.lookAt(center);
    const controls = new OrbitControls(this.camera, canvas);
    controls.target.copy(center);
    // wheel: zoom; right-drag: pan; left-drag on nothing, middle-drag or Alt+drag: orbit
    // (painting and joint drags take a plain left drag, never Alt or the middle button)
    controls.mouseButtons = { LEFT: THREE.MOUSE.ROTATE, MIDDLE: THREE.MOUSE.ROTATE, RIGHT: THREE.MOUSE.PAN };
    if (dim === 2) {
      controls.enableRotate = false;
      controls.screenSpacePanning = true;
      controls.mouseButtons = { LEFT: THREE.MOUSE.PAN, MIDDLE: THREE.MOUSE.PAN, RIGHT: THREE.MOUSE.PAN };
    }
    controls.update();
    controls.addEventListener("change", () => this.render());
    this.controls = controls;
    window.addEventListener("resize", () => this.resize());
    if (typeof ResizeObserver !== "undefined") new ResizeObserver(() => this.resize()).observe(canvas);

    this.feedback = new SkinFeedback(this.gl, { position, normal, index, weight, end }, this.b);
    renderer.resetState();
  }

  /** The canvas's size on the page (the area the panels leave), CSS pixels. */
  canvasSize() {
    const c = document.getElementById("view");
    const r = c.getBoundingClientRect();
    return [Math.max(1, Math.round(r.width)), Math.max(1, Math.round(r.height))];
  }

  /** The 2D picture's texture (arrays UV and texture, row 0 at the top), or null. */
  pictureTexture() {
    const { UV, texture } = this.arrays;
    const shape = this.summary.arrays.texture && this.summary.arrays.texture.shape;
    if (!UV || !texture || !shape || shape.length !== 3 || shape[2] !== 4) return null;
    const [h, w] = shape, flipped = new Uint8Array(texture.length), row = 4 * w;
    for (let y = 0; y < h; y++) flipped.set(texture.subarray(y * row, (y + 1) * row), (h - 1 - y) * row);
    const tex = new THREE.DataTexture(flipped, w, h, THREE.RGBAFormat, THREE.UnsignedByteType);
    tex.minFilter = THREE.LinearFilter;
    tex.magFilter = THREE.LinearFilter;
    tex.generateMipmaps = false;
    tex.needsUpdate = true;
    return tex;
  }

  resize() {
    if (!this.renderer) return;
    const [w, h] = this.canvasSize();
    const size = this.renderer.getSize(new THREE.Vector2());
    if (size.x !== w || size.y !== h) this.renderer.setSize(w, h, false);
    const view = this.viewRect(), aspect = Math.max(view.width, 1) / Math.max(view.height, 1);
    if (this.camera.isOrthographicCamera) {
      const half = 0.5 * (this.camera.top - this.camera.bottom);
      this.camera.left = -half * aspect; this.camera.right = half * aspect;
    } else {
      this.camera.aspect = aspect;
    }
    this.camera.updateProjectionMatrix();
    this.render();
  }

  /** Check that three's program for the mesh compiled and linked; throw if not. */
  compile() {
    this.renderer.compile(this.scene, this.camera);
    this.render();
    const props = this.renderer.properties.get(this.material);
    const program = props.currentProgram;
    const gl = this.gl;
    const ok = !!program && !program.diagnostics &&
               gl.getProgramParameter(program.program, gl.LINK_STATUS);
    this.shaders = { mesh: !!ok, feedback: !!this.feedback.linked };
    if (!ok) {
      const d = program && program.diagnostics;
      throw new Error(`the skinning shader did not compile: ${d ? (d.vertexShader.log ||
        d.fragmentShader.log || d.programLog) : "no program"}`);
    }
  }

  /** A pose's per-bone arrays (the store's "pose" event) into the bone texture and the
   * skeleton's lines; drawn. */
  upload(arrays) {
    packBones(this.rest, arrays, this.dim, this.boneData);
    this.boneTexture.needsUpdate = true;
    const segs = this.skeletonLines.geometry.attributes.position;
    posedSegments(this.rest, arrays, this.dim, segs.array);
    segs.needsUpdate = true;
    if (this.links.length) {
      const links = this.linkLines.geometry.attributes.position;
      hangSegments(this.links, segs.array, links.array);
      links.needsUpdate = true;
    }
    this.showSelected();
    this.render();
  }

  /** The selected bone's wide line and joint ring where the pose has it. */
  showSelected() {
    const i = this.store.selection.bone;
    const on = i !== null && !!this.skeletonLines;
    if (this.selectedLine) { this.selectedLine.visible = on; this.jointRing.visible = on; }
    if (!on) return;
    const s = this.skeletonLines.geometry.attributes.position.array;
    this.selectedLine.geometry.setPositions(Array.from(s.subarray(6 * i, 6 * i + 6)));
    this.jointRing.position.set(s[6 * i], s[6 * i + 1], s[6 * i + 2]);
  }

  /** World units per CSS pixel at point p (the left viewport). */
  perPixel(p) {
    const cam = this.camera, h = Math.max(this.viewRect().height, 1);
    if (cam.isOrthographicCamera) return (cam.top - cam.bottom) / cam.zoom / h;
    return 2 * p.distanceTo(cam.position) * Math.tan(THREE.MathUtils.degToRad(0.5 * cam.fov)) / h;
  }

  render() {
    if (!this.renderer) return;
    if (this.gizmo) this.gizmo.update();
    if (this.jointRing && this.jointRing.visible) {
      this.jointRing.quaternion.copy(this.camera.quaternion);
      this.jointRing.scale.setScalar(JOINT_RING_PX * this.perPixel(this.jointRing.position));
      const rect = this.viewRect();
      this.selectedLine.material.resolution.set(rect.width, rect.height);
    }
    if (this.compare && this.compare.active) this.compare.render();
    else this.renderer.render(this.scene, this.camera);
  }

  /** The (left, with side by side) viewport on the page, CSS pixels {left, top, width, height}. */
  viewRect() {
    if (this.compare) return this.compare.rect(0);
    const r = this.renderer.domElement.getBoundingClientRect();
    return { left: r.left, top: r.top, width: r.width, height: r.height };
  }

  /** The viewport under a page point. */
  viewRectAt(x, y) {
    return this.compare ? this.compare.rectAt(x, y) : this.viewRect();
  }

  /** The page's own shortcuts (keys.js): undo and redo, play, frame, mode, mirror. */
  registerKeys() {
    const k = this.keys, report = (what) => (err) => status(`${what}: ${err.message}`, true);
    k.register({ key: "Ctrl+Z", label: "undo", run: () => this.history.undo().catch(report("undo")) });
    k.register({ key: "Ctrl+Shift+Z", label: "redo", run: () => this.history.redo().catch(report("redo")) });
    k.register({ key: "Space", label: "play or pause the clip", when: () => this.timeline.state().keys > 0,
                 run: () => (this.timeline.playing ? this.timeline.pause() : this.timeline.play()).catch(report("play")) });
    k.register({ key: "F", label: "frame the view on the character", run: () => this.frame() });
    k.register({ key: "Tab", label: "switch between posing and painting",
                 run: () => this.store.setMode(this.store.mode === "pose" ? "paint" : "pose") });
    k.register({ key: "X", label: "mirror edits across the middle (X) on or off",
                 run: () => this.store.setMirror(!this.store.mirror) });
  }

  buildUI() {
    const sel = document.getElementById("method");
    if (!sel) return;
    for (const m of this.methods) {
      const o = document.createElement("option");
      o.value = o.textContent = m;
      sel.appendChild(o);
    }
    sel.value = this.methods[this.methodIndex];
    sel.addEventListener("change", () => this.setMethod(sel.value));
    const mirror = document.getElementById("mirror");
    if (mirror) {
      mirror.addEventListener("change", () => this.store.setMirror(mirror.checked));
      this.events.on("mirror", ({ on }) => { mirror.checked = on; });
    }
    document.getElementById("help-button")?.addEventListener("click", () => this.keys.toggleHelp());
    const s = this.summary;
    status(`${s.name}: ${s.vertices} vertices, ${s.bones} bones, ${s.dim}D`);
  }

  info() {
    return { vertices: this.n, bones: this.b, dim: this.dim, methods: this.methods.slice(),
             method: this.methods[this.methodIndex], names: this.summary.names,
             shaders: Object.assign({}, this.shaders) };
  }

  setMethod(name) {
    const i = this.methods.indexOf(name);
    if (i < 0) throw new Error(`method must be one of ${this.methods.join(", ")}, got ${JSON.stringify(name)}`);
    this.methodIndex = i;
    this.material.uniforms.uMethod.value = i;
    const sel = document.getElementById("method");
    if (sel) sel.value = name;
    this.render();
    return this.methods[i];
  }

  /** The scripting API's setPose: after any edit in flight, then frame the posed mesh. */
  async setPose(pose) {
    await this.settled();
    const back = await this.poses.post(pose);
    this.frame();
    return back;
  }

  /** Resolves once no edit, undo or redo is in flight. */
  async settled() {
    do {
      await this.history.idle();
      await this.poses.idle();
    } while (this.poses.sending || this.poses.preparing);
  }

  /** Posed joint positions (j x 3; rest position for a joint of no bone). */
  posedJoints() {
    const { C, BE } = this.arrays, dim = this.dim, j = C.length / dim;
    const segs = this.skeletonLines.geometry.attributes.position.array;
    const out = new Float64Array(3 * j), seen = new Uint8Array(j);
    for (let i = 0; i < this.b; i++) {
      for (const end of [1, 0]) {
        const k = BE[2 * i + end];
        if (seen[k]) continue;
        seen[k] = 1;
        for (let c = 0; c < 3; c++) out[3 * k + c] = segs[6 * i + 3 * end + c];
      }
    }
    for (let k = 0; k < j; k++) {
      if (!seen[k]) for (let c = 0; c < dim; c++) out[3 * k + c] = C[dim * k + c];
    }
    return out;
  }

  /** The posed bones' segments, b x 6 (start, end; 3D). */
  segments() { return this.skeletonLines.geometry.attributes.position.array; }

  /** A world point's position on the page, CSS pixels [x, y]. */
  toScreen(x, y, z, rect = this.viewRect()) {
    const v = new THREE.Vector3(x, y, z).project(this.camera);
    return [rect.left + 0.5 * (v.x + 1) * rect.width, rect.top + 0.5 * (1 - v.y) * rect.height];
  }

  jointScreenPositions() {
    const J = this.posedJoints(), out = [];
    for (let k = 0; k < J.length / 3; k++) out.push(this.toScreen(J[3 * k], J[3 * k + 1], J[3 * k + 2]));
    return out;
  }

  cameraInfo() {
    const cam = this.camera, rect = this.viewRect();
    cam.updateMatrixWorld();
    return { view: Array.from(cam.matrixWorldInverse.elements),
             projection: Array.from(cam.projectionMatrix.elements),
             width: rect.width, height: rect.height, left: rect.left, top: rect.top,
             orthographic: !!cam.isOrthographicCamera };
  }

  /** Frame the posed mesh (its skinned positions and the posed joints) in the view. */
  frame(more = []) {    // more: further point arrays (x, y, z, ...) to keep in view
    this.resize();
    const U = this.skinned()[0], J = this.posedJoints();
    const box = new THREE.Box3(), p = new THREE.Vector3();
    for (const A of [U, J, ...more]) for (let i = 0; i < A.length; i += 3) box.expandByPoint(p.set(A[i], A[i + 1], A[i + 2]));
    const center = box.getCenter(new THREE.Vector3());
    const size = box.getSize(new THREE.Vector3());
    const r = Math.max(0.5 * size.length(), 1e-6);
    const rect = this.viewRect();
    const aspect = Math.max(rect.width, 1) / Math.max(rect.height, 1);
    const cam = this.camera;
    if (cam.isOrthographicCamera) {
      const half = 1.08 * Math.max(0.5 * size.y, 0.5 * size.x / aspect, 1e-6);
      cam.zoom = 1;
      cam.top = half; cam.bottom = -half; cam.left = -half * aspect; cam.right = half * aspect;
      cam.position.set(center.x, center.y, cam.position.z);
      cam.near = -10 * r - Math.abs(cam.position.z); cam.far = 10 * r + Math.abs(cam.position.z);
    } else {
      const dir = cam.position.clone().sub(this.controls.target);
      if (dir.lengthSq() === 0) dir.set(0, 0, 1);
      dir.normalize();
      const halfV = THREE.MathUtils.degToRad(0.5 * cam.fov);
      const halfH = Math.atan(Math.tan(halfV) * aspect);
      const dist = 1.05 * r / Math.sin(Math.min(halfV, halfH));
      cam.position.copy(center).addScaledVector(dir, dist);
      cam.near = Math.max(dist - 2 * r, dist * 1e-3);
      cam.far = dist + 4 * r;
    }
    cam.updateProjectionMatrix();
    this.controls.target.copy(center);
    this.controls.update();
    this.render();
  }

  async getPose() {
    return this.poses.get();
  }

  skinned() {
    const out = this.feedback.run(this.boneData, this.methodIndex);
    this.renderer.resetState();
    return out;
  }

  timeFrames(count = 60) {
    return timeFrames(this.gl, count, () => {
      packBones(this.rest, this.poseArrays, this.dim, this.boneData);
      this.boneTexture.needsUpdate = true;
      this.render();
    });
  }
}

/** The drawing services modules get as ctx.view (the Viewer's, read live). */
function makeView(v) {
  const view = {};
  for (const k of ["renderer", "scene", "camera", "controls", "mesh", "material", "feedback",
                   "diag", "boneData", "methodIndex", "methods"]) {
    Object.defineProperty(view, k, { get: () => v[k], enumerable: true });
  }
  for (const f of ["render", "viewRect", "viewRectAt", "skinned", "toScreen", "posedJoints",
                   "segments", "frame", "resize", "perPixel"]) {
    view[f] = (...args) => v[f](...args);
  }
  /** Turn the camera's orbit, pan and zoom off (during a drag) or back on. */
  view.setOrbit = (on) => { v.controls.enabled = !!on; };
  /** Set a uniform of the mesh's material (uMethod, uColorMode, ...). */
  view.setUniform = (name, value) => {
    if (!(name in v.material.uniforms)) throw new Error(`view.setUniform: no uniform ${JSON.stringify(name)}`);
    v.material.uniforms[name].value = value;
  };
  /** Put the camera and the orbit target back as saved by saveCamera(). */
  view.saveCamera = () => ({ camera: v.camera.clone(), target: v.controls.target.clone() });
  view.restoreCamera = (saved) => {       // exactly as saved (no re-derivation by the controls)
    v.camera.copy(saved.camera);
    v.camera.updateProjectionMatrix();
    v.controls.target.copy(saved.target);
    v.render();
  };
  return Object.freeze(view);
}

document.getElementById("fallback")?.remove();
const viewer = new Viewer();
const ready = viewer.load().then(() => {
  document.body.dataset.ready = "true";
  return viewer.info();
}, (err) => {
  status(`stbs view: ${err.message}`, true);
  console.error(`stbs view: ${err.message}`);
  throw err;
});

const whenReady = (f) => (...args) => ready.then(() => f(...args));
const plain = (a) => Array.from(a);

window.stbsViewer = Object.freeze({
  ready,
  info: () => viewer.info(),
  setMethod: whenReady((name) => viewer.setMethod(name)),
  setPose: whenReady((pose) => viewer.setPose(pose)),
  getPose: whenReady(() => viewer.getPose()),
  skinnedPositions: whenReady(() => viewer.skinned()[0]),
  skinnedNormals: whenReady(() => viewer.skinned()[1]),
  restNormals: whenReady(() => viewer.restNormals.slice()),
  timeFrames: whenReady((count) => viewer.timeFrames(count)),
  frame: whenReady(() => { viewer.frame(); return viewer.cameraInfo(); }),
  camera: whenReady(() => viewer.cameraInfo()),
  posedJoints: whenReady(() => {
    const J = viewer.posedJoints(), out = [];
    for (let k = 0; k < J.length; k += 3) out.push(plain(J.subarray(k, k + viewer.dim)));
    return out;
  }),
  jointScreenPositions: whenReady(() => viewer.jointScreenPositions()),
  idle: whenReady(() => viewer.settled().then(() => undefined)),
  undo: whenReady(() => viewer.editor.undo()),
  redo: whenReady(() => viewer.editor.redo()),
  canUndo: () => viewer.history.canUndo,
  canRedo: () => viewer.history.canRedo,
  history: () => ({ undo: viewer.history.undos.map((c) => c.name), redo: viewer.history.redos.map((c) => c.name) }),
  store: () => ({ selection: Object.assign({}, viewer.store.selection), mode: viewer.store.mode,
                  mirror: viewer.store.mirror }),
  shortcuts: () => viewer.keys.shortcuts(),
  selectBone: whenReady((bone) => viewer.editor.select(bone)),
  setMirror: whenReady((on) => viewer.store.setMirror(on)),
  setMode: whenReady((mode) => viewer.store.setMode(mode)),
  // posing tools: drag modes, the rotation gizmo, side by side, pose files
  setDragMode: whenReady((mode) => viewer.editor.setDragMode(mode)),
  dragMode: () => (viewer.editor ? viewer.editor.mode : "stretch"),
  setGizmo: whenReady((bone) => viewer.gizmo.set(bone)),
  turnBone: whenReady((bone, axis, degrees) => viewer.editor.turnBone(bone, axis, degrees)),
  gizmo: whenReady(() => viewer.gizmo.info()),
  setCompare: whenReady((name) => viewer.compare.set(name)),
  compare: () => (viewer.compare ? viewer.compare.method() : null),
  savePose: whenReady((name, overwrite) => viewer.poseFiles.save(name ?? null, !!overwrite)),
  poseText: whenReady(() => viewer.poseFiles.text()),
  loadPoseText: whenReady((text) => viewer.poseFiles.loadText(text)),
  // weights: colour modes, painting, endpoint recompute, the endpoint curve
  setColorMode: whenReady((name) => viewer.weights.setColorMode(name)),
  colorMode: () => (viewer.weights ? viewer.weights.colorMode() : "shaded"),
  setPaint: whenReady((opts) => viewer.weights.setPaint(opts)),
  paint: whenReady(() => viewer.weights.paintSettings()),
  lastStroke: whenReady(() => viewer.weights.lastStroke),
  paintUndo: whenReady(() => viewer.weights.undo()),
  paintRedo: whenReady(() => viewer.weights.redo()),
  canPaintUndo: () => !!viewer.weights && viewer.weights.undoStack.length > 0,
  canPaintRedo: () => !!viewer.weights && viewer.weights.redoStack.length > 0,
  weights: whenReady(() => viewer.weights.weights()),
  saveRig: whenReady(() => viewer.weights.saveRig()),
  recomputeEndpoint: whenReady((bone, method, options) => viewer.weights.recompute(bone, method, options)),
  setSpline: whenReady((bone, points) => viewer.weights.setSpline(bone, points)),
  spline: whenReady((bone) => viewer.weights.splinePointsOf(viewer.weights.boneIndex(bone))),
  splineValues: whenReady((bone, xs) => viewer.weights.splineValues(bone, xs)),
  applySpline: whenReady((bone) => viewer.weights.applySpline(bone)),
  // clips (timeline.js): keys, seek, playback, clip files, GIF export
  addKey: whenReady((time, pose) => viewer.timeline.addKey(time ?? viewer.timeline.time, pose ?? null)),
  deleteKey: whenReady((time) => viewer.timeline.deleteKey(time ?? null)),
  keys: () => (viewer.timeline ? viewer.timeline.keys() : []),
  clearKeys: whenReady(() => viewer.timeline.clearKeys()),
  setClip: whenReady((clip) => viewer.timeline.setClip(clip)),
  getClip: whenReady(() => viewer.timeline.fullClip()),
  setFps: whenReady((fps) => viewer.timeline.setFps(fps)),
  setInterpolation: whenReady((name) => viewer.timeline.setInterpolation(name)),
  seek: whenReady((t) => viewer.timeline.seek(t)),
  play: whenReady(() => viewer.timeline.play()),
  pause: whenReady(() => viewer.timeline.pause()),
  clipState: () => (viewer.timeline ? viewer.timeline.state() : null),
  saveClip: whenReady((name, overwrite) => viewer.timeline.saveClip(name ?? null, !!overwrite)),
  exportClip: whenReady((opts) => viewer.timeline.exportClip(opts || {})),
});
