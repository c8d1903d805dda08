// Compounds (shape type 7): one body of convex parts, each a shape of the dictionary at a pose
// in the body's frame. The engine centres that frame on the parts' centre of mass, so a body's
// position is that centre: the server sends the parts centred, and a scene file's parts are
// centred here the same way (centredParts) before a trajectory is drawn.
import { SHAPE } from './protocol.js';

/// Rotates v by the unit quaternion q (w x y z).
export function rotate(q, v) {
  const [w, a, b, c] = q;
  const tx = 2 * (b * v[2] - c * v[1]), ty = 2 * (c * v[0] - a * v[2]), tz = 2 * (a * v[1] - b * v[0]);
  return [v[0] + w * tx + (b * tz - c * ty), v[1] + w * ty + (c * tx - a * tz), v[2] + w * tz + (a * ty - b * tx)];
}

/// q r (w x y z).
export function multiply(q, r) {
  return [
    q[0] * r[0] - q[1] * r[1] - q[2] * r[2] - q[3] * r[3],
    q[0] * r[1] + q[1] * r[0] + q[2] * r[3] - q[3] * r[2],
    q[0] * r[2] - q[1] * r[3] + q[2] * r[0] + q[3] * r[1],
    q[0] * r[3] + q[1] * r[2] - q[2] * r[1] + q[3] * r[0],
  ];
}

/// A part's world pose at a body pose, as spu::part_pose composes it: position + R(body)
/// (body scale · part position), orientation body · part, scale body · part.
export function partPose(position, orientation, scale, part) {
  const r = rotate(orientation, part.position.map((x) => x * scale));
  return { position: r.map((x, k) => position[k] + x), orientation: multiply(orientation, part.orientation), scale: scale * part.scale };
}

/// A polyhedron's volume and centroid from its faces (vertices, face_start, face_vertices,
/// counter-clockwise from outside), fanned into tetrahedra about the vertex mean as the engine
/// integrates a hull.
export function polyhedronVolume(s) {
  const v = s.vertices, n = v.length / 3, ref = [0, 0, 0];
  for (let i = 0; i < n; ++i) for (let k = 0; k < 3; ++k) ref[k] += v[3 * i + k] / n;
  const at = (i) => [v[3 * i] - ref[0], v[3 * i + 1] - ref[1], v[3 * i + 2] - ref[2]];
  let V = 0;
  const S = [0, 0, 0];
  for (let f = 0; f + 1 < s.face_start.length; ++f) {
    const a = at(s.face_vertices[s.face_start[f]]);
    for (let i = s.face_start[f] + 1; i + 1 < s.face_start[f + 1]; ++i) {
      const b = at(s.face_vertices[i]), c = at(s.face_vertices[i + 1]);
      const det = a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0]) + a[2] * (b[0] * c[1] - b[1] * c[0]);
      V += det / 6;
      for (let k = 0; k < 3; ++k) S[k] += (det / 24) * (a[k] + b[k] + c[k]);
    }
  }
  return { volume: V, centroid: V > 0 ? S.map((x, k) => ref[k] + x / V) : ref };
}

/// A convex shape record's volume at unit scale (sphere, capsule, box, hull), as
/// runtime/ppe/mass_properties.cpp gives it.
export function shapeVolume(s) {
  const p = s.params;
  switch (s.type) {
    case SHAPE.sphere: return (4 / 3) * Math.PI * p[0] ** 3;
    case SHAPE.capsule: return Math.PI * p[0] * p[0] * 2 * p[1] + (4 / 3) * Math.PI * p[0] ** 3;
    case SHAPE.box: return 8 * p[0] * p[1] * p[2];
    case SHAPE.hull: return polyhedronVolume(s).volume;
    default: return 0;
  }
}

/// Parts as a scene file gives them ({record, position, orientation, scale}), moved so their
/// centre of mass at uniform density is the origin, as the engine stores them: volumes add (each
/// part's shape's volume times its scale cubed) and the centroids average, a part's centroid
/// being its position (every part's shape is centred on its own centre of mass: spheres,
/// capsules and boxes are, and hulls are stored so). Returns the parts and the shift taken off.
export function centredParts(parts) {
  let V = 0;
  const S = [0, 0, 0];
  for (const p of parts) {
    const v = shapeVolume(p.record) * p.scale ** 3;
    V += v;
    for (let k = 0; k < 3; ++k) S[k] += v * p.position[k];
  }
  const shift = V > 0 ? S.map((x) => x / V) : [0, 0, 0];
  return { parts: parts.map((p) => ({ ...p, position: p.position.map((x, k) => x - shift[k]) })), shift };
}
