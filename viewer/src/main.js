// The viewer page: watches a world of the server it was loaded from (/ws?world=NAME), or plays a
// file dropped on it (a `cellphys serve --record` recording, or a trajectory CSV); controls,
// picking, dragging, spawning, stats and the timeline.
import * as THREE from 'three';
import uPlot from 'uplot';
import 'uplot/dist/uPlot.min.css';
import './style.css';
import * as P from './protocol.js';
import { applyTick, modelFromJoin, F_STATIC } from './model.js';
import { Renderer } from './render.js';
import { Overlay, boundingBox } from './overlay.js';
import { parseTrajectory, trajectoryModel } from './trajectory.js';
import { isRecording, readRecording } from './recording.js';

const $ = (id) => document.getElementById(id);
const params = new URLSearchParams(location.search);
const HISTORY = Number(params.get('history')) || 600; // ticks kept for the timeline (10 s at 60 Hz)

const renderer = new Renderer($('view'));
const ui = { status: $('status'), scrub: $('scrub'), tlabel: $('tlabel') };

const state = {
  model: null, ws: null, join: null, world: params.get('world') || '', token: params.get('token') || '',
  live: true, shown: null, shownIndex: 0, paused: false, worldState: 'running', canCommand: false,
  seq: 1, pending: new Map(), drag: null, selected: -1, errors: [], received: [], playing: false,
  lastStats: null, steps: 0, connected: false,
  debug: null, debugBodies: null, debugs: new Map(), // the shown frame's debug message; the live ones kept, by step
};
$('token').value = state.token;

function setStatus(text, isError = false) {
  ui.status.textContent = text;
  ui.status.className = isError ? 'err' : '';
}

// ---- connection ----

async function listWorlds() {
  try {
    const r = await fetch('/metrics', { cache: 'no-store' });
    if (!r.ok) return [];
    const m = await r.json();
    return m.worlds.map((w) => w.name);
  } catch {
    return [];
  }
}

// ---- solver overlays: the server's debug message (protocol revision 2) ----

const overlay = new Overlay(renderer.scene);
const ov = { contacts: $('ov-contacts'), normals: $('ov-normals'), islands: $('ov-islands'), cuts: $('ov-cuts'), boxes: $('ov-boxes') };
const shown = () => ({ contacts: ov.contacts.checked, normals: ov.normals.checked });
// Debug messages are asked for while an overlay that needs them is on or a body is picked (mass,
// island); stages messages (protocol revision 3) always, for the stage chart.
const wantDebug = () => ov.contacts.checked || ov.normals.checked || ov.islands.checked || ov.cuts.checked || state.selected >= 0;
function subscribeDebug() {
  const want = wantDebug();
  if (want === state.debugWanted || !state.ws || state.ws.readyState !== 1) return;
  state.debugWanted = want;
  state.ws.send(P.subscribe({ debug: want, stages: true }));
  if (!want) { setDebug(null); state.debugs.clear(); overlay.setContacts(null, shown()); overlay.setCuts(null); renderer.islandOf = null; }
}
function setDebug(m) {
  state.debug = m;
  state.debugBodies = m ? new Map(m.bodies.map((b) => [b.id, b])) : null;
}
// The debug message of the frame shown: a recording's own (`--record-debug on`); live, the one
// kept for its step (the newest while following live, until the next one arrives).
function debugOfShown(m, index, f) {
  if (m.source === 'recording') return m.debugAt(index);
  if (m.source !== 'live') return null;
  return state.debugs.get(f.step) ?? (state.live ? state.debug : null);
}
function applyDebug() {
  const d = state.debug;
  overlay.setContacts(d && d.contacts, shown());
  overlay.setCuts(d && d.cuts, state.model, state.shown, ov.cuts.checked);
  renderer.islandOf = d && ov.islands.checked ? new Map(d.bodies.filter((b) => b.island !== null).map((b) => [b.id, b.island])) : null;
  if (state.shown) renderer.draw(state.shown);
}
for (const box of Object.values(ov)) box.addEventListener('change', () => { subscribeDebug(); applyDebug(); overlay.setBoxes(state.model, state.shown, ov.boxes.checked); });

function connect(world) {
  if (state.ws) { state.ws.onclose = null; state.ws.close(); }
  state.world = world;
  const q = new URLSearchParams({ world, revision: String(P.REVISION) });
  if (state.token) q.set('token', state.token);
  const ws = new WebSocket(`${location.protocol === 'https:' ? 'wss' : 'ws'}://${location.host}/ws?${q}`);
  ws.binaryType = 'arraybuffer';
  state.ws = ws;
  setStatus(`connecting to ${world}…`);
  ws.onopen = () => { state.connected = true; state.debugWanted = null; subscribeDebug(); };
  ws.onmessage = (e) => onMessage(e.data);
  ws.onclose = (e) => {
    state.connected = false;
    setStatus(`disconnected from ${world} (${e.code}${e.reason ? ': ' + e.reason : ''}); reload to reconnect`, true);
  };
}

// What the page's own work costs (viewer/bench/frame_cost.mjs reads it): ms to take in a tick
// (decode, apply, update the instances) and ms a frame's render call takes, the last 600 of each.
const cost = { tick: [], render: [] };
const sample = (list, ms) => { list.push(ms); if (list.length > 600) list.shift(); };

function onMessage(buffer) {
  const now = performance.now();
  handle(buffer, now);
  if (state.lastTickAt === now) sample(cost.tick, performance.now() - now);
}

function handle(buffer, now) {
  state.received.push([now, buffer.byteLength]);
  let m;
  try {
    m = P.decode(buffer);
  } catch (e) {
    setStatus(`bad message from the server: ${e.message}`, true);
    return;
  }
  switch (m.type) {
    case 'join': {
      const sameWorld = state.join && state.join.name === m.name;
      state.join = m;
      state.debugs.clear();
      setDebug(null);
      state.canCommand = (m.flags & 1) !== 0;
      state.model = modelFromJoin(m, HISTORY);
      state.selected = -1;
      renderer.selectedSlot = -1;
      state.drag = null;
      renderer.setModel(state.model, state.model.live, { keepCamera: sameWorld });
      goLive();
      setStatus(`${m.name}: ${m.bodies.length} bodies, ${m.shapes.length} shapes, step ${m.step}${state.canCommand ? '' : ' (watching: no token, commands off)'}`);
      updateButtons();
      break;
    }
    case 'tick': {
      if (!state.model || m.epoch !== state.join.epoch) return;
      state.lastTickAt = now;
      const f = applyTick(state.model, m);
      state.lastStats = m.stats;
      state.paused = (m.flags & P.TICK_PAUSED) !== 0;
      state.steps = m.step;
      recordStats(m);
      if (state.live) show(state.model.frameCount() - 1);
      else ui.scrub.max = String(state.model.frameCount() - 1);
      if (f.flags.length !== renderer.frame?.flags.length && state.live) renderer.draw(f);
      updateButtons();
      break;
    }
    case 'stages':
      if (!state.join || m.epoch !== state.join.epoch) return;
      recordStages(m.step * state.join.dt, m.stages);
      break;
    case 'debug':
      if (!state.join || m.epoch !== state.join.epoch) return;
      state.debugs.set(m.step, m); // kept with the timeline's history, as long as it
      while (state.debugs.size > HISTORY) state.debugs.delete(state.debugs.keys().next().value);
      if (state.live || state.shown?.step === m.step) { setDebug(m); applyDebug(); }
      break;
    case 'ack': {
      const p = state.pending.get(m.seq);
      state.pending.delete(m.seq);
      if (p) p.resolve(m);
      break;
    }
    case 'error': {
      const p = state.pending.get(m.seq);
      state.pending.delete(m.seq);
      setStatus(`refused: ${m.code_name}${m.field ? ' ' + m.field : ''}: ${m.reason}`, true);
      if (p) p.reject(m);
      break;
    }
    case 'status':
      state.worldState = m.state;
      state.paused = m.state === 'paused';
      if (m.state === 'failed') setStatus(`world failed at step ${m.step}: ${m.text} (reset brings it back)`, true);
      updateButtons();
      break;
  }
}

/// Sends a command; resolves with its ack, rejects with its error.
function command(make) {
  if (!state.ws || state.ws.readyState !== 1) return Promise.reject(new Error('not connected'));
  const seq = state.seq++;
  state.ws.send(make(seq));
  return new Promise((resolve, reject) => state.pending.set(seq, { resolve, reject }));
}
const quiet = (p) => p.catch(() => {}); // refusals are shown in the status line

function updateButtons() {
  const live = state.model?.source === 'live';
  const can = live && state.canCommand;
  $('play').textContent = state.paused ? 'Resume' : 'Pause';
  for (const id of ['play', 'step', 'reset']) $(id).disabled = !can;
  $('tplay').textContent = state.playing ? '❚❚' : '▶';
}

// ---- timeline ----

function show(index) {
  const m = state.model;
  if (!m || !m.frameCount()) return;
  index = Math.max(0, Math.min(m.frameCount() - 1, index));
  state.shownIndex = index;
  state.shown = m.frameAt(index);
  const d = debugOfShown(m, index, state.shown);
  if (d !== state.debug) { setDebug(d); applyDebug(); } else {
    renderer.draw(state.shown);
    overlay.setCuts(state.debug?.cuts, m, state.shown, ov.cuts.checked); // drawn between the shown bodies
  }
  overlay.setBoxes(m, state.shown, ov.boxes.checked);
  ui.scrub.max = String(m.frameCount() - 1);
  ui.scrub.value = String(index);
  const f = state.shown;
  ui.tlabel.textContent = `step ${f.step}  t ${f.t.toFixed(3)} s  (${index + 1}/${m.frameCount()})${state.live && m.source === 'live' ? ' live' : ''}`;
  if (m.source === 'recording') chartRecording(m, index);
}

function goLive() {
  state.live = state.model?.source === 'live';
  state.playing = false;
  if (state.model) show(state.model.frameCount() - 1);
  updateButtons();
}

ui.scrub.addEventListener('input', () => {
  state.live = false;
  state.playing = false;
  show(Number(ui.scrub.value));
  updateButtons();
});
$('live').onclick = goLive;
$('tplay').onclick = () => {
  if (!state.model) return;
  state.playing = !state.playing;
  state.live = false;
  if (state.playing && state.shownIndex >= state.model.frameCount() - 1) show(0);
  state.playClock = performance.now();
  state.playTime = state.shown?.t ?? 0;
  updateButtons();
};

function advancePlayback(now) {
  if (!state.playing || !state.model) return;
  const speed = Number($('speed').value);
  state.playTime += ((now - state.playClock) / 1000) * speed;
  state.playClock = now;
  const m = state.model;
  let i = state.shownIndex;
  while (i + 1 < m.frameCount() && m.timeAt(i + 1) <= state.playTime) ++i;
  if (i !== state.shownIndex) show(i);
  if (i >= m.frameCount() - 1) { state.playing = false; updateButtons(); }
}

// ---- controls ----

$('play').onclick = () => quiet(command((s) => P.simple(state.paused ? P.T.resume : P.T.pause, s)));
$('step').onclick = () => quiet(command((s) => P.simple(P.T.step_once, s)));
$('reset').onclick = () => quiet(command((s) => P.simple(P.T.reset, s)));
// The speed selector paces the timeline's playback and, live with the token, the world itself.
$('speed').onchange = () => {
  const v = Number($('speed').value);
  if (state.model?.source !== 'live' || !state.canCommand) return;
  if (state.join.revision < P.SET_SPEED_REVISION) { setStatus(`this server (protocol revision ${state.join.revision}) has no speed command`, true); return; }
  quiet(command((s) => P.setSpeed(s, v)).then(() => setStatus(`world at ${v}× real time`)));
};
$('token').onchange = () => {
  state.token = $('token').value.trim();
  const u = new URL(location.href);
  if (state.token) u.searchParams.set('token', state.token); else u.searchParams.delete('token');
  history.replaceState(null, '', u);
  if (state.world) connect(state.world);
};
$('world').onchange = () => {
  const u = new URL(location.href);
  u.searchParams.set('world', $('world').value);
  history.replaceState(null, '', u);
  state.join = null;
  connect($('world').value);
};
window.addEventListener('keydown', (e) => {
  if (e.target.tagName === 'INPUT') return;
  if (e.code === 'Space') { e.preventDefault(); $('play').click(); }
  if (e.key === 's') $('step').click();
});

// ---- picking, dragging, spawning ----

const canvas = $('view');
let down = null;

// The first shape of the chosen type in the dictionary (`cellphys serve` gives every world a
// sphere and a box), else the first a client may spawn (a server that adds none).
function spawnShape() {
  const shapes = state.join.shapes, want = P.SHAPE[$('spawnshape').value];
  const shape = shapes.findIndex((s) => s.type === want);
  return shape >= 0 ? shape : shapes.findIndex((s) => !P.isStaticShape(s.type));
}

function spawnAt(hit) {
  const shape = spawnShape();
  if (shape < 0) { setStatus('no shape in this world can be spawned', true); return; }
  const s = state.join.shapes[shape];
  const half = s.type === P.SHAPE.box ? Math.max(s.params[0], s.params[1], s.params[2]) : s.params[0] || 0.25;
  const n = hit.normal && hit.normal.z > 0.3 ? hit.normal : new THREE.Vector3(0, 0, 1);
  const p = hit.point.clone().addScaledVector(n, half * 1.8 + 0.02);
  quiet(command((seq) => P.spawn(seq, { shape, position: p.toArray() })).then((a) => setStatus(`spawned body ${a.result} (${SHAPE_NAMES[s.type]}) at step ${a.step}`)));
}

canvas.addEventListener('pointerdown', (e) => {
  if (e.button !== 0 || !state.model) return;
  const hit = renderer.pick(e.clientX, e.clientY, true);
  // The ground (a plane, a mesh, a height field) is where one clicks to deselect or to spawn, not a body to pick.
  const isGround = hit.slot >= 0 && P.isStaticShape(state.model.shapes[state.model.bodies[hit.slot].shape].type);
  const live = state.model.source === 'live' && state.live;
  if ((e.shiftKey || $('spawnmode').checked) && live && state.canCommand && hit.slot >= 0) {
    spawnAt(hit);
    return;
  }
  if (hit.slot < 0 || isGround) { down = { x: e.clientX, y: e.clientY, slot: -1 }; return; }
  select(hit.slot);
  down = { x: e.clientX, y: e.clientY, slot: hit.slot };
  const b = state.model.bodies[hit.slot];
  if (!live || !state.canCommand || b.static) return;
  // Drag on a plane through the grabbed point facing the camera.
  renderer.controls.enabled = false;
  canvas.setPointerCapture(e.pointerId);
  const normal = renderer.camera.getWorldDirection(new THREE.Vector3());
  state.drag = { slot: hit.slot, plane: new THREE.Plane().setFromNormalAndCoplanarPoint(normal, hit.point), id: null, target: hit.point.toArray(), sent: 0, released: false };
  const drag = state.drag;
  command((seq) => P.dragStart(seq, b.id, hit.point.toArray(), hit.point.toArray())).then(
    (a) => {
      drag.id = a.result;
      if (drag.released) quiet(command((seq) => P.dragRelease(seq, drag.id)));
      else quiet(command((seq) => P.dragMove(seq, drag.id, drag.target)));
    },
    () => { if (state.drag === drag) state.drag = null; });
});

canvas.addEventListener('pointermove', (e) => {
  const d = state.drag;
  if (!d) return;
  const hit = renderer.pick(e.clientX, e.clientY);
  const p = hit.ray.intersectPlane(d.plane, new THREE.Vector3());
  if (!p) return;
  d.target = p.toArray();
  const now = performance.now();
  if (d.id !== null && now - d.sent > 40) { // 25 moves a second at most, inside the rate limit
    d.sent = now;
    quiet(command((seq) => P.dragMove(seq, d.id, d.target)));
  }
});

function endDrag() {
  const d = state.drag;
  renderer.controls.enabled = true;
  if (!d) return;
  state.drag = null;
  d.released = true;
  if (d.id !== null) {
    quiet(command((seq) => P.dragMove(seq, d.id, d.target)));
    quiet(command((seq) => P.dragRelease(seq, d.id)));
  }
}
canvas.addEventListener('pointerup', (e) => {
  if (down && down.slot < 0 && Math.hypot(e.clientX - down.x, e.clientY - down.y) < 4) select(-1);
  down = null;
  endDrag();
});
canvas.addEventListener('pointercancel', endDrag);

function select(slot) {
  state.selected = slot;
  subscribeDebug();
  renderer.selectedSlot = slot;
  if (state.shown) renderer.draw(state.shown);
}

// ---- panels ----

const fmt = (v, d = 3) => v.map((x) => x.toFixed(d).padStart(8)).join(' ');
const SHAPE_NAMES = Object.fromEntries(Object.entries(P.SHAPE).map(([name, type]) => [type, name.replace('_', ' ')]));

function debugLine(s) {
  const b = state.debugBodies?.get(s.id);
  if (s.static) return 'mass  static';
  const m = state.model;
  if (!b && m?.source === 'recording') return m.hasDebug ? 'mass and island: no debug message with this frame' : 'mass and island: not in this recording (record with --record-debug on)';
  if (!b && m?.source !== 'live') return 'mass and island: not in a trajectory file';
  if (!b) return state.live ? 'mass and island: waiting for the server' : 'mass and island: no debug message kept for this step';
  return `mass  ${b.mass.toPrecision(4)} kg   island ${b.island === null ? '— (asleep)' : b.island + (b.decoupled ? ' (decoupled)' : '')}`;
}

function updateSelection() {
  const el = $('selection');
  if (state.selected < 0 || !state.model) { el.textContent = 'Click a body to inspect it; drag it to pull it\n(needs the token); shift-click to spawn a box or a sphere.'; return; }
  const s = state.model.bodyState(state.shown, state.selected);
  if (!s) { el.textContent = `body ${state.model.bodies[state.selected].label}: not in this frame`; return; }
  const parts = s.shape_type === P.SHAPE.compound ? ` of ${state.model.shapes[s.shape].parts.length} parts` : '';
  el.textContent = [
    `body ${s.label}  ${SHAPE_NAMES[s.shape_type] ?? '?'}${parts} (shape ${s.shape}) ×${s.scale}`,
    s.static ? 'static' : s.awake ? 'awake' : 'asleep',
    `pos   ${fmt(s.position)}`, `quat  ${fmt(s.orientation, 4)}`, `vel   ${fmt(s.velocity)}`, `omega ${fmt(s.angular_velocity)}`,
    debugLine(s),
  ].join('\n');
}

const series = { t: [], ms: [], active: [], sleeping: [], contacts: [], iters: [], kbps: [] };
const PLOT_POINTS = 600;
function recordStats(tick) {
  const s = tick.stats;
  const push = (k, v) => { series[k].push(v); if (series[k].length > PLOT_POINTS) series[k].shift(); };
  push('t', tick.step * (state.join?.dt || 1 / 60));
  push('ms', s.step_ms);
  push('active', s.active_bodies);
  push('sleeping', s.sleeping_bodies);
  push('contacts', s.contacts);
  push('iters', s.solver_iterations);
  push('kbps', bytesPerSecond() / 1000);
}

function bytesPerSecond() {
  const now = performance.now();
  while (state.received.length && state.received[0][0] < now - 1000) state.received.shift();
  return state.received.reduce((n, r) => n + r[1], 0);
}

function updateStats() {
  const m = state.model;
  const s = m?.source === 'recording' ? state.shown?.stats : state.lastStats;
  const lines = [];
  if (m?.source === 'file') lines.push(`file: ${m.bodies.length} bodies, ${m.frameCount()} frames`);
  if (m?.source === 'recording') {
    lines.push(`recording of ${m.world}: ${m.frameCount()} frames, steps ${m.stepAt(0)}–${m.stepAt(m.frameCount() - 1)}, ${m.commands} commands`);
    if (state.shown) lines.push(`step ${state.shown.step}${state.shown.paused ? ' (paused)' : ''}`);
  }
  if (s && m?.source === 'recording') {
    lines.push(`ms per step     ${s.step_ms.toFixed(3)}`, `active bodies   ${s.active_bodies}`, `sleeping bodies ${s.sleeping_bodies}`,
      `contacts        ${s.contacts}`, `islands         ${s.islands}`, `solver iters    ${s.solver_iterations}`,
      `failed islands  ${s.failed_islands}`, `step halvings   ${s.step_halvings}`);
  } else if (s) {
    lines.push(`world ${state.join.name}  step ${state.steps}  ${state.worldState}${state.paused ? ' (paused)' : ''}`,
      `ms per step     ${s.step_ms.toFixed(3)}`, `active bodies   ${s.active_bodies}`, `sleeping bodies ${s.sleeping_bodies}`,
      `contacts        ${s.contacts}`, `islands         ${s.islands}`, `solver iters    ${s.solver_iterations}`,
      `failed islands  ${s.failed_islands}`, `step halvings   ${s.step_halvings}`, `received        ${(bytesPerSecond() / 1000).toFixed(1)} kB/s`);
  }
  if (state.debug) lines.push(`cut couplings   ${state.debug.cuts.length}`);
  lines.push(`drawn instances ${renderer.instanceCount()}`, `frames drawn    ${fps.toFixed(0)}/s`);
  $('stats').textContent = lines.join('\n');
}

function makePlot(el, title, defs) {
  return new uPlot({
    title, width: 256, height: 130, legend: { show: true, live: false }, cursor: { show: false }, scales: { x: { time: false } },
    axes: [{ stroke: '#9fb0c0', grid: { stroke: '#333a42' } }, { stroke: '#9fb0c0', grid: { stroke: '#333a42' }, size: 50 }],
    series: [{}, ...defs.map(([label, stroke]) => ({ label, stroke, width: 1.5, points: { show: false } }))],
  }, [[], ...defs.map(() => [])], el);
}
const plotMs = makePlot($('chart-ms'), 'ms per step', [['ms', '#ffb454']]);
const plotCounts = makePlot($('chart-counts'), 'bodies, contacts, iterations, kB/s', [['active', '#4f8fd8'], ['asleep', '#a0a0a0'], ['contacts', '#58b368'], ['iters', '#d86a4f'], ['kB/s', '#b36bc4']]);
// ms per stage, stacked: the stages are the server's (the stages message names them), so the
// chart is made again whenever their names change; "total" is the whole step, a line over them.
const stageChart = { key: null, plot: null, names: [], t: [], rows: [] };
const stageColour = (k, alpha = 1) => `hsla(${(k * 137.5 + 30) % 360}, 60%, 58%, ${alpha})`;

function recordStages(t, stages) {
  const key = stages.map((s) => s.name).join(',');
  if (key !== stageChart.key) makeStagePlot(stages.map((s) => s.name));
  stageChart.t.push(t);
  stageChart.rows.push(stages.map((s) => s.ms));
  if (stageChart.t.length > PLOT_POINTS) { stageChart.t.shift(); stageChart.rows.shift(); }
}

function makeStagePlot(names) {
  stageChart.key = names.join(',');
  stageChart.names = names;
  stageChart.t = [];
  stageChart.rows = [];
  if (stageChart.plot) stageChart.plot.destroy();
  const parts = names.map((n, k) => [n, k]).filter(([n]) => n !== 'total');
  // Series k is the sum of the parts up to k, filled down to zero, drawn from the top part down,
  // so each part shows as the band it adds.
  const defs = parts.map(([n], k) => ({ label: n, stroke: stageColour(k), fill: stageColour(k, 0.75), width: 1, points: { show: false } })).reverse();
  if (names.includes('total')) defs.push({ label: 'total', stroke: '#e8eef4', width: 1, dash: [4, 3], points: { show: false } });
  stageChart.parts = parts.map(([, k]) => k);
  stageChart.total = names.indexOf('total');
  stageChart.plot = new uPlot({
    title: 'ms per stage (stacked)', width: 256, height: 170, legend: { show: true, live: false }, cursor: { show: false },
    scales: { x: { time: false } },
    axes: [{ stroke: '#9fb0c0', grid: { stroke: '#333a42' } }, { stroke: '#9fb0c0', grid: { stroke: '#333a42' }, size: 50 }],
    series: [{ label: 't (s)' }, ...defs],
  }, [[], ...defs.map(() => [])], $('chart-stages'));
}

function stageData() {
  const c = stageChart, sums = c.parts.map(() => []);
  for (const row of c.rows) {
    let sum = 0;
    c.parts.forEach((k, i) => { sum += row[k]; sums[i].push(sum); });
  }
  const data = [c.t, ...sums.reverse()];
  if (c.total >= 0) data.push(c.rows.map((r) => r[c.total]));
  return data;
}

/// The charts of a recording: its recorded ticks' statistics up to the shown one.
function chartRecording(m, index) {
  for (const k of Object.keys(series)) series[k].length = 0;
  if (stageChart.plot) { stageChart.t.length = 0; stageChart.rows.length = 0; }
  for (let i = Math.max(0, index - PLOT_POINTS + 1); i <= index; ++i) {
    const e = m.entries[i];
    if (e.stages) recordStages(e.step * m.dt, e.stages);
    if (!e.stats) continue;
    series.t.push(e.step * m.dt);
    series.ms.push(e.stats.step_ms);
    series.active.push(e.stats.active_bodies);
    series.sleeping.push(e.stats.sleeping_bodies);
    series.contacts.push(e.stats.contacts);
    series.iters.push(e.stats.solver_iterations);
    series.kbps.push(m.dt > 0 ? e.bytes.length / m.dt / 1000 : 0); // as sent at one tick a step
  }
}

function updatePlots() {
  if (stageChart.plot && stageChart.t.length >= 2) stageChart.plot.setData(stageData());
  if (series.t.length < 2) return;
  plotMs.setData([series.t, series.ms]);
  plotCounts.setData([series.t, series.active, series.sleeping, series.contacts, series.iters, series.kbps]);
}

// ---- offline files ----

async function openFiles(files) {
  const list = Array.from(files);
  try {
    for (const f of list) {
      const bytes = new Uint8Array(await f.arrayBuffer());
      if (!isRecording(bytes) && !f.name.endsWith('.rec')) continue;
      const m = readRecording(bytes, f.name);
      loadModel(m);
      setStatus(`${f.name}: recording of ${m.world}, ${m.frameCount()} frames, ${m.bodies.length} bodies${m.warning ? ` (warning: ${m.warning}; shown up to there)` : ''}`, !!m.warning);
      return;
    }
  } catch (e) {
    setStatus(e.message, true);
    return;
  }
  const csv = list.find((f) => f.name.endsWith('.csv'));
  const json = list.find((f) => f.name.endsWith('.json'));
  if (!csv) { setStatus('drop a recording (cellphys serve --record), or a trajectory .csv (cellphys run --out) optionally with its scene .json', true); return; }
  try {
    const rows = parseTrajectory(await csv.text(), csv.name);
    let scene = null;
    if (json) {
      try { scene = JSON.parse(await json.text()); } catch (e) { throw new Error(`${json.name}: not JSON (${e.message})`); }
    }
    loadModel(trajectoryModel(rows, scene, json?.name));
    const w = state.model.warning;
    setStatus(`${csv.name}${json ? ' + ' + json.name : ''}: ${state.model.bodies.length} bodies, ${state.model.frameCount()} frames${json ? '' : ' (drawn as boxes: drop the scene JSON too for shapes)'}${w ? ` (warning: ${w})` : ''}`, !!w);
  } catch (e) {
    setStatus(e.message, true);
  }
}

function loadModel(model) {
  if (state.ws) { state.ws.onclose = null; state.ws.close(); state.ws = null; }
  state.model = model;
  state.join = null;
  state.lastStats = null;
  state.selected = -1;
  // The live world's debug messages say nothing of a file's bodies.
  setDebug(null);
  state.debugs.clear();
  overlay.setContacts(null, shown());
  overlay.setCuts(null);
  renderer.islandOf = null;
  renderer.selectedSlot = -1;
  renderer.setModel(model, model.frameAt(0));
  state.live = false;
  show(0);
  updateButtons();
}

$('open').onclick = () => $('file').click();
$('file').onchange = () => openFiles($('file').files);
window.addEventListener('dragover', (e) => { e.preventDefault(); $('drop').classList.add('on'); });
window.addEventListener('dragleave', () => $('drop').classList.remove('on'));
window.addEventListener('drop', (e) => { e.preventDefault(); $('drop').classList.remove('on'); openFiles(e.dataTransfer.files); });

// ---- loop ----

let fps = 0, fpsCount = 0, fpsClock = performance.now(), panelClock = 0;
function frame(now) {
  advancePlayback(now);
  const t0 = performance.now();
  renderer.render();
  sample(cost.render, performance.now() - t0);
  if (++fpsCount && now - fpsClock >= 1000) { fps = (fpsCount * 1000) / (now - fpsClock); fpsCount = 0; fpsClock = now; }
  if (now - panelClock > 250) { panelClock = now; updateSelection(); updateStats(); updatePlots(); }
  requestAnimationFrame(frame);
}
requestAnimationFrame(frame);

// ---- start ----

(async () => {
  const worlds = await listWorlds();
  const sel = $('world');
  for (const w of worlds) sel.add(new Option(w, w));
  if (!worlds.length) { setStatus('no server: open or drop a trajectory CSV'); return; }
  const world = worlds.includes(state.world) ? state.world : worlds[0];
  sel.value = world;
  connect(world);
})();

// The slot of body `id` in the epoch of the frame shown.
const slotOfShown = (id) => (state.shown?.slotOf ?? state.model?.slotOf)?.get(id);

// A small hook for tests and the console: reads of what is shown, no control the page lacks.
window.__viewer = {
  ready: () => !!state.model && renderer.frames > 0,
  source: () => state.model?.source ?? null,
  join: () => state.join && { name: state.join.name, step: state.join.step, epoch: state.join.epoch, bodies: state.join.bodies.length, canCommand: state.canCommand },
  bodies: () => state.model?.bodies.map((b) => ({ id: b.id, label: b.label, shape: b.shape, static: b.static })) ?? [],
  step: () => state.shown?.step ?? null,
  paused: () => state.paused,
  frameCount: () => state.model?.frameCount() ?? 0,
  frameIndex: () => state.shownIndex,
  instanceCount: () => renderer.instanceCount(),
  framesDrawn: () => renderer.frames,
  bodyState: (id) => { const s = slotOfShown(id); return s === undefined ? null : state.model.bodyState(state.shown, s); },
  drawnPosition: (id) => { const s = slotOfShown(id); return s === undefined ? null : renderer.instancePosition(s); },
  drawnParts: (id) => { const s = slotOfShown(id); return s === undefined ? null : renderer.parts(s); },
  boxOf: (id) => {
    const s = slotOfShown(id), b = s === undefined ? null : state.model.bodyState(state.shown, s);
    return b && boundingBox(state.model.shapes[b.shape], b.scale, b.position, b.orientation);
  },
  screenOf: (id) => { const b = window.__viewer.bodyState(id); return b && renderer.toScreen(b.position); },
  screenOfPoint: (v) => renderer.toScreen(v),
  surfaces: () => renderer.surfaces(),
  selected: () => (state.selected < 0 ? null : state.model.bodies[state.selected].id),
  status: () => ui.status.textContent,
  lastStats: () => state.lastStats,
  debug: () => (state.debug ? { step: state.debug.step, contacts: state.debug.contacts.length, bodies: state.debug.bodies.length, cuts: state.debug.cuts.length } : null),
  debugKept: () => state.debugs.size,
  // The page's own cost: ms per tick taken in and per render call (the last 600), draw calls a frame.
  cost: () => ({ tick: [...cost.tick], render: [...cost.render], drawCalls: renderer.gl.info.render.calls }),
  cutLines: () => overlay.cutCount,
  frameEpochs: () => state.model?.entries?.map((e) => e.epoch) ?? null,
  contactMarkers: () => overlay.contactCount,
  boxCount: () => overlay.boxCount,
  selection: () => $('selection').textContent,
  stageChart: () => ({ names: stageChart.names, points: stageChart.t.length }),
};
