// Solver overlays drawn over the bodies: contact points, their normals (length by normal force),
// the couplings decoupling cut (from each body's centre through the contact point to the other's),
// and axis-aligned bounding boxes computed here from each body's shape, scale and pose.
import * as THREE from 'three';
import { FLOATS, F_PRESENT } from './model.js';
import { SHAPE, isSurface } from './protocol.js';
import { partPose } from './compound.js';

const NORMAL_LENGTH = 0.5; // m, the longest normal in a message (the largest force)

/// A body's world box from its shape record, scale and pose (w x y z); null for a plane, or a
/// shape whose vertices the viewer does not have. A compound's is the union of its parts' boxes,
/// each at its part pose.
export function boundingBox(shape, scale, pos, q) {
  if (shape.type === SHAPE.compound) {
    let box = null;
    for (const part of shape.parts) {
      const p = partPose(pos, q, scale, part);
      const b = boundingBox(part.record, p.scale, p.position, p.orientation);
      if (!b) return null;
      box = box ? { min: box.min.map((c, i) => Math.min(c, b.min[i])), max: box.max.map((c, i) => Math.max(c, b.max[i])) } : b;
    }
    return box;
  }
  const [w, x, y, z] = q;
  // rotation matrix rows
  const R = [
    [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
    [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
    [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
  ];
  const p = shape.params;
  const half = [0, 0, 0];
  if (shape.type === SHAPE.sphere) half.fill(p[0] * scale);
  else if (shape.type === SHAPE.box) for (let i = 0; i < 3; ++i) half[i] = scale * (Math.abs(R[i][0]) * p[0] + Math.abs(R[i][1]) * p[1] + Math.abs(R[i][2]) * p[2]);
  else if (shape.type === SHAPE.capsule) for (let i = 0; i < 3; ++i) half[i] = scale * (Math.abs(R[i][2]) * p[1] + p[0]);
  else if (shape.type === SHAPE.hull || isSurface(shape.type)) { // their vertices, turned
    const lo = [Infinity, Infinity, Infinity], hi = [-Infinity, -Infinity, -Infinity], v = shape.vertices;
    if (!v || !v.length) return null; // an OBJ mesh a trajectory could not read
    for (let k = 0; k < v.length; k += 3)
      for (let i = 0; i < 3; ++i) {
        const c = scale * (R[i][0] * v[k] + R[i][1] * v[k + 1] + R[i][2] * v[k + 2]);
        lo[i] = Math.min(lo[i], c); hi[i] = Math.max(hi[i], c);
      }
    return { min: lo.map((c, i) => pos[i] + c), max: hi.map((c, i) => pos[i] + c) };
  } else return null;
  return { min: pos.map((c, i) => c - half[i]), max: pos.map((c, i) => c + half[i]) };
}

function lines(colour) {
  const g = new THREE.BufferGeometry();
  g.setAttribute('position', new THREE.Float32BufferAttribute([], 3));
  const l = new THREE.LineSegments(g, new THREE.LineBasicMaterial({ color: colour, depthTest: false }));
  l.renderOrder = 2;
  l.frustumCulled = false;
  return l;
}

export class Overlay {
  constructor(scene) {
    this.group = new THREE.Group();
    scene.add(this.group);
    const pg = new THREE.BufferGeometry();
    pg.setAttribute('position', new THREE.Float32BufferAttribute([], 3));
    this.points = new THREE.Points(pg, new THREE.PointsMaterial({ color: 0xff3b3b, size: 6, sizeAttenuation: false, depthTest: false }));
    this.points.renderOrder = 3;
    this.points.frustumCulled = false;
    this.normals = lines(0xffd23b);
    this.boxes = lines(0x7fe0ff);
    this.cuts = lines(0xff4fd8);
    this.group.add(this.points, this.normals, this.boxes, this.cuts);
    this.contactCount = 0;
    this.boxCount = 0;
    this.cutCount = 0;
  }

  /// The cut couplings of a debug message (null: none) between the bodies where `frame` has
  /// them; a contact's line bends at its point, a force's is straight.
  setCuts(cuts, model, frame, show) {
    const seg = [];
    let n = 0;
    if (show && cuts && model && frame) {
      const at = (id) => {
        const s = frame.slotOf.get(id);
        if (s === undefined || !(frame.flags[s] & F_PRESENT)) return null;
        return Array.from(frame.data.subarray(s * FLOATS, s * FLOATS + 3));
      };
      for (const c of cuts) {
        const a = at(c.a), b = at(c.b);
        if (!a || !b) continue;
        if (c.force === null) seg.push(...a, ...c.point, ...c.point, ...b);
        else seg.push(...a, ...b);
        ++n;
      }
    }
    this.cuts.geometry.setAttribute('position', new THREE.Float32BufferAttribute(seg, 3));
    this.cutCount = n;
  }

  /// Contacts of a debug message (null: none); `show` picks points and normals.
  setContacts(contacts, show) {
    const pts = [], seg = [];
    if (contacts && (show.contacts || show.normals)) {
      const most = contacts.reduce((a, c) => Math.max(a, c.force), 0) || 1;
      for (const c of contacts) {
        if (show.contacts) pts.push(...c.point);
        if (show.normals) {
          const len = NORMAL_LENGTH * Math.max(c.force / most, 0.02);
          seg.push(...c.point, c.point[0] + c.normal[0] * len, c.point[1] + c.normal[1] * len, c.point[2] + c.normal[2] * len);
        }
      }
    }
    this.points.geometry.setAttribute('position', new THREE.Float32BufferAttribute(pts, 3));
    this.normals.geometry.setAttribute('position', new THREE.Float32BufferAttribute(seg, 3));
    this.contactCount = pts.length / 3;
  }

  /// Bounding boxes of the frame's bodies, or none.
  setBoxes(model, frame, show) {
    const seg = [];
    if (show && model && frame) {
      const d = frame.data;
      for (let s = 0; s < frame.flags.length; ++s) {
        if (!(frame.flags[s] & F_PRESENT)) continue;
        const b = model.bodies[s], o = s * FLOATS;
        const box = boundingBox(model.shapes[b.shape], b.scale, [d[o], d[o + 1], d[o + 2]], [d[o + 3], d[o + 4], d[o + 5], d[o + 6]]);
        if (!box) continue;
        const c = (i) => [i & 1 ? box.max[0] : box.min[0], i & 2 ? box.max[1] : box.min[1], i & 4 ? box.max[2] : box.min[2]];
        for (const [i, j] of [[0, 1], [2, 3], [4, 5], [6, 7], [0, 2], [1, 3], [4, 6], [5, 7], [0, 4], [1, 5], [2, 6], [3, 7]]) seg.push(...c(i), ...c(j));
      }
    }
    this.boxes.geometry.setAttribute('position', new THREE.Float32BufferAttribute(seg, 3));
    this.boxCount = seg.length / 72;
  }
}
