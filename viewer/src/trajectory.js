// Offline: a `cellphys run --out` trajectory CSV (step,t,body,px,py,pz,qw,qx,qy,qz,vx,vy,vz,wx,wy,wz)
// as a Model with one frame per step written. The CSV has no shapes: each body is drawn as the
// shape its scene file gives it when that file is dropped with the CSV (the scene's static
// bodies, a ground plane say, are drawn too), otherwise as a 0.5 m box. A scene's meshes and
// height fields become the vertices and triangles the server would send for them, its hulls the
// faces of their points' convex hull centred on its centre of mass, and its compounds their
// parts centred on theirs: the engine's centring, which a trajectory's positions are of.
import { Vector3 } from 'three';
import { ConvexHull } from 'three/examples/jsm/math/ConvexHull.js';
import { Model, F_AWAKE, F_PRESENT, F_STATIC } from './model.js';
import { SHAPE, isConvex } from './protocol.js';
import { centredParts, polyhedronVolume } from './compound.js';

const HEADER = ['step', 't', 'body', 'px', 'py', 'pz', 'qw', 'qx', 'qy', 'qz', 'vx', 'vy', 'vz', 'wx', 'wy', 'wz'];

export class FileError extends Error {}

/// The CSV's body field: plain, or quoted with "" for a quote.
function splitRow(line) {
  if (!line.includes('"')) return line.split(',');
  const out = [];
  let cur = '', q = false;
  for (let i = 0; i < line.length; ++i) {
    const ch = line[i];
    if (q) {
      if (ch === '"' && line[i + 1] === '"') { cur += '"'; ++i; } else if (ch === '"') q = false; else cur += ch;
    } else if (ch === '"') q = true;
    else if (ch === ',') { out.push(cur); cur = ''; } else cur += ch;
  }
  out.push(cur);
  return out;
}

export function parseTrajectory(text, name = 'trajectory.csv') {
  const lines = text.split(/\r?\n/);
  const head = lines[0].trim().split(',');
  if (head.join(',') !== HEADER.join(',')) throw new FileError(`${name}: line 1 is not the trajectory header ${HEADER.join(',')}`);
  const rows = [];
  for (let i = 1; i < lines.length; ++i) {
    if (!lines[i]) continue;
    const f = splitRow(lines[i]);
    if (f.length !== HEADER.length) throw new FileError(`${name}: line ${i + 1} has ${f.length} fields, not ${HEADER.length}`);
    const v = f.map((x, k) => (k === 2 ? x : Number(x)));
    for (let k = 0; k < HEADER.length; ++k) {
      if (k !== 2 && !Number.isFinite(v[k])) throw new FileError(`${name}: line ${i + 1}, field ${HEADER[k]}: "${f[k]}" is not a number`);
    }
    rows.push(v);
  }
  if (!rows.length) throw new FileError(`${name}: no rows after the header`);
  return rows;
}

/// Triangles as the server sends them: each a face of 3.
function surface(type, vertices, triangles) {
  const n = triangles.length / 3;
  return {
    type, params: [], vertices, face_vertices: triangles, face_start: Uint32Array.from({ length: n + 1 }, (_, k) => 3 * k),
    num_vertices: vertices.length / 3, num_faces: n, num_face_vertices: 3 * n,
  };
}

/// A scene file's inline mesh: its vertices ([x, y, z] each) and triangles ([i, j, k] each).
function sceneMesh(s, where) {
  if (!Array.isArray(s.vertices) || !Array.isArray(s.triangles)) throw new FileError(`${where}: a mesh needs vertices and triangles`);
  const v = new Float32Array(3 * s.vertices.length), t = new Uint32Array(3 * s.triangles.length);
  s.vertices.forEach((x, i) => {
    if (!Array.isArray(x) || x.length !== 3 || !x.every(Number.isFinite)) throw new FileError(`${where}.vertices[${i}]: not 3 numbers`);
    v.set(x, 3 * i);
  });
  s.triangles.forEach((x, i) => {
    if (!Array.isArray(x) || x.length !== 3 || !x.every((k) => Number.isInteger(k) && k >= 0 && k < s.vertices.length))
      throw new FileError(`${where}.triangles[${i}]: not 3 indices of its ${s.vertices.length} vertices`);
    t.set(x, 3 * i);
  });
  return surface(SHAPE.mesh, v, t);
}

/// A height field's grid as the engine makes it (runtime/ppe/triangle_surface.cpp): row i along
/// y, column j along x, centred on the body origin, heights along z; each cell two triangles,
/// counter-clockwise seen from +z.
function sceneHeightField(s, where) {
  const R = s.rows, C = s.columns, h = s.heights;
  if (!Number.isInteger(R) || !Number.isInteger(C) || R < 2 || C < 2) throw new FileError(`${where}: rows and columns must be integers of at least 2`);
  if (!Array.isArray(s.spacing) || s.spacing.length !== 2 || !s.spacing.every((x) => x > 0)) throw new FileError(`${where}.spacing: not 2 positive numbers`);
  const sp = s.spacing.map(Math.fround); // the engine's spacing is a float, its products doubles
  if (!Array.isArray(h) || h.length !== R * C) throw new FileError(`${where}.heights: ${Array.isArray(h) ? h.length : 'no'} heights, but rows x columns is ${R * C}`);
  const v = new Float32Array(3 * R * C), t = new Uint32Array(6 * (R - 1) * (C - 1));
  for (let i = 0; i < R; ++i)
    for (let j = 0; j < C; ++j) v.set([(j - 0.5 * (C - 1)) * sp[0], (i - 0.5 * (R - 1)) * sp[1], h[i * C + j]], 3 * (i * C + j));
  let k = 0;
  for (let i = 0; i + 1 < R; ++i)
    for (let j = 0; j + 1 < C; ++j) {
      const a = i * C + j, b = a + 1, d = a + C, c = d + 1;
      t.set([a, b, c, a, c, d], k);
      k += 6;
    }
  return surface(SHAPE.height_field, v, t);
}

/// A scene file's hull as the server sends one: its points' convex hull (three's quickhull; the
/// engine's may differ for a cloud it simplifies, over HullLimits' 256 vertices), its faces
/// counter-clockwise from outside, centred on its centre of mass as the engine centres a hull.
function sceneHull(s, where) {
  if (!Array.isArray(s.points) || s.points.length < 4 || !s.points.every((x) => Array.isArray(x) && x.length === 3 && x.every(Number.isFinite)))
    throw new FileError(`${where}.points: not 4 or more points of 3 numbers`);
  const hull = new ConvexHull().setFromPoints(s.points.map((x) => new Vector3(...x)));
  const index = new Map(), vertices = [], faceStart = [0], loops = [];
  for (const face of hull.faces) {
    let e = face.edge;
    do {
      const v = e.head();
      if (!index.has(v)) { index.set(v, vertices.length / 3); vertices.push(v.point.x, v.point.y, v.point.z); }
      loops.push(index.get(v));
      e = e.next;
    } while (e !== face.edge);
    faceStart.push(loops.length);
  }
  const rec = {
    type: SHAPE.hull, params: [], vertices: Float32Array.from(vertices), face_start: Uint32Array.from(faceStart), face_vertices: Uint32Array.from(loops),
    num_vertices: vertices.length / 3, num_faces: faceStart.length - 1, num_face_vertices: loops.length,
  };
  const { volume, centroid } = polyhedronVolume(rec);
  if (!(volume > 0)) throw new FileError(`${where}.points: their hull has no volume`);
  for (let i = 0; i < rec.vertices.length; ++i) rec.vertices[i] -= centroid[i % 3];
  return rec;
}

/// A scene file's compound: each part names a shape earlier in the file (`named`: name to its
/// record and index); the parts come out centred on their centre of mass, as the server's are.
function sceneCompound(s, where, named) {
  if (!Array.isArray(s.parts) || !s.parts.length) throw new FileError(`${where}.parts: a compound needs at least one part`);
  const parts = s.parts.map((p, k) => {
    const at = `${where}.parts[${k}]`, n = named.get(p.shape);
    if (!n) throw new FileError(`${at}.shape: "${p.shape}" is not a shape named before this one`);
    if (!isConvex(n.record.type)) throw new FileError(`${at}.shape: "${p.shape}" is not a sphere, capsule, box or hull`);
    const q = p.orientation ?? [1, 0, 0, 0], norm = Math.hypot(...q);
    if (!(norm > 0)) throw new FileError(`${at}.orientation: not a rotation`);
    return { shape: n.index, record: n.record, position: [...(p.position ?? [0, 0, 0])], orientation: q.map((x) => x / norm), scale: p.scale ?? 1 };
  });
  return { type: SHAPE.compound, params: [], num_vertices: parts.length, parts: centredParts(parts).parts };
}

function sceneShape(s, where, warnings, named) {
  switch (s.type) {
    case 'sphere': return { type: SHAPE.sphere, params: [s.radius] };
    case 'capsule': return { type: SHAPE.capsule, params: [s.radius, s.half_height] };
    case 'box': return { type: SHAPE.box, params: [...s.half_extents] };
    case 'plane': return { type: SHAPE.plane, params: [...s.normal, s.offset ?? 0] };
    case 'hull': return sceneHull(s, where);
    case 'compound': return sceneCompound(s, where, named);
    case 'mesh':
      if (s.obj !== undefined) { // the OBJ file is not among the dropped files: drawn as nothing
        warnings.push(`${where}: mesh "${s.name}" is read from ${s.obj}, which the viewer does not open; it is not drawn`);
        return surface(SHAPE.mesh, new Float32Array(0), new Uint32Array(0));
      }
      return sceneMesh(s, where);
    case 'height_field': return sceneHeightField(s, where);
    default: throw new FileError(`${where}.type: "${s.type}" is not a shape type`);
  }
}

/// A Model from trajectory rows and, optionally, the scene (parsed JSON) they were run from.
export function trajectoryModel(rows, scene = null, sceneName = 'scene.json') {
  const shapes = [{ type: SHAPE.box, params: [0.25, 0.25, 0.25] }];
  const sceneBodies = new Map();
  const shapeIndex = new Map();
  const named = new Map(); // the shapes read so far, for compounds' parts
  const warnings = [];
  if (scene) {
    if (!Array.isArray(scene.shapes) || !Array.isArray(scene.bodies)) throw new FileError(`${sceneName}: not a scene file (no shapes or bodies array)`);
    scene.shapes.forEach((s, i) => {
      const record = sceneShape(s, `${sceneName}: shapes[${i}]`, warnings, named);
      named.set(s.name, { record, index: shapes.length });
      shapeIndex.set(s.name, shapes.length);
      shapes.push(record);
    });
    scene.bodies.forEach((b, i) => {
      if (!shapeIndex.has(b.shape)) throw new FileError(`${sceneName}: bodies[${i}].shape: "${b.shape}" is not a shape of the file`);
      sceneBodies.set(String(b.id), b);
    });
  }
  const dt = rows.length > 1 && rows[1][0] !== rows[0][0] ? (rows[1][1] - rows[0][1]) / (rows[1][0] - rows[0][0]) : 0;
  const m = new Model({ shapes, name: 'file', dt, source: 'file', capacity: Infinity });
  m.warning = warnings.join('; ');
  for (const r of rows) {
    if (m.slotOf.has(r[2])) continue;
    const sb = sceneBodies.get(r[2]);
    m.addBody({ id: r[2], label: r[2], shape: sb ? shapeIndex.get(sb.shape) : 0, scale: sb?.scale ?? 1 });
  }
  // Static bodies of the scene (not in the CSV) stand where the scene puts them.
  const statics = [];
  for (const [id, b] of sceneBodies) {
    if (m.slotOf.has(id) || !b.static) continue;
    statics.push([m.addBody({ id, label: id, shape: shapeIndex.get(b.shape), scale: b.scale ?? 1, flags: F_STATIC }), b]);
  }
  let f = null;
  for (const r of rows) {
    if (!f || f.step !== r[0]) {
      if (f) m.push(f);
      f = m.newFrame(r[0]);
      f.t = r[1];
      for (const [slot, b] of statics) {
        Model.setBody(f, slot, { position: b.position ?? [0, 0, 0], orientation: b.orientation ?? [1, 0, 0, 0], velocity: [0, 0, 0], angular_velocity: [0, 0, 0] }, F_PRESENT | F_STATIC);
      }
    }
    const slot = m.slotOf.get(r[2]);
    const moving = r.slice(10, 16).some((x) => x !== 0);
    Model.setBody(f, slot, { position: r.slice(3, 6), orientation: r.slice(6, 10), velocity: r.slice(10, 13), angular_velocity: r.slice(13, 16) }, F_PRESENT | (moving ? F_AWAKE : 0));
  }
  m.push(f);
  return m;
}
