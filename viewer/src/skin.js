// The skinning GLSL (GLSL ES 3.00), shared by the mesh's ShaderMaterial and the
// transform-feedback program that reads the skinned vertices back (feedback.js):
// one source, so what the tests read back is what the page draws.
//
// docs/skinning.md, four methods, with the library's conventions
// (src/stbs/skinning/_kernels.py): top-4 bones per vertex, heaviest first; the
// dual-quaternion methods flip every quaternion into the hemisphere of slot 0's
// (the heaviest bone, the pivot); normals turned by the cofactor of the blended
// linear part (lbs, stbs-lbs) or by the blended rotation (dqs, stbs-dqs).

/** Texels per bone in the pose texture (one row per bone), see pose.js. */
export const TEXELS_PER_BONE = 8;

/**
 * The skinning methods in the order of the shader's uMethod values (its branches
 * below test these indices). The page takes the names from the server (`methods`
 * of /api/rig, the library's stbs.methods.SKINNING_METHODS) and only checks them
 * against this order with checkMethods.
 */
export const SHADER_METHODS = Object.freeze(["lbs", "dqs", "stbs-lbs", "stbs-dqs"]);

/**
 * The server's skinning methods, checked to be the shader's order: returns a copy
 * of `methods`, or throws naming what the shader knows and what arrived.
 */
export function checkMethods(methods) {
  const ok = Array.isArray(methods) && methods.length === SHADER_METHODS.length &&
             methods.every((m, i) => m === SHADER_METHODS[i]);
  if (!ok) {
    throw new Error(`the rig's skinning methods ("methods" of /api/rig) must be ` +
                    `${JSON.stringify(SHADER_METHODS)} in this order, the order this page's ` +
                    `shader knows, got ${JSON.stringify(methods)}: the page and the server ` +
                    `are from different versions of stbs`);
  }
  return methods.slice();
}

export const SKIN_GLSL = /* glsl */ `
// ---- stbs skinning -------------------------------------------------------
// Pose texture, RGBA32F, row i = bone i:
//  0..2: columns of R_i (xyz) | w: sigma_i, theta_a, theta_b
//  3: a'_i (posed start), w: rest length l_i
//  4: a_i (rest start)
//  5: u_i (rest unit axis)
//  6: the rotation quaternion of R_i (xyz vector, w scalar)
//  7: the dual part of the rigid map x -> a'_i + R_i (x - a_i)
uniform highp sampler2D uBones;
uniform int uMethod;        // 0 lbs, 1 dqs, 2 stbs-lbs, 3 stbs-dqs

struct StbsBone {
  mat3 R; vec3 ap; vec3 a; vec3 u; vec4 qr; vec4 qd;
  float sigma; float ta; float tb; float len;
};

StbsBone stbsBone(float index) {
  int i = int(index + 0.5);
  vec4 t0 = texelFetch(uBones, ivec2(0, i), 0);
  vec4 t1 = texelFetch(uBones, ivec2(1, i), 0);
  vec4 t2 = texelFetch(uBones, ivec2(2, i), 0);
  vec4 t3 = texelFetch(uBones, ivec2(3, i), 0);
  StbsBone b;
  b.R = mat3(t0.xyz, t1.xyz, t2.xyz);
  b.sigma = t0.w; b.ta = t1.w; b.tb = t2.w;
  b.ap = t3.xyz; b.len = t3.w;
  b.a = texelFetch(uBones, ivec2(4, i), 0).xyz;
  b.u = texelFetch(uBones, ivec2(5, i), 0).xyz;
  b.qr = texelFetch(uBones, ivec2(6, i), 0);
  b.qd = texelFetch(uBones, ivec2(7, i), 0);
  return b;
}

// (sin x, cos x) to float precision for any |x| up to thousands of radians: the
// built-in sin/cos are not accurate enough on every GPU (SwiftShader: 1e-3 at
// 720 degrees). Reduce by pi/2 in two parts (Cody-Waite), then Taylor
// polynomials on |r| <= pi/4 and a quadrant fix-up.
vec2 stbsSinCos(float x) {
  float k = floor(x * 0.636619772367581 + 0.5);
  float r = (x - k * 1.5703125) - k * 4.838267948966e-4;
  float r2 = r * r;
  float s = r + r * r2 * (-1.666666666666667e-1 + r2 * (8.333333333333333e-3
            + r2 * (-1.984126984126984e-4 + r2 * 2.755731922398589e-6)));
  float c = 1.0 + r2 * (-0.5 + r2 * (4.166666666666667e-2 + r2 * (-1.388888888888889e-3
            + r2 * (2.480158730158730e-5 - r2 * 2.755731922398589e-7))));
  int q = int(k) & 3;
  vec2 sc = ((q & 1) == 1) ? vec2(c, s) : vec2(s, c);
  if (q == 2 || q == 3) sc.x = -sc.x;
  if (q == 1 || q == 2) sc.y = -sc.y;
  return sc;
}

// quaternions as vec4(x, y, z, w), w the scalar part
vec4 stbsQmul(vec4 p, vec4 q) {
  return vec4(p.w * q.xyz + q.w * p.xyz + cross(p.xyz, q.xyz), p.w * q.w - dot(p.xyz, q.xyz));
}
vec3 stbsQrot(vec4 q, vec3 v) {
  return v + 2.0 * cross(q.xyz, cross(q.xyz, v) + q.w * v);
}
// the normal of a surface mapped by M: cof(M) n = det(M) M^-T n, normalised
vec3 stbsCofactor(mat3 M, vec3 n) {
  mat3 C = mat3(cross(M[1], M[2]), cross(M[2], M[0]), cross(M[0], M[1]));
  vec3 m = C * n;
  float l = length(m);
  return l > 0.0 ? m / l : m;
}
mat3 stbsCrossMatrix(vec3 u) {   // [u]x: [u]x v = cross(u, v)
  return mat3(0.0, u.z, -u.y, -u.z, 0.0, u.x, u.y, -u.x, 0.0);
}
// apply the blended dual quaternion (r, d), normalised; r comes back normalised
vec3 stbsDqApply(inout vec4 r, vec4 d, vec3 p) {
  float inv = inversesqrt(dot(r, r));
  r *= inv; d *= inv;
  vec3 t = 2.0 * (r.w * d.xyz - d.w * r.xyz + cross(r.xyz, d.xyz));
  return stbsQrot(r, p) + t;
}

void stbsSkin(vec3 p, vec3 n, vec4 idx, vec4 w, vec4 e, out vec3 P, out vec3 N) {
  P = vec3(0.0);
  N = n;
  if (uMethod == 0 || uMethod == 2) {
    // lbs (eq. 1-3): a' + R S (p - a);  stbs-lbs (eq. 5): a' + R K(e) (e s + p - a)
    mat3 M = mat3(0.0);
    for (int k = 0; k < 4; k++) {
      float wk = w[k];
      if (wk <= 0.0) continue;
      StbsBone b = stbsBone(idx[k]);
      vec3 x = p - b.a;
      if (uMethod == 0) {
        vec3 Sx = x + (b.sigma - 1.0) * dot(b.u, x) * b.u;
        P += wk * (b.ap + b.R * Sx);
        M += wk * (b.R + (b.sigma - 1.0) * outerProduct(b.R * b.u, b.u));
      } else {
        float ek = e[k];
        vec2 sc = stbsSinCos((1.0 - ek) * b.ta + ek * b.tb);
        vec3 y = x + (ek * (b.sigma - 1.0) * b.len) * b.u;
        vec3 Ky = sc.y * y + sc.x * cross(b.u, y) + (1.0 - sc.y) * dot(b.u, y) * b.u;
        P += wk * (b.ap + b.R * Ky);
        mat3 K = sc.y * mat3(1.0) + sc.x * stbsCrossMatrix(b.u)
                 + (1.0 - sc.y) * outerProduct(b.u, b.u);
        M += wk * (b.R * K);
      }
    }
    N = stbsCofactor(M, n);
  } else {
    // dqs: stretches blended in rest space, rigid parts as dual quaternions;
    // stbs-dqs (eq. 6): x -> a' + R K(e) (e s - a) + R K(e) x as dual quaternions
    vec4 r = vec4(0.0), d = vec4(0.0), pivot = vec4(0.0);
    vec3 ps = p;
    for (int k = 0; k < 4; k++) {
      float wk = w[k];
      if (wk <= 0.0) continue;
      StbsBone b = stbsBone(idx[k]);
      vec4 qr, qd;
      if (uMethod == 1) {
        ps += wk * (b.sigma - 1.0) * dot(b.u, p - b.a) * b.u;
        qr = b.qr;
        qd = b.qd;
      } else {
        float ek = e[k];
        vec2 sc = stbsSinCos(0.5 * ((1.0 - ek) * b.ta + ek * b.tb));
        qr = stbsQmul(b.qr, vec4(sc.x * b.u, sc.y));
        vec3 t = b.ap + (ek * (b.sigma - 1.0) * b.len) * (b.R * b.u) - stbsQrot(qr, b.a);
        qd = 0.5 * stbsQmul(vec4(t, 0.0), qr);
      }
      if (k == 0) pivot = qr;
      float sw = dot(qr, pivot) >= 0.0 ? wk : -wk;   // the pivot's hemisphere
      r += sw * qr;
      d += sw * qd;
    }
    P = stbsDqApply(r, d, ps);
    N = stbsQrot(r, n);
  }
}
// ---------------------------------------------------------------------------
`;

/** The mesh's vertex shader (three.js ShaderMaterial, GLSL3: three adds its prefix). */
export const MESH_VERTEX = SKIN_GLSL + /* glsl */ `
in vec4 stbsIndex;
in vec4 stbsWeight;
in vec4 stbsEnd;
in vec2 stbsSel;            // the selected bone's (W, f(E)) at this vertex (paint.js)
uniform int uColorMode;     // 0 shaded, 1 bones, 2 endpoint, 3 weight (paint.js COLOR_MODES)
out vec3 vNormal;
out vec3 vView;
out vec3 vTint;
out vec2 vUv;
out float vColorMode;
vec3 boneHue(float i) {
  return 0.5 + 0.5 * cos(6.28318 * (fract(i * 0.618034) + vec3(0.0, 0.33, 0.67)));
}
// heat map of a weight in [0, 1]: 0 blue, 0.25 cyan, 0.5 green, 0.75 yellow, 1 red
vec3 stbsHeat(float e) {
  float t = clamp(e, 0.0, 1.0) * 4.0;
  vec3 c0 = vec3(0.10, 0.15, 0.85), c1 = vec3(0.0, 0.75, 0.95), c2 = vec3(0.15, 0.85, 0.25);
  vec3 c3 = vec3(1.0, 0.85, 0.05), c4 = vec3(0.90, 0.10, 0.05);
  if (t < 1.0) return mix(c0, c1, t);
  if (t < 2.0) return mix(c1, c2, t - 1.0);
  if (t < 3.0) return mix(c2, c3, t - 2.0);
  return mix(c3, c4, t - 3.0);
}
void main() {
  vec3 P, N;
  stbsSkin(position, normal, stbsIndex, stbsWeight, stbsEnd, P, N);
  vTint = vec3(0.0);
  for (int k = 0; k < 4; k++) vTint += stbsWeight[k] * boneHue(stbsIndex[k]);
  // the selected bone's endpoint weight f(E) where its bone weight is not zero (1e-7:
  // "zero" in the paper's §3), grey elsewhere; or its bone weight W everywhere
  if (uColorMode == 2) vTint = stbsSel.x > 1e-7 ? stbsHeat(stbsSel.y) : vec3(0.5);
  if (uColorMode == 3) vTint = stbsHeat(stbsSel.x);
  vColorMode = float(uColorMode);
  vUv = uv;
  vec4 mv = modelViewMatrix * vec4(P, 1.0);
  vView = -mv.xyz;
  vNormal = normalMatrix * N;
  gl_Position = projectionMatrix * mv;
}
`;

/** Lit and shaded: a headlight (diffuse + Blinn-Phong), a fill light and ambient. */
export const MESH_FRAGMENT = /* glsl */ `
uniform vec3 uColor;
uniform float uBoneTint;
uniform float uFlat;
uniform float uTextured;
uniform sampler2D uPicture;
in vec3 vNormal;
in vec3 vView;
in vec3 vTint;
in vec2 vUv;
in float vColorMode;
out highp vec4 fragColor;
void main() {
  // shaded: the skin colour tinted by the bones; bones, endpoint: the tint alone
  vec3 base = vColorMode < 0.5 ? mix(uColor, vTint, uBoneTint) : vTint;
  if (uTextured > 0.5 && vColorMode < 0.5) {      // a 2D picture (stbs view --example picture): its own colours
    vec4 t = texture(uPicture, vUv);
    if (t.a < 0.5) discard;
    fragColor = vec4(t.rgb, 1.0);
    return;
  }
  if (uFlat > 0.5) { fragColor = vec4(base, 1.0); return; }
  vec3 n = normalize(vNormal);
  if (!gl_FrontFacing) n = -n;
  vec3 v = normalize(vView);
  vec3 key = normalize(v + vec3(0.35, 0.5, 0.0));
  vec3 fill = normalize(vec3(-0.6, -0.2, 0.5));
  float dk = max(dot(n, key), 0.0);
  float df = max(dot(n, fill), 0.0);
  float spec = pow(max(dot(n, normalize(key + v)), 0.0), 48.0);
  vec3 c = base * (0.18 + 0.75 * dk + 0.22 * df) + 0.25 * spec;
  fragColor = vec4(pow(c, vec3(1.0 / 2.2)), 1.0);
}
`;

/** The transform-feedback program: the same skinning, positions and normals out. */
export const FEEDBACK_VERTEX = `#version 300 es
precision highp float;
precision highp int;
precision highp sampler2D;
in vec3 position;
in vec3 normal;
in vec4 stbsIndex;
in vec4 stbsWeight;
in vec4 stbsEnd;
out vec3 tfPosition;
out vec3 tfNormal;
` + SKIN_GLSL + `
void main() {
  stbsSkin(position, normal, stbsIndex, stbsWeight, stbsEnd, tfPosition, tfNormal);
  gl_Position = vec4(0.0, 0.0, 0.0, 1.0);
  gl_PointSize = 1.0;
}
`;

export const FEEDBACK_FRAGMENT = `#version 300 es
precision highp float;
out vec4 color;
void main() { color = vec4(0.0); }
`;
