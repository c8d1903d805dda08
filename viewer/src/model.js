// What the viewer knows of a world: the shape dictionary, the bodies (a slot each, stable for
// the epoch), the newest state, and a ring of the last states received (or every frame of a
// trajectory file) for the timeline. One frame stores, per slot, 13 floats (position,
// orientation w x y z, velocity, angular velocity) and flags, and the id-to-slot map of its
// epoch (a recording holds several epochs, one a reset, in one model).

export const FLOATS = 13;
export const F_AWAKE = 1, F_STATIC = 2, F_PRESENT = 4;

export class Model {
  constructor({ shapes, name = '', dt = 0, source = 'live', capacity = 600 }) {
    this.shapes = shapes; // [{type, params, vertices?, face_start?, face_vertices?}]
    this.name = name;
    this.dt = dt;
    this.source = source;
    this.bodies = []; // slot -> {id, shape, scale, static, label}
    this.slotOf = new Map(); // id -> slot
    this.capacity = capacity;
    this.frames = []; // ring (live) or every frame (file)
    this.head = 0; // ring index of the oldest frame once full
    this.live = null; // newest frame (live)
  }

  /// The body's slot in the id map `slots` (the current epoch's by default), added if new.
  addBody({ id, shape, scale, flags = 0, label }, slots = this.slotOf) {
    let slot = slots.get(id);
    if (slot === undefined) {
      slot = this.bodies.length;
      slots.set(id, slot);
      this.bodies.push({ id, shape, scale, static: (flags & F_STATIC) !== 0, label: label ?? String(id) });
    } else {
      Object.assign(this.bodies[slot], { shape, scale, static: (flags & F_STATIC) !== 0 });
    }
    return slot;
  }

  /// A frame for `count` slots (copied from `from` when given, grown to the current body count).
  newFrame(step, from = null) {
    const n = this.bodies.length;
    const f = { step, t: step * this.dt, stats: null, data: new Float32Array(n * FLOATS), flags: new Uint8Array(n), slotOf: from ? from.slotOf : this.slotOf };
    if (from) {
      f.data.set(from.data.subarray(0, Math.min(from.data.length, f.data.length)));
      f.flags.set(from.flags.subarray(0, Math.min(from.flags.length, n)));
    }
    return f;
  }

  static setBody(frame, slot, b, flags) {
    const d = frame.data, o = slot * FLOATS;
    d.set(b.position, o);
    d.set(b.orientation, o + 3);
    d.set(b.velocity, o + 7);
    d.set(b.angular_velocity, o + 10);
    if (flags !== undefined) frame.flags[slot] = flags;
  }

  push(frame) {
    if (this.frames.length < this.capacity) this.frames.push(frame);
    else {
      this.frames[this.head] = frame;
      this.head = (this.head + 1) % this.capacity;
    }
  }

  /// Frames in time order: i = 0 is the oldest kept.
  frameCount() { return this.frames.length; }
  frameAt(i) { return this.frames[(this.head + i) % this.frames.length]; }
  timeAt(i) { return this.frameAt(i).t; }

  /// One body's state in a frame, or null if it is not there.
  bodyState(frame, slot) {
    if (!frame || slot >= frame.flags.length || !(frame.flags[slot] & F_PRESENT)) return null;
    const d = frame.data, o = slot * FLOATS;
    const b = this.bodies[slot];
    return {
      id: b.id, label: b.label, shape: b.shape, shape_type: this.shapes[b.shape]?.type, scale: b.scale, static: b.static,
      awake: (frame.flags[slot] & F_AWAKE) !== 0,
      position: Array.from(d.subarray(o, o + 3)), orientation: Array.from(d.subarray(o + 3, o + 7)),
      velocity: Array.from(d.subarray(o + 7, o + 10)), angular_velocity: Array.from(d.subarray(o + 10, o + 13)),
    };
  }
}

/// The frame of a join: its bodies, in an id map of its own when the model already holds bodies
/// (a recording's reset starts a new epoch whose ids may name other bodies). A body of the same
/// id, shape, scale and kind as before keeps its slot: a reset brings the same bodies back.
export function joinFrame(m, join) {
  if (m.bodies.length) {
    const before = m.slotOf;
    m.slotOf = new Map();
    for (const b of join.bodies) {
      const s = before.get(b.id), o = s === undefined ? null : m.bodies[s];
      if (o && o.shape === b.shape && o.scale === b.scale && o.static === ((b.flags & F_STATIC) !== 0)) m.slotOf.set(b.id, s);
    }
  }
  for (const b of join.bodies) m.addBody(b);
  const f = m.newFrame(join.step);
  for (const b of join.bodies) Model.setBody(f, m.slotOf.get(b.id), b, F_PRESENT | (b.flags & (F_AWAKE | F_STATIC)));
  return f;
}

/// The live model's reaction to a join: a fresh model and its first frame.
export function modelFromJoin(join, capacity) {
  const m = new Model({ shapes: join.shapes, name: join.name, dt: join.dt, source: 'live', capacity });
  const f = joinFrame(m, join);
  m.live = f;
  m.push(f);
  return m;
}

/// The next frame from a tick: the previous one with the entered, moved and gone bodies applied.
/// A moved body is awake (the server resends only bodies whose state changed); bodies not moved
/// keep their last state and are taken as asleep once the tick's sleeping count says some are.
/// It depends on `prev` and the tick alone, so a recording rebuilds any frame from the one before.
export function nextFrame(m, prev, tick) {
  for (const b of tick.entered) m.addBody(b, prev.slotOf);
  const f = m.newFrame(tick.step, prev);
  const slotOf = f.slotOf;
  f.stats = tick.stats;
  f.paused = (tick.flags & 2) !== 0;
  const moved = new Uint8Array(m.bodies.length);
  for (const b of tick.entered) {
    const s = slotOf.get(b.id);
    Model.setBody(f, s, b, F_PRESENT | (b.flags & (F_AWAKE | F_STATIC)));
    if (b.flags & F_AWAKE) moved[s] = 1;
  }
  for (const b of tick.moved) {
    const s = slotOf.get(b.id);
    if (s === undefined) continue;
    Model.setBody(f, s, b);
    f.flags[s] |= F_PRESENT | F_AWAKE;
    moved[s] = 1;
  }
  for (const id of tick.gone) {
    const s = slotOf.get(id);
    if (s !== undefined) f.flags[s] = 0;
  }
  // Not resent: asleep (its state's bits did not change), unless the world is paused, when
  // nothing moves and the previous awake flags stand.
  if (!f.paused) for (let s = 0; s < f.flags.length; ++s) if (!moved[s] && !(f.flags[s] & F_STATIC)) f.flags[s] &= ~F_AWAKE;
  return f;
}

/// The live model's reaction to a tick: the next frame, kept as the newest.
export function applyTick(m, tick) {
  const f = nextFrame(m, m.live, tick);
  m.live = f;
  m.push(f);
  return f;
}
