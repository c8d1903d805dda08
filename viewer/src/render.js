// Drawing a Model's frame with three.js: one InstancedMesh per shape of the dictionary (a body
// is an instance: its pose and uniform scale in the instance matrix, its colour by state), an
// orbit camera about z up, a sun with shadows, a sky light and a grid on the ground plane.
// Meshes and height fields (static level geometry) are drawn from their triangles. A compound
// has one InstancedMesh a part: the part's shape's geometry moved to the part's pose in the
// body frame, so a compound body is an instance of each, at the body's pose.
import * as THREE from 'three';
import { OrbitControls } from 'three/examples/jsm/controls/OrbitControls.js';
import { FLOATS, F_AWAKE, F_PRESENT, F_STATIC } from './model.js';
import { SHAPE, isStaticShape, isSurface } from './protocol.js';
import { boundingBox } from './overlay.js';

const COLOURS = {
  [SHAPE.sphere]: 0x4f8fd8, [SHAPE.capsule]: 0x58b368, [SHAPE.box]: 0xd8924f, [SHAPE.hull]: 0xb36bc4, [SHAPE.plane]: 0x9aa3ad,
  [SHAPE.mesh]: 0x9b8c6e, [SHAPE.height_field]: 0x6e8f4f, // stone and grass: ground, not bodies
  [SHAPE.compound]: 0xd0607e, // one colour for all its parts: one body
};
const STATIC_COLOUR = new THREE.Color(0x6d747c);
const ASLEEP_COLOUR = new THREE.Color(0xa0a0a0);
const SELECTED_COLOUR = new THREE.Color(0xffe04a);

function hullGeometry(s) {
  const pos = [];
  const v = s.vertices;
  for (let f = 0; f < s.face_start.length - 1; ++f) {
    const a = s.face_start[f], b = s.face_start[f + 1];
    for (let k = a + 1; k + 1 < b; ++k) {
      for (const i of [s.face_vertices[a], s.face_vertices[k], s.face_vertices[k + 1]]) pos.push(v[3 * i], v[3 * i + 1], v[3 * i + 2]);
    }
  }
  const g = new THREE.BufferGeometry();
  g.setAttribute('position', new THREE.Float32BufferAttribute(pos, 3));
  g.computeVertexNormals(); // not indexed: one normal a face, flat shading
  return g;
}

/// A height field's triangles sharing its grid's vertices, so the normals computed at a vertex
/// average its triangles' and the terrain shades smooth; a mesh is drawn flat, as a hull is
/// (its edges may be creases meant to show).
function surfaceGeometry(s) {
  if (s.type !== SHAPE.height_field) return hullGeometry(s);
  const g = new THREE.BufferGeometry();
  g.setAttribute('position', new THREE.BufferAttribute(Float32Array.from(s.vertices), 3));
  g.setIndex(new THREE.BufferAttribute(Uint32Array.from(s.face_vertices), 1));
  g.computeVertexNormals();
  return g;
}

/// The geometry of a dictionary shape in its body frame (scale 1). `extent` sizes planes.
export function shapeGeometry(s, extent) {
  const p = s.params;
  switch (s.type) {
    case SHAPE.sphere: return new THREE.SphereGeometry(p[0], 24, 16);
    case SHAPE.capsule: return new THREE.CapsuleGeometry(p[0], 2 * p[1], 6, 16).rotateX(Math.PI / 2); // three's axis is y, ours z
    case SHAPE.box: return new THREE.BoxGeometry(2 * p[0], 2 * p[1], 2 * p[2]);
    case SHAPE.hull: return hullGeometry(s); // a trajectory's too: trajectory.js makes its faces
    case SHAPE.mesh:
    case SHAPE.height_field: return surfaceGeometry(s);
    case SHAPE.plane: {
      const n = new THREE.Vector3(p[0], p[1], p[2]).normalize();
      const g = new THREE.PlaneGeometry(extent, extent);
      g.applyQuaternion(new THREE.Quaternion().setFromUnitVectors(new THREE.Vector3(0, 0, 1), n));
      g.translate(n.x * p[3], n.y * p[3], n.z * p[3]);
      return g;
    }
    default: return new THREE.BoxGeometry(0.1, 0.1, 0.1);
  }
}

/// A compound part's placement in its body's frame.
function partMatrix(part) {
  const [w, x, y, z] = part.orientation;
  return new THREE.Matrix4().compose(new THREE.Vector3(...part.position), new THREE.Quaternion(x, y, z, w).normalize(),
    new THREE.Vector3().setScalar(part.scale));
}

/// A colour per island: hues a golden angle apart, so neighbouring indices differ.
function islandColour(island, c) {
  return c.setHSL((island * 0.618034) % 1, 0.65, 0.55);
}

export class Renderer {
  constructor(canvas) {
    this.canvas = canvas;
    this.gl = new THREE.WebGLRenderer({ canvas, antialias: true, preserveDrawingBuffer: true });
    this.gl.setPixelRatio(Math.min(window.devicePixelRatio, 2));
    this.gl.shadowMap.enabled = true;
    this.gl.shadowMap.type = THREE.PCFShadowMap;
    this.scene = new THREE.Scene();
    this.scene.background = new THREE.Color(0x1d2228);
    this.camera = new THREE.PerspectiveCamera(45, 1, 0.05, 2000);
    this.camera.up.set(0, 0, 1);
    this.controls = new OrbitControls(this.camera, canvas);
    this.controls.enableDamping = true;
    this.scene.add(new THREE.HemisphereLight(0xe6eefa, 0x5a5046, 2.2), new THREE.AmbientLight(0xffffff, 0.35));
    this.sun = new THREE.DirectionalLight(0xffffff, 2.0);
    this.sun.castShadow = true;
    this.sun.shadow.mapSize.set(2048, 2048);
    this.scene.add(this.sun, this.sun.target);
    this.world = new THREE.Group();
    this.scene.add(this.world);
    this.meshes = [];
    this.selectedSlot = -1;
    this.frames = 0;
    this.resize();
    window.addEventListener('resize', () => this.resize());
  }

  resize() {
    const w = this.canvas.clientWidth || window.innerWidth, h = this.canvas.clientHeight || window.innerHeight;
    this.gl.setSize(w, h, false);
    this.camera.aspect = w / h;
    this.camera.updateProjectionMatrix();
  }

  /// A new model: meshes for its shapes, camera and sun framed on its first frame.
  setModel(model, frame, { keepCamera = false } = {}) {
    for (const m of this.meshes) { m.geometry.dispose(); m.material.dispose(); }
    this.world.clear();
    this.meshes = [];
    this.model = model;
    let gridDone = false;
    // Framed on the bodies; the ground and level geometry only when there is nothing else.
    const box = new THREE.Box3(), ground = new THREE.Box3();
    for (let s = 0; s < frame.flags.length; ++s) {
      if (!(frame.flags[s] & F_PRESENT)) continue;
      const b = model.bodies[s], type = model.shapes[b.shape]?.type, o = s * FLOATS;
      if (isSurface(type)) {
        const d = frame.data;
        const w = boundingBox(model.shapes[b.shape], b.scale, [d[o], d[o + 1], d[o + 2]], [d[o + 3], d[o + 4], d[o + 5], d[o + 6]]);
        if (w) ground.union(new THREE.Box3(new THREE.Vector3(...w.min), new THREE.Vector3(...w.max)));
      } else if (type !== SHAPE.plane) box.expandByPoint(new THREE.Vector3().fromArray(frame.data, o));
    }
    const lowest = Math.min(box.isEmpty() ? Infinity : box.min.z, ground.isEmpty() ? Infinity : ground.min.z);
    if (box.isEmpty()) box.copy(ground);
    if (box.isEmpty()) box.set(new THREE.Vector3(-5, -5, 0), new THREE.Vector3(5, 5, 2));
    const size = box.getSize(new THREE.Vector3()), centre = box.getCenter(new THREE.Vector3());
    const radius = Math.max(2, 0.5 * size.length());
    this.extent = Math.max(20, 4 * radius);
    model.shapes.forEach((s, i) => {
      // A compound's parts, each its shape's geometry placed in the body frame; other shapes one piece.
      const pieces = s.type === SHAPE.compound
        ? s.parts.map((part, k) => { const m = partMatrix(part); return { geometry: shapeGeometry(part.record, this.extent).applyMatrix4(m), type: part.record.type, part: k, matrix: m }; })
        : [{ geometry: shapeGeometry(s, this.extent), type: s.type, part: -1, matrix: null }];
      for (const piece of pieces) {
        const t = piece.type;
        const material = new THREE.MeshStandardMaterial({ color: 0xffffff, roughness: t === SHAPE.height_field ? 0.95 : 0.75, metalness: 0.05, flatShading: t === SHAPE.hull || t === SHAPE.mesh });
        if (t === SHAPE.plane) { material.polygonOffset = true; material.polygonOffsetFactor = 1; material.polygonOffsetUnits = 1; }
        const mesh = new THREE.InstancedMesh(piece.geometry, material, 16);
        mesh.userData = { shape: i, part: piece.part, partMatrix: piece.matrix, slots: [] };
        // The ground receives shadows; a terrain casting them on itself would speckle.
        mesh.castShadow = t !== SHAPE.plane && t !== SHAPE.height_field;
        mesh.receiveShadow = true;
        mesh.frustumCulled = false;
        mesh.count = 0;
        this.meshes.push(mesh);
        this.world.add(mesh);
      }
      if (s.type === SHAPE.plane && !gridDone) {
        gridDone = true;
        const p = s.params, n = new THREE.Vector3(p[0], p[1], p[2]).normalize();
        const cells = Math.min(100, Math.round(this.extent));
        const grid = new THREE.GridHelper(this.extent, cells, 0x5a6470, 0x3e4650);
        grid.quaternion.setFromUnitVectors(new THREE.Vector3(0, 1, 0), n);
        grid.position.copy(n).multiplyScalar(p[3] + 0.002);
        this.world.add(grid);
      }
    });
    if (!model.shapes.some((s) => s.type === SHAPE.plane)) {
      const grid = new THREE.GridHelper(this.extent, Math.min(100, Math.round(this.extent)), 0x5a6470, 0x3e4650);
      grid.rotateX(Math.PI / 2);
      // Under any level geometry, so a flat terrain hides it rather than flickers with it.
      grid.position.z = ground.isEmpty() ? box.min.z : lowest - 0.01;
      this.world.add(grid);
    }
    const sc = this.sun.shadow.camera;
    sc.left = sc.bottom = -radius * 1.5;
    sc.right = sc.top = radius * 1.5;
    sc.near = 0.1;
    sc.far = radius * 8;
    sc.updateProjectionMatrix();
    this.sun.position.copy(centre).add(new THREE.Vector3(0.5, 0.3, 1).normalize().multiplyScalar(radius * 3));
    this.sun.target.position.copy(centre);
    if (!keepCamera) {
      this.controls.target.copy(centre);
      this.camera.position.copy(centre).add(new THREE.Vector3(1.2, -1.6, 1.3).normalize().multiplyScalar(radius * (radius > 20 ? 1.5 : 3)));
      this.camera.near = radius / 200;
      this.camera.far = radius * 50;
      this.camera.updateProjectionMatrix();
    }
    this.draw(frame);
  }

  /// Puts every present body of `frame` into its shape's mesh.
  draw(frame) {
    const m = this.model;
    if (!m) return;
    this.frame = frame;
    const counts = new Array(m.shapes.length).fill(0);
    for (let s = 0; s < frame.flags.length; ++s) if (frame.flags[s] & F_PRESENT) counts[m.bodies[s].shape]++;
    this.meshes.forEach((mesh, i) => {
      const need = counts[mesh.userData.shape];
      if (need > mesh.instanceMatrix.count) {
        const bigger = new THREE.InstancedMesh(mesh.geometry, mesh.material, Math.max(need, 2 * mesh.instanceMatrix.count));
        Object.assign(bigger, { userData: mesh.userData, castShadow: mesh.castShadow, receiveShadow: mesh.receiveShadow, frustumCulled: false });
        this.world.remove(mesh);
        this.world.add(bigger);
        this.meshes[i] = bigger;
      }
      this.meshes[i].count = 0;
      this.meshes[i].userData.slots.length = 0;
    });
    const meshesOf = m.shapes.map(() => []); // a shape's meshes: one, or a compound's one a part
    for (const mesh of this.meshes) meshesOf[mesh.userData.shape].push(mesh);
    const mat = new THREE.Matrix4(), p = new THREE.Vector3(), q = new THREE.Quaternion(), sc = new THREE.Vector3(), c = new THREE.Color();
    const d = frame.data;
    for (let s = 0; s < frame.flags.length; ++s) {
      const f = frame.flags[s];
      if (!(f & F_PRESENT)) continue;
      const b = m.bodies[s];
      const o = s * FLOATS;
      p.set(d[o], d[o + 1], d[o + 2]);
      q.set(d[o + 4], d[o + 5], d[o + 6], d[o + 3]); // ours w x y z, three's x y z w
      sc.setScalar(b.scale);
      mat.compose(p, q, sc);
      if (s === this.selectedSlot) c.copy(SELECTED_COLOUR);
      else if (f & F_STATIC || b.static) c.copy(STATIC_COLOUR);
      else if (f & F_AWAKE && this.islandOf && this.islandOf.has(b.id)) islandColour(this.islandOf.get(b.id), c);
      else if (f & F_AWAKE) c.setHex(COLOURS[m.shapes[b.shape].type] ?? 0xcccccc);
      else c.copy(ASLEEP_COLOUR);
      if (isStaticShape(m.shapes[b.shape].type)) c.setHex(COLOURS[m.shapes[b.shape].type]);
      for (const mesh of meshesOf[b.shape]) {
        const k = mesh.count++;
        mesh.setMatrixAt(k, mat);
        mesh.setColorAt(k, c);
        mesh.userData.slots[k] = s;
      }
    }
    for (const mesh of this.meshes) {
      mesh.instanceMatrix.needsUpdate = true;
      if (mesh.instanceColor) mesh.instanceColor.needsUpdate = true;
      mesh.computeBoundingSphere();
    }
  }

  render() {
    this.controls.update();
    this.gl.render(this.scene, this.camera);
    this.frames++;
  }

  /// The body (slot) and point under a canvas pixel; the ground (planes, meshes, height fields)
  /// counts only with `withGround`.
  pick(clientX, clientY, withGround = false) {
    const r = this.canvas.getBoundingClientRect();
    const ndc = new THREE.Vector2(((clientX - r.left) / r.width) * 2 - 1, -((clientY - r.top) / r.height) * 2 + 1);
    const ray = new THREE.Raycaster();
    ray.setFromCamera(ndc, this.camera);
    const targets = this.meshes.filter((mesh) => withGround || !isStaticShape(this.model.shapes[mesh.userData.shape].type));
    const hit = ray.intersectObjects(targets, false)[0];
    if (!hit) return { ray: ray.ray, slot: -1 };
    return { ray: ray.ray, slot: hit.object.userData.slots[hit.instanceId], point: hit.point, normal: hit.face ? hit.face.normal.clone().transformDirection(hit.object.matrixWorld) : null, distance: hit.distance };
  }

  /// A world point's canvas pixel (client coordinates).
  toScreen(v) {
    const r = this.canvas.getBoundingClientRect();
    const p = new THREE.Vector3().fromArray(v).project(this.camera);
    return { x: r.left + (p.x + 1) / 2 * r.width, y: r.top + (1 - p.y) / 2 * r.height };
  }

  /// The triangles drawn for each mesh and height field, in its body frame (three vertices each),
  /// with its shape index, type and instance count.
  surfaces() {
    return this.meshes.filter((mesh) => isSurface(this.model.shapes[mesh.userData.shape].type)).map((mesh) => {
      const g = mesh.geometry, pos = g.attributes.position.array, index = g.index ? g.index.array : null;
      const triangles = [];
      for (let t = 0, n = index ? index.length / 3 : pos.length / 9; t < n; ++t) {
        const tri = [];
        for (let k = 0; k < 3; ++k) {
          const i = index ? index[3 * t + k] : 3 * t + k;
          tri.push([pos[3 * i], pos[3 * i + 1], pos[3 * i + 2]]);
        }
        triangles.push(tri);
      }
      return { shape: mesh.userData.shape, type: this.model.shapes[mesh.userData.shape].type, instances: mesh.count, triangles };
    });
  }

  /// The parts drawn for one slot (a compound body), in part order: each its shape type and its
  /// world pose (position, orientation w x y z, scale), read back from its instance matrix and
  /// the part's placement in its mesh.
  parts(slot) {
    const out = [];
    for (const mesh of this.meshes) {
      const k = mesh.userData.slots.indexOf(slot);
      if (mesh.userData.part < 0 || k < 0 || k >= mesh.count) continue;
      const mat = new THREE.Matrix4();
      mesh.getMatrixAt(k, mat);
      mat.multiply(mesh.userData.partMatrix);
      const p = new THREE.Vector3(), q = new THREE.Quaternion(), sc = new THREE.Vector3();
      mat.decompose(p, q, sc);
      const part = this.model.shapes[mesh.userData.shape].parts[mesh.userData.part];
      out[mesh.userData.part] = { type: part.record.type, position: p.toArray(), orientation: [q.w, q.x, q.y, q.z], scale: sc.x };
    }
    return out;
  }

  /// Instances drawn (a compound body is one a part), and the drawn position of one slot (read
  /// back from its instance matrix).
  instanceCount() { return this.meshes.reduce((n, m) => n + m.count, 0); }
  instancePosition(slot) {
    for (const mesh of this.meshes) {
      const k = mesh.userData.slots.indexOf(slot);
      if (k >= 0 && k < mesh.count) {
        const mat = new THREE.Matrix4();
        mesh.getMatrixAt(k, mat);
        return new THREE.Vector3().setFromMatrixPosition(mat).toArray();
      }
    }
    return null;
  }
}
