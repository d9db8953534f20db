// Where a ray meets a triangle mesh, without the page: the nearest hit in front of the
// ray's origin (both sides of each triangle), with the point it stands for on the rest
// mesh. paint.js casts the pointer's ray against the skinned positions with it.
// Pure: no DOM, no WebGL.

/**
 * The nearest triangle the ray o + t d (t > 0) crosses, by Moller and Trumbore's test.
 *
 * @param o  the ray's origin {x, y, z}
 * @param d  its direction {x, y, z} (any length: t is in its units)
 * @param U  the mesh's positions, n x 3 (flat): where it is hit
 * @param F  its triangles, f x 3 vertex ids (flat)
 * @param R  the rest positions, n x 3 (flat): where the hit lies at rest
 * @returns {face, u, v, t, rest, posed, normal} or null: the face, the barycentric
 *   coordinates of the hit on its 2nd and 3rd corners, the hit point at rest (on R) and
 *   posed (on U), and the face's normal on U (not of unit length)
 */
export function castRay(o, d, U, F, R) {
  let best = null;
  for (let f = 0; f < F.length; f += 3) {
    const i0 = 3 * F[f], i1 = 3 * F[f + 1], i2 = 3 * F[f + 2];
    const e1x = U[i1] - U[i0], e1y = U[i1 + 1] - U[i0 + 1], e1z = U[i1 + 2] - U[i0 + 2];
    const e2x = U[i2] - U[i0], e2y = U[i2 + 1] - U[i0 + 1], e2z = U[i2 + 2] - U[i0 + 2];
    const px = d.y * e2z - d.z * e2y, py = d.z * e2x - d.x * e2z, pz = d.x * e2y - d.y * e2x;
    const det = e1x * px + e1y * py + e1z * pz;
    if (Math.abs(det) < 1e-20) continue;     // the ray runs along the triangle
    const inv = 1 / det;
    const sx = o.x - U[i0], sy = o.y - U[i0 + 1], sz = o.z - U[i0 + 2];
    const u = (sx * px + sy * py + sz * pz) * inv;
    if (u < 0 || u > 1) continue;
    const qx = sy * e1z - sz * e1y, qy = sz * e1x - sx * e1z, qz = sx * e1y - sy * e1x;
    const w = (d.x * qx + d.y * qy + d.z * qz) * inv;
    if (w < 0 || u + w > 1) continue;
    const t = (e2x * qx + e2y * qy + e2z * qz) * inv;
    if (t <= 0 || (best && t >= best.t)) continue;
    best = { face: f / 3, u, v: w, t };
  }
  if (!best) return null;
  const a = 3 * F[3 * best.face], b = 3 * F[3 * best.face + 1], c = 3 * F[3 * best.face + 2];
  const wa = 1 - best.u - best.v;
  best.rest = [0, 1, 2].map((k) => wa * R[a + k] + best.u * R[b + k] + best.v * R[c + k]);
  best.posed = [0, 1, 2].map((k) => wa * U[a + k] + best.u * U[b + k] + best.v * U[c + k]);
  const e1 = [0, 1, 2].map((k) => U[b + k] - U[a + k]), e2 = [0, 1, 2].map((k) => U[c + k] - U[a + k]);
  best.normal = [e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]];
  return best;
}
