// Read the skinned vertices back from the GPU: a raw WebGL2 program compiled from
// the same skinning GLSL as the mesh (skin.js), run over the vertices as points
// with transform feedback (rasterizer off), in the rig's vertex order.

import { FEEDBACK_FRAGMENT, FEEDBACK_VERTEX, TEXELS_PER_BONE } from "./skin.js";

function compile(gl, type, source) {
  const s = gl.createShader(type);
  gl.shaderSource(s, source);
  gl.compileShader(s);
  if (!gl.getShaderParameter(s, gl.COMPILE_STATUS)) {
    const log = gl.getShaderInfoLog(s);
    gl.deleteShader(s);
    throw new Error(`stbs viewer: the feedback shader did not compile: ${log}`);
  }
  return s;
}

export class SkinFeedback {
  /**
   * @param {WebGL2RenderingContext} gl  three's context (state is reset after each use)
   * @param {object} attrs  Float32Arrays: position, normal (n x 3), index, weight, end (n x 4)
   */
  constructor(gl, attrs, boneCount) {
    this.gl = gl;
    this.n = attrs.position.length / 3;
    this.boneCount = boneCount;
    const vs = compile(gl, gl.VERTEX_SHADER, FEEDBACK_VERTEX);
    const fs = compile(gl, gl.FRAGMENT_SHADER, FEEDBACK_FRAGMENT);
    const prog = gl.createProgram();
    gl.attachShader(prog, vs);
    gl.attachShader(prog, fs);
    gl.transformFeedbackVaryings(prog, ["tfPosition", "tfNormal"], gl.SEPARATE_ATTRIBS);
    gl.linkProgram(prog);
    if (!gl.getProgramParameter(prog, gl.LINK_STATUS)) {
      throw new Error(`stbs viewer: the feedback program did not link: ${gl.getProgramInfoLog(prog)}`);
    }
    gl.deleteShader(vs);
    gl.deleteShader(fs);
    this.program = prog;
    this.linked = true;
    this.uBones = gl.getUniformLocation(prog, "uBones");
    this.uMethod = gl.getUniformLocation(prog, "uMethod");
    this.vao = gl.createVertexArray();
    gl.bindVertexArray(this.vao);
    const layout = { position: 3, normal: 3, stbsIndex: 4, stbsWeight: 4, stbsEnd: 4 };
    const data = { position: attrs.position, normal: attrs.normal, stbsIndex: attrs.index,
                   stbsWeight: attrs.weight, stbsEnd: attrs.end };
    this.buffers = [];
    this.bufferOf = {};
    for (const [name, size] of Object.entries(layout)) {
      const loc = gl.getAttribLocation(prog, name);
      const buf = gl.createBuffer();
      this.bufferOf[name] = buf;
      gl.bindBuffer(gl.ARRAY_BUFFER, buf);
      gl.bufferData(gl.ARRAY_BUFFER, data[name], gl.STATIC_DRAW);
      this.buffers.push(buf);
      if (loc >= 0) {
        gl.enableVertexAttribArray(loc);
        gl.vertexAttribPointer(loc, size, gl.FLOAT, false, 0, 0);
      }
    }
    gl.bindVertexArray(null);
    this.out = [gl.createBuffer(), gl.createBuffer()];
    for (const buf of this.out) {
      gl.bindBuffer(gl.TRANSFORM_FEEDBACK_BUFFER, buf);
      gl.bufferData(gl.TRANSFORM_FEEDBACK_BUFFER, 12 * this.n, gl.STREAM_READ);
    }
    gl.bindBuffer(gl.TRANSFORM_FEEDBACK_BUFFER, null);
    this.tf = gl.createTransformFeedback();
    this.texture = gl.createTexture();
    gl.bindTexture(gl.TEXTURE_2D, this.texture);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, gl.NEAREST);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, gl.NEAREST);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_WRAP_S, gl.CLAMP_TO_EDGE);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_WRAP_T, gl.CLAMP_TO_EDGE);
    gl.bindTexture(gl.TEXTURE_2D, null);
  }

  /** Replace one input attribute's data (stbsIndex, stbsWeight, stbsEnd: n x 4 floats). */
  setAttribute(name, data) {
    const gl = this.gl, buf = this.bufferOf[name];
    if (!buf) throw new Error(`stbs viewer: no feedback attribute ${name}`);
    gl.bindBuffer(gl.ARRAY_BUFFER, buf);
    gl.bufferSubData(gl.ARRAY_BUFFER, 0, data);
    gl.bindBuffer(gl.ARRAY_BUFFER, null);
  }

  /** Skin with the pose texture data and method; returns [positions, normals] (n x 3 each). */
  run(boneData, method) {
    const gl = this.gl;
    gl.useProgram(this.program);
    gl.activeTexture(gl.TEXTURE0);
    gl.bindTexture(gl.TEXTURE_2D, this.texture);
    gl.pixelStorei(gl.UNPACK_ALIGNMENT, 4);
    gl.pixelStorei(gl.UNPACK_FLIP_Y_WEBGL, false);
    gl.pixelStorei(gl.UNPACK_PREMULTIPLY_ALPHA_WEBGL, false);
    gl.bindBuffer(gl.PIXEL_UNPACK_BUFFER, null);
    gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA32F, TEXELS_PER_BONE, this.boneCount, 0,
                  gl.RGBA, gl.FLOAT, boneData);
    gl.uniform1i(this.uBones, 0);
    gl.uniform1i(this.uMethod, method);
    gl.bindVertexArray(this.vao);
    gl.bindTransformFeedback(gl.TRANSFORM_FEEDBACK, this.tf);
    gl.bindBufferBase(gl.TRANSFORM_FEEDBACK_BUFFER, 0, this.out[0]);
    gl.bindBufferBase(gl.TRANSFORM_FEEDBACK_BUFFER, 1, this.out[1]);
    gl.enable(gl.RASTERIZER_DISCARD);
    gl.beginTransformFeedback(gl.POINTS);
    gl.drawArrays(gl.POINTS, 0, this.n);
    gl.endTransformFeedback();
    gl.disable(gl.RASTERIZER_DISCARD);
    gl.bindBufferBase(gl.TRANSFORM_FEEDBACK_BUFFER, 0, null);
    gl.bindBufferBase(gl.TRANSFORM_FEEDBACK_BUFFER, 1, null);
    gl.bindTransformFeedback(gl.TRANSFORM_FEEDBACK, null);
    gl.bindVertexArray(null);
    const result = [];
    for (const buf of this.out) {
      const a = new Float32Array(3 * this.n);
      gl.bindBuffer(gl.TRANSFORM_FEEDBACK_BUFFER, buf);
      gl.getBufferSubData(gl.TRANSFORM_FEEDBACK_BUFFER, 0, a);
      result.push(a);
    }
    gl.bindBuffer(gl.TRANSFORM_FEEDBACK_BUFFER, null);
    return result;
  }
}
