// A `cellphys serve --record` file (server/recording.h) in the page: its records checked as
// `cellphys replay` checks them (length and checksum; a damaged or cut tail ends the recording
// there, with a warning), and its frames — the join and tick messages the server sent, each with
// its stages message and, recorded with `--record-debug on`, its debug message — decoded by the
// live decoders (protocol.js) into a Model the timeline scrubs over. Keeping every frame
// of a long recording would take 52 bytes a body a tick, so one in KEY_EVERY is kept and the
// others are rebuilt from the one before, as the live page built them.
import * as P from './protocol.js';
import { Model, joinFrame, nextFrame } from './model.js';

export class RecordingError extends Error {}

const MAGIC = 'CELLREC1';
const VERSION = 2; // the newest this page reads
const FRAMES = 1; // header flag: frames recorded
const DEBUG = 2; // header flag: and each frame's debug message
const REC = { world: 1, command: 2, hash: 3, end: 4, frame: 5 };
const KEY_EVERY = 64;

/// True when the bytes open as a recording.
export function isRecording(bytes) {
  return bytes.length >= 8 && String.fromCharCode(...bytes.subarray(0, 8)) === MAGIC;
}

// ---- spu::checksum (runtime/spu/island_image.cpp), in 32-bit halves ----

/// (hi, lo) times the FNV prime 2^40 + 0x1B3, modulo 2^64.
function mulPrime(h, i) {
  const lo = h[i + 1], a = lo * 0x1b3;
  h[i] = (h[i] * 0x1b3 + Math.floor(a / 4294967296) + lo * 256) >>> 0;
  h[i + 1] = a >>> 0;
}

export function checksum(bytes, seed = 0x811c9dc5) {
  const h = [0xcbf29ce4, 0x84222325, 0x84222325, 0xcbf29ce4, 0x9e3779b9, 0x7f4a7c15, 0xc2b2ae3d, 0x27d4eb4f]; // hi, lo a lane
  for (let k = 0; k < 4; ++k) h[2 * k + 1] = (h[2 * k + 1] ^ seed) >>> 0;
  const dv = new DataView(bytes.buffer, bytes.byteOffset, bytes.byteLength);
  const n = bytes.length;
  let i = 0;
  for (; i + 32 <= n; i += 32)
    for (let k = 0; k < 4; ++k) {
      h[2 * k + 1] = (h[2 * k + 1] ^ dv.getUint32(i + 8 * k, true)) >>> 0;
      h[2 * k] = (h[2 * k] ^ dv.getUint32(i + 8 * k + 4, true)) >>> 0;
      mulPrime(h, 2 * k);
    }
  for (; i < n; ++i) {
    h[1] = (h[1] ^ bytes[i]) >>> 0;
    mulPrime(h, 0);
  }
  const M = (1n << 64n) - 1n;
  const lane = (k) => (BigInt(h[2 * k]) << 32n) | BigInt(h[2 * k + 1]);
  let x = lane(0) ^ ((lane(1) * 3n) & M) ^ ((lane(2) * 5n) & M) ^ ((lane(3) * 7n) & M);
  x ^= x >> 29n;
  x = (x * 0xbf58476d1ce4e5b9n) & M;
  x ^= x >> 32n;
  return Number(x & 0xffffffffn);
}

function recordChecksum(header, payload) {
  const h = new Uint8Array(header); // a copy, its checksum field zero
  h.fill(0, 8, 12);
  const c = checksum(h);
  return payload.length ? checksum(payload, c) : c;
}

// ---- the file ----

/// The model of a recording: one entry a frame record (its step, message bytes and tick
/// statistics), frames rebuilt on demand from the nearest kept one.
export class RecordingModel extends Model {
  constructor(opts) {
    super({ ...opts, source: 'recording', capacity: Infinity });
    this.entries = [];
    this.cache = null; // the last frame rebuilt, and its index
  }

  frameCount() { return this.entries.length; }
  /// The debug message recorded with frame i (`--record-debug on`), or null.
  debugAt(i) {
    const b = this.entries[i]?.debugBytes;
    return b ? P.decode(b) : null;
  }
  stepAt(i) { return this.entries[i].step; }
  timeAt(i) { return this.entries[i].step * this.dt; }

  frameAt(i) {
    const e = this.entries;
    let k = i;
    while (!e[k].key) --k;
    let at = k, f = e[k].key;
    if (this.cache && this.cache.index <= i && this.cache.index > k) { at = this.cache.index; f = this.cache.frame; }
    for (let j = at + 1; j <= i; ++j) f = nextFrame(this, f, P.decode(e[j].bytes));
    this.cache = { index: i, frame: f };
    return f;
  }
}

/// A Model from a recording's bytes; `name` names the file in errors. The result's `warning`
/// says why reading stopped early (a server killed mid-record), if it did.
export function readRecording(bytes, name) {
  if (!isRecording(bytes) || bytes.length < 16) throw new RecordingError(`${name}: not a cellphys recording (no ${MAGIC} header)`);
  const dv = new DataView(bytes.buffer, bytes.byteOffset, bytes.byteLength);
  const version = dv.getUint32(8, true), flags = dv.getUint32(12, true);
  if (version < 1 || version > VERSION)
    throw new RecordingError(`${name}: recording version ${version} is not one this viewer reads (1 to ${VERSION})`);
  if (version < 2) throw new RecordingError(`${name}: a version-1 recording holds no frames to draw (\`cellphys replay\` re-runs it; record again with this cellphys to watch it here)`);
  if (!(flags & FRAMES)) throw new RecordingError(`${name}: recorded with --record-frames off: no frames to draw (\`cellphys replay\` re-runs it)`);
  let world = null, m = null, prev = null, warning = '', commands = 0, ended = false;
  let at = 16, count = 0;
  while (at < bytes.length) {
    const where = `record ${count} (byte ${at})`;
    if (bytes.length - at < 16) { warning = `${where} is cut short in its header`; break; }
    const type = dv.getUint32(at, true), size = dv.getUint32(at + 4, true), sum = dv.getUint32(at + 8, true);
    if (size > bytes.length - at - 16) { warning = `${where} is cut short: it says ${size} bytes`; break; }
    const payload = bytes.subarray(at + 16, at + 16 + size);
    if (recordChecksum(bytes.subarray(at, at + 16), payload) !== sum) { warning = `${where} is damaged (checksum)`; break; }
    if (world === null) {
      if (type !== REC.world || size < 4 || dv.getUint32(at + 16, true) > size - 4)
        throw new RecordingError(`${name}: ${where} is not the world record a recording opens with`);
      world = new TextDecoder().decode(payload.subarray(4, 4 + dv.getUint32(at + 16, true)));
    } else if (type === REC.frame) {
      if (size < 16) { warning = `${where} is too short for a frame`; break; }
      const step = Number(dv.getBigUint64(at + 16, true));
      const msg = payload.subarray(8);
      let decoded;
      try {
        decoded = P.decode(msg);
      } catch (e) {
        if (!(e instanceof P.ProtocolError)) throw e;
        warning = `${where}: its frame is not a server message: ${e.message}`;
        break;
      }
      if (decoded.type === 'join') {
        if (!m) m = new RecordingModel({ shapes: decoded.shapes, name: decoded.name || world, dt: decoded.dt });
        m.join = decoded;
        prev = joinFrame(m, decoded);
        m.entries.push({ step, bytes: msg, key: prev, stats: null, epoch: decoded.epoch });
      } else if (decoded.type === 'tick') {
        if (!prev) throw new RecordingError(`${name}: ${where}: a tick before any join`);
        prev = nextFrame(m, prev, decoded);
        m.entries.push({ step, bytes: msg, key: m.entries.length % KEY_EVERY === 0 ? prev : null, stats: decoded.stats, epoch: decoded.epoch });
      } else if (decoded.type === 'stages' && m) {
        m.entries[m.entries.length - 1].stages = decoded.stages;
      } else if (decoded.type === 'debug' && m) {
        m.entries[m.entries.length - 1].debugBytes = msg; // decoded when its frame is shown
      }
    } else if (type === REC.command) {
      ++commands;
    } else if (type === REC.end) {
      ended = true;
      break;
    } else if (type !== REC.hash) {
      warning = `${where} has an unknown type ${type}`;
      break;
    }
    at += 16 + size;
    ++count;
  }
  if (world === null) throw new RecordingError(`${name}: the recording has no sound world record${warning ? ` (${warning})` : ''}`);
  if (!m) throw new RecordingError(`${name}: no frames before ${warning || 'its end'}`);
  if (!warning && !ended) warning = 'no end record (the server did not stop cleanly)';
  m.world = world;
  m.hasDebug = (flags & DEBUG) !== 0;
  m.commands = commands;
  m.warning = warning;
  return m;
}
