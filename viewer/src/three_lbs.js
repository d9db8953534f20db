// The peer page of `stbs bench --viewer` (static/three-lbs.html): the rig that the
// viewer serves, drawn by three.js's own SkinnedMesh (plain linear blend skinning in
// three's shader) with the same top-4 bone indices and weights, so that the viewer's
// frame time has a yardstick. Exposes window.stbsThreeLbs (see the bottom).
//
// Bones are posed with the current pose's rotations R_i and posed starts a'_i only:
// bone i's skinning matrix is x -> a'_i + R_i (x - a_i), which is the viewer's lbs with
// stretch 1. Stretch and twist cannot be expressed by a three.js bone, so a pose's
// stretch and twists are ignored here (the a'_i of a stretched chain are kept).

import * as THREE from "three";
import { timeFrames } from "./timing.js";

const TOKEN = new URLSearchParams(location.search).get("token") || "";
const DTYPES = { float32: Float32Array, uint16: Uint16Array, uint32: Uint32Array, int32: Int32Array };

async function api(path) {
  const r = await fetch(path, { headers: { "X-Stbs-Token": TOKEN }, cache: "no-store" });
  if (!r.ok) {
    let msg = `${r.status}`;
    try { msg = (await r.json()).error || msg; } catch (_) { /* not JSON */ }
    throw new Error(`${path}: ${msg}`);
  }
  return r;
}

async function loadArray(desc) {
  const Type = DTYPES[desc.dtype];
  if (!Type) throw new Error(`${desc.url}: unsupported dtype ${desc.dtype}`);
  return new Type(await (await api(desc.url)).arrayBuffer());
}

class ThreeLbs {
  async load() {
    const info = await (await api("/api/rig")).json();
    if (info.dim !== 3) throw new Error(`the three-lbs peer draws 3D rigs, this one is ${info.dim}D`);
    const arrays = {};
    await Promise.all(["V", "F", "C", "BE", "I4", "W4"].map(async (k) => {
      if (!info.arrays[k]) throw new Error(`the rig has no array ${k}`);
      arrays[k] = await loadArray(info.arrays[k]);
    }));
    this.n = info.vertices;
    this.b = info.bones;
    const canvas = document.getElementById("view");
    // the viewer page's renderer settings, so both draw the same way
    const renderer = new THREE.WebGLRenderer({ canvas, antialias: true, preserveDrawingBuffer: true });
    renderer.setPixelRatio(window.devicePixelRatio || 1);
    renderer.setSize(window.innerWidth, window.innerHeight, false);
    renderer.setClearColor(0x20232a, 1);
    this.renderer = renderer;
    this.gl = renderer.getContext();

    const geom = new THREE.BufferGeometry();
    geom.setAttribute("position", new THREE.BufferAttribute(arrays.V, 3));
    geom.setIndex(new THREE.BufferAttribute(arrays.F, 1));
    geom.computeVertexNormals();           // area-weighted, as the viewer's rest normals
    const I = arrays.I4 instanceof Uint16Array ? arrays.I4 : Uint16Array.from(arrays.I4);
    geom.setAttribute("skinIndex", new THREE.Uint16BufferAttribute(I, 4));
    geom.setAttribute("skinWeight", new THREE.BufferAttribute(arrays.W4, 4));

    // One bone per stbs bone, all children of the mesh (no hierarchy: each bone's
    // world matrix is set from the pose directly); its inverse bind matrix moves the
    // rest start a_i to the origin.
    const { C, BE } = arrays;
    this.restStart = new Float64Array(3 * this.b);
    const bones = [], inverses = [];
    for (let i = 0; i < this.b; i++) {
      const j = BE[2 * i];
      const a = [C[3 * j], C[3 * j + 1], C[3 * j + 2]];
      this.restStart.set(a, 3 * i);
      const bone = new THREE.Bone();
      bone.position.set(a[0], a[1], a[2]);
      bones.push(bone);
      inverses.push(new THREE.Matrix4().makeTranslation(-a[0], -a[1], -a[2]));
    }
    const material = new THREE.MeshPhongMaterial({ color: 0xd9a885, shininess: 48,
                                                   side: THREE.DoubleSide });
    const mesh = new THREE.SkinnedMesh(geom, material);
    for (const bone of bones) mesh.add(bone);
    mesh.bind(new THREE.Skeleton(bones, inverses), new THREE.Matrix4());
    mesh.frustumCulled = false;             // skinned on the GPU, as the viewer's mesh
    this.mesh = mesh;

    const scene = new THREE.Scene();
    scene.add(mesh);
    scene.add(new THREE.AmbientLight(0xffffff, 0.6));
    const light = new THREE.DirectionalLight(0xffffff, 2.0);
    light.position.set(0.35, 0.5, 1);
    scene.add(light);
    this.scene = scene;

    geom.computeBoundingBox();
    const box = geom.boundingBox, center = box.getCenter(new THREE.Vector3());
    const diag = Math.max(box.getSize(new THREE.Vector3()).length(), 1e-6);
    this.camera = new THREE.PerspectiveCamera(40, window.innerWidth / Math.max(window.innerHeight, 1),
                                              diag * 1e-3, diag * 100);
    this.camera.position.copy(center).add(new THREE.Vector3(0.35, 0.25, 1).normalize()
                                          .multiplyScalar(1.6 * diag));
    this.camera.lookAt(center);

    await this.fetchPose();
    renderer.compile(scene, this.camera);
    this.render();
    const program = renderer.properties.get(material).currentProgram;
    if (!program || program.diagnostics) throw new Error("three.js's skinning shader did not compile");
  }

  /** The server's current pose (rotations and posed starts; stretch and twist unused). */
  async fetchPose() {
    this.poseArrays = await (await api("/api/pose/bones")).json();
    this.applyPose();
  }

  /** Bone i's world matrix T(a'_i) R_i from the pose arrays: rotations and origins only. */
  applyPose() {
    const { rotations, origins } = this.poseArrays, m = new THREE.Matrix4();
    const bones = this.mesh.skeleton.bones;
    for (let i = 0; i < this.b; i++) {
      const R = rotations[i], o = origins[i];
      m.set(R[0][0], R[0][1], R[0][2], 0, R[1][0], R[1][1], R[1][2], 0,
            R[2][0], R[2][1], R[2][2], 0, 0, 0, 0, 1);
      bones[i].quaternion.setFromRotationMatrix(m);
      bones[i].position.set(o[0], o[1], o[2]);
    }
  }

  /** Use the viewer page's camera: {view, projection} column-major 4x4 (stbsViewer.camera()). */
  setCamera(cam) {
    const c = this.camera;
    new THREE.Matrix4().fromArray(cam.view).invert().decompose(c.position, c.quaternion, c.scale);
    c.projectionMatrix.fromArray(cam.projection);
    c.projectionMatrixInverse.copy(c.projectionMatrix).invert();
    c.updateMatrixWorld(true);
    this.render();
  }

  render() {
    this.renderer.render(this.scene, this.camera);
  }

  /** Skinned positions by three.js's own CPU path (SkinnedMesh.getVertexPosition), n x 3. */
  skinnedPositions() {
    this.scene.updateMatrixWorld(true);
    this.mesh.skeleton.update();
    const out = new Float32Array(3 * this.n), v = new THREE.Vector3();
    for (let i = 0; i < this.n; i++) {
      this.mesh.getVertexPosition(i, v);
      out[3 * i] = v.x; out[3 * i + 1] = v.y; out[3 * i + 2] = v.z;
    }
    return out;
  }

  /** The median ms of `count` frames: pose to bone matrices (three's bone texture
   *  upload), skinning and shading in three's shader, and a 1-pixel readPixels that
   *  waits for the GPU, as stbsViewer.timeFrames. */
  timeFrames(count = 60) {
    return timeFrames(this.gl, count, () => {
      this.applyPose();
      this.render();                        // updates the bones' matrices and their texture
    });
  }

  info() {
    const s = this.renderer.getDrawingBufferSize(new THREE.Vector2());
    return { vertices: this.n, bones: this.b, width: s.x, height: s.y,
             three: THREE.REVISION };
  }
}

const peer = new ThreeLbs();
const ready = peer.load().then(() => {
  document.body.dataset.ready = "true";
  return peer.info();
}, (err) => {
  document.body.dataset.error = err.message;
  console.error(`stbs three-lbs: ${err.message}`);
  throw err;
});
const whenReady = (f) => (...args) => ready.then(() => f(...args));

window.stbsThreeLbs = Object.freeze({
  ready,
  info: whenReady(() => peer.info()),
  fetchPose: whenReady(() => peer.fetchPose().then(() => undefined)),
  setCamera: whenReady((cam) => peer.setCamera(cam)),
  skinnedPositions: whenReady(() => peer.skinnedPositions()),
  timeFrames: whenReady((count) => peer.timeFrames(count)),
});
