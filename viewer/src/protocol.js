// The binary protocol of `cellphys serve` (docs/protocol.md): decoding the server's messages and
// encoding the client's. Little-endian throughout; offsets are the documented ones.

export const VERSION = 1;
/// The protocol revision this page reads, said to the server when connecting (/ws?...&revision=4):
/// a server refuses, with an error naming it, a client that reads less than its world's join needs.
export const REVISION = 4;
export const T = {
  join: 1, tick: 2, ack: 3, error: 4, status: 5, debug: 6, stages: 7, subscribe: 32,
  spawn: 33, remove: 34, impulse: 35, drag_start: 36, drag_move: 37, drag_release: 38,
  pause: 39, resume: 40, step_once: 41, reset: 42, set_speed: 43,
};
/// The first revision whose server takes set_speed (the join's revision says what a server takes).
export const SET_SPEED_REVISION = 5;
export const SHAPE = { sphere: 0, capsule: 1, box: 2, hull: 3, plane: 4, mesh: 5, height_field: 6, compound: 7 };
/// The shapes a compound's parts are.
export const isConvex = (type) => type >= SHAPE.sphere && type <= SHAPE.hull;
/// Triangle surfaces: static level geometry, sent (and drawn) as a hull is, their triangles the faces.
export const isSurface = (type) => type === SHAPE.mesh || type === SHAPE.height_field;
/// Shapes only a static body has: the ground and level geometry, never spawned or dragged.
export const isStaticShape = (type) => type === SHAPE.plane || isSurface(type);
export const BODY_AWAKE = 1, BODY_STATIC = 2, BODY_UNBOUNDED = 4;
export const TICK_QUANTISED = 1, TICK_PAUSED = 2;
export const WORLD_STATE = ['running', 'paused', 'failed'];
export const ERROR_CODE = ['', 'malformed', 'invalid', 'unauthorized', 'rate_limited', 'world_failed'];

const BODY_FULL = 68, BODY_MOVED = 56, BODY_MOVED_Q = 28, SHAPE_RECORD = 48, COMPOUND_PART = 36;

export class ProtocolError extends Error {}

function text(dv, at, bytes) {
  return new TextDecoder().decode(new Uint8Array(dv.buffer, dv.byteOffset + at, bytes)).replace(/\0+$/, '');
}

function need(dv, end, what) {
  if (end > dv.byteLength) throw new ProtocolError(`${what}: message of ${dv.byteLength} bytes ends before byte ${end}`);
}

function f3(dv, at) { return [dv.getFloat32(at, true), dv.getFloat32(at + 4, true), dv.getFloat32(at + 8, true)]; }
function f4(dv, at) { return [dv.getFloat32(at, true), dv.getFloat32(at + 4, true), dv.getFloat32(at + 8, true), dv.getFloat32(at + 12, true)]; }

function bodyFull(dv, at) {
  return {
    id: dv.getUint32(at, true), shape: dv.getUint32(at + 4, true), scale: dv.getFloat32(at + 8, true),
    flags: dv.getUint32(at + 12, true), position: f3(dv, at + 16), orientation: f4(dv, at + 28),
    velocity: f3(dv, at + 44), angular_velocity: f3(dv, at + 56),
  };
}

function bodyMoved(dv, at) {
  return { id: dv.getUint32(at, true), position: f3(dv, at + 4), orientation: f4(dv, at + 16), velocity: f3(dv, at + 32), angular_velocity: f3(dv, at + 44) };
}

const ORIENT_LEVELS = 1023;
/// The smallest-three quaternion of BodyMovedQ: the largest component rebuilt, then renormalised.
export function decodeOrientation(bits) {
  const largest = bits >>> 30;
  const c = [0, 0, 0, 0];
  let sum = 0;
  for (let i = 0, k = 0; i < 4; ++i) {
    if (i === largest) continue;
    const level = (bits >>> (10 * k)) & 1023;
    c[i] = (level / ORIENT_LEVELS - 0.5) * 2 * Math.SQRT1_2;
    sum += c[i] * c[i];
    ++k;
  }
  c[largest] = Math.sqrt(Math.max(0, 1 - sum));
  const n = Math.hypot(c[0], c[1], c[2], c[3]);
  return c.map((v) => v / n);
}

function bodyMovedQ(dv, at, q) {
  const i16 = (o) => [dv.getInt16(at + o, true), dv.getInt16(at + o + 2, true), dv.getInt16(at + o + 4, true)];
  const p = i16(8), v = i16(14), w = i16(20);
  return {
    id: dv.getUint32(at, true), orientation: decodeOrientation(dv.getUint32(at + 4, true)),
    position: p.map((x, k) => q.origin[k] + q.position_step * x),
    velocity: v.map((x) => q.velocity_step * x), angular_velocity: w.map((x) => q.angular_step * x),
  };
}

function shapeDictionary(dv, at, count) {
  const shapes = [];
  for (let s = 0; s < count; ++s) {
    need(dv, at + SHAPE_RECORD, `join.shapes[${s}]`);
    const rec = {
      type: dv.getUint32(at, true), num_vertices: dv.getUint32(at + 4, true), num_faces: dv.getUint32(at + 8, true),
      num_face_vertices: dv.getUint32(at + 12, true), params: [],
    };
    for (let k = 0; k < 8; ++k) rec.params.push(dv.getFloat32(at + 16 + 4 * k, true));
    at += SHAPE_RECORD;
    if (rec.type === SHAPE.compound) {
      // Revision 4: num_vertices parts, each an earlier (convex) shape at a pose in the compound's
      // frame; `record` is that shape's own record, so a part is drawn and boxed as one.
      const n = rec.num_vertices;
      need(dv, at + COMPOUND_PART * n, `join.shapes[${s}] parts`);
      rec.parts = [];
      for (let k = 0; k < n; ++k, at += COMPOUND_PART) {
        const shape = dv.getUint32(at, true);
        if (shape >= s || !isConvex(shapes[shape].type))
          throw new ProtocolError(`join.shapes[${s}].parts[${k}]: shape ${shape} is not an earlier convex shape`);
        rec.parts.push({ shape, record: shapes[shape], position: f3(dv, at + 4), orientation: f4(dv, at + 16), scale: dv.getFloat32(at + 32, true) });
      }
    } else if (rec.type === SHAPE.hull || isSurface(rec.type)) {
      const bytes = 12 * rec.num_vertices + 4 * (rec.num_faces + 1) + 4 * rec.num_face_vertices;
      need(dv, at + bytes, `join.shapes[${s}] vertex and face data`);
      rec.vertices = new Float32Array(dv.buffer.slice(dv.byteOffset + at, dv.byteOffset + at + 12 * rec.num_vertices));
      at += 12 * rec.num_vertices;
      rec.face_start = new Uint32Array(dv.buffer.slice(dv.byteOffset + at, dv.byteOffset + at + 4 * (rec.num_faces + 1)));
      at += 4 * (rec.num_faces + 1);
      rec.face_vertices = new Uint32Array(dv.buffer.slice(dv.byteOffset + at, dv.byteOffset + at + 4 * rec.num_face_vertices));
      at += 4 * rec.num_face_vertices;
    }
    shapes.push(rec);
  }
  return { shapes, at };
}

/// One server message (an ArrayBuffer, or a view of one: a recording's frame) as a plain object
/// with its `type` name.
export function decode(buffer) {
  const dv = buffer instanceof DataView ? buffer
    : ArrayBuffer.isView(buffer) ? new DataView(buffer.buffer, buffer.byteOffset, buffer.byteLength) : new DataView(buffer);
  need(dv, 8, 'header');
  const length = dv.getUint32(0, true), type = dv.getUint16(4, true), version = dv.getUint16(6, true);
  if (length !== dv.byteLength) throw new ProtocolError(`header.length ${length} is not the message's ${dv.byteLength} bytes`);
  if (version !== VERSION) throw new ProtocolError(`header.version ${version} is not ${VERSION}`);
  switch (type) {
    case T.join: {
      need(dv, 48, 'join');
      const m = {
        type: 'join', epoch: dv.getUint32(8, true), flags: dv.getUint32(12, true), step: Number(dv.getBigUint64(16, true)),
        dt: dv.getFloat32(24, true), tick_hz: dv.getFloat32(28, true), revision: dv.getUint32(44, true),
      };
      const numShapes = dv.getUint32(32, true), numBodies = dv.getUint32(36, true), nameBytes = dv.getUint32(40, true);
      need(dv, 48 + nameBytes, 'join.name');
      m.name = text(dv, 48, nameBytes);
      const d = shapeDictionary(dv, 48 + nameBytes, numShapes);
      m.shapes = d.shapes;
      need(dv, d.at + BODY_FULL * numBodies, 'join.bodies');
      m.bodies = [];
      for (let i = 0; i < numBodies; ++i) m.bodies.push(bodyFull(dv, d.at + BODY_FULL * i));
      return m;
    }
    case T.tick: {
      need(dv, 96, 'tick');
      const m = {
        type: 'tick', step: Number(dv.getBigUint64(8, true)), epoch: dv.getUint32(16, true), flags: dv.getUint32(20, true),
        skipped: dv.getUint32(24, true), bytes: dv.byteLength,
        stats: {
          step_ms: dv.getFloat32(40, true), active_bodies: dv.getUint32(44, true), sleeping_bodies: dv.getUint32(48, true),
          contacts: dv.getUint32(52, true), islands: dv.getUint32(56, true), solver_iterations: dv.getUint32(60, true),
          failed_islands: dv.getUint32(64, true), step_halvings: dv.getUint32(68, true),
        },
      };
      const quant = { origin: f3(dv, 72), position_step: dv.getFloat32(84, true), velocity_step: dv.getFloat32(88, true), angular_step: dv.getFloat32(92, true) };
      const ne = dv.getUint32(28, true), nm = dv.getUint32(32, true), ng = dv.getUint32(36, true);
      const q = (m.flags & TICK_QUANTISED) !== 0;
      const movedBytes = q ? BODY_MOVED_Q : BODY_MOVED;
      need(dv, 96 + BODY_FULL * ne + movedBytes * nm + 4 * ng, 'tick bodies');
      let at = 96;
      m.entered = [];
      for (let i = 0; i < ne; ++i, at += BODY_FULL) m.entered.push(bodyFull(dv, at));
      m.moved = [];
      for (let i = 0; i < nm; ++i, at += movedBytes) m.moved.push(q ? bodyMovedQ(dv, at, quant) : bodyMoved(dv, at));
      m.gone = [];
      for (let i = 0; i < ng; ++i, at += 4) m.gone.push(dv.getUint32(at, true));
      return m;
    }
    case T.ack:
      need(dv, 32, 'ack');
      return { type: 'ack', seq: dv.getUint32(8, true), command_type: dv.getUint16(12, true), step: Number(dv.getBigUint64(16, true)), result: dv.getUint32(24, true) };
    case T.error: {
      need(dv, 24, 'error');
      const fb = dv.getUint16(16, true), rb = dv.getUint16(18, true);
      need(dv, 24 + fb + rb, 'error text');
      return {
        type: 'error', seq: dv.getUint32(8, true), command_type: dv.getUint16(12, true), code: dv.getUint16(14, true),
        code_name: ERROR_CODE[dv.getUint16(14, true)] || 'unknown', field: text(dv, 24, fb), reason: text(dv, 24 + fb, rb),
      };
    }
    case T.status: {
      need(dv, 24, 'status');
      const state = dv.getUint32(8, true), tb = dv.getUint32(12, true);
      need(dv, 24 + tb, 'status text');
      return { type: 'status', state: WORLD_STATE[state] || String(state), step: Number(dv.getBigUint64(16, true)), text: text(dv, 24, tb) };
    }
    case T.debug: {  // revision 2
      need(dv, 32, 'debug');
      const nb = dv.getUint32(20, true), nc = dv.getUint32(24, true), ncut = dv.getUint32(28, true); // ncut: revision 3 (0 before)
      need(dv, 32 + 16 * nb + 40 * nc + 32 * ncut, 'debug records');
      const m = { type: 'debug', step: Number(dv.getBigUint64(8, true)), epoch: dv.getUint32(16, true), bodies: [], contacts: [], cuts: [] };
      let at = 32;
      for (let i = 0; i < nb; ++i, at += 16) {
        const island = dv.getUint32(at + 4, true);
        m.bodies.push({ id: dv.getUint32(at, true), island: island === 0xFFFFFFFF ? null : island, mass: dv.getFloat32(at + 8, true), decoupled: (dv.getUint32(at + 12, true) & 1) !== 0 });
      }
      for (let i = 0; i < nc; ++i, at += 40)
        m.contacts.push({ a: dv.getUint32(at, true), b: dv.getUint32(at + 4, true), point: f3(dv, at + 8), normal: f3(dv, at + 20), depth: dv.getFloat32(at + 32, true), force: dv.getFloat32(at + 36, true) });
      for (let i = 0; i < ncut; ++i, at += 32) {
        const force = dv.getUint32(at + 8, true);
        m.cuts.push({ a: dv.getUint32(at, true), b: dv.getUint32(at + 4, true), force: force === 0xFFFFFFFF ? null : force, island: dv.getUint32(at + 12, true), point: f3(dv, at + 16) });
      }
      return m;
    }
    case T.stages: { // revision 3
      need(dv, 32, 'stages');
      const n = dv.getUint32(20, true), nameBytes = dv.getUint32(24, true);
      need(dv, 32 + 4 * n + nameBytes, 'stages records');
      const names = text(dv, 32 + 4 * n, nameBytes).split('\0');
      const m = { type: 'stages', step: Number(dv.getBigUint64(8, true)), epoch: dv.getUint32(16, true), stages: [] };
      for (let k = 0; k < n; ++k) m.stages.push({ name: names[k] ?? `stage ${k}`, ms: dv.getFloat32(32 + 4 * k, true) });
      return m;
    }
    default:
      throw new ProtocolError(`header.type ${type} is not a server message`);
  }
}

// ---- client messages ----

function message(type, bytes) {
  const dv = new DataView(new ArrayBuffer(bytes));
  dv.setUint32(0, bytes, true);
  dv.setUint16(4, type, true);
  dv.setUint16(6, VERSION, true);
  return dv;
}
function putF(dv, at, values) { values.forEach((v, k) => dv.setFloat32(at + 4 * k, v, true)); }

export function subscribe({ quantised = false, region = null, debug = false, stages = false } = {}) {
  const dv = message(T.subscribe, 40);
  dv.setUint32(8, (quantised ? 1 : 0) | (region ? 2 : 0) | (debug ? 4 : 0) | (stages ? 8 : 0), true);
  if (region) { putF(dv, 16, region.min); putF(dv, 28, region.max); }
  return dv.buffer;
}

/// pause, resume, step_once, reset: the header, seq, reserved.
export function simple(type, seq) {
  const dv = message(type, 16);
  dv.setUint32(8, seq, true);
  return dv.buffer;
}

/// set_speed (revision 5): the world's pace against real time, 0.05 to 8.
export function setSpeed(seq, speed) {
  const dv = message(T.set_speed, 16);
  dv.setUint32(8, seq, true);
  dv.setFloat32(12, speed, true);
  return dv.buffer;
}

export function spawn(seq, { shape, scale = 1, mass = 1, friction = 0.5, position, orientation = [1, 0, 0, 0], velocity = [0, 0, 0], angular_velocity = [0, 0, 0] }) {
  const dv = message(T.spawn, 80);
  dv.setUint32(8, seq, true);
  dv.setUint32(12, shape, true);
  putF(dv, 16, [scale, mass, friction, ...position, ...orientation, ...velocity, ...angular_velocity]);
  return dv.buffer;
}

export function dragStart(seq, body, point, target, stiffness = 0, damping = 0) {
  const dv = message(T.drag_start, 48);
  dv.setUint32(8, seq, true);
  dv.setUint32(12, body, true);
  putF(dv, 16, [...point, ...target, stiffness, damping]);
  return dv.buffer;
}

export function dragMove(seq, drag, target) {
  const dv = message(T.drag_move, 28);
  dv.setUint32(8, seq, true);
  dv.setUint32(12, drag, true);
  putF(dv, 16, target);
  return dv.buffer;
}

export function dragRelease(seq, drag) {
  const dv = message(T.drag_release, 16);
  dv.setUint32(8, seq, true);
  dv.setUint32(12, drag, true);
  return dv.buffer;
}
