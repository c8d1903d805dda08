// The viewer in a real browser: Debian's Chromium, headless, driven by playwright-core, against
// `cellphys serve` started here on a free port. Usage:
//   node viewer/test/viewer_test.mjs CELLPHYS_EXE [--images DIR]
// Exit 0: every check passed; 1: a check failed; 77: skipped (no Chromium; scripts/setup installs it).
import { execFileSync } from 'node:child_process';
import { existsSync, mkdtempSync, readFileSync, rmSync, mkdirSync, writeFileSync } from 'node:fs';
import { tmpdir } from 'node:os';
import { dirname, join, resolve } from 'node:path';
import { fileURLToPath } from 'node:url';
import { CHROMIUM, launchBrowser, serve as harnessServe } from './harness.mjs';
await import('playwright-core').catch(() => { console.error('viewer_test: playwright-core is not installed in viewer/node_modules (scripts/setup runs npm ci there)'); process.exit(1); });
const here = dirname(fileURLToPath(import.meta.url));
const exe = process.argv[2];
const imagesAt = process.argv.indexOf('--images');
const images = imagesAt > 0 ? resolve(process.argv[imagesAt + 1]) : null;
const viewerDir = resolve(here, '..', 'dist');
const scenesDir = resolve(here, '..', '..', 'examples', 'scenes');

if (!exe || !existsSync(exe)) { console.error(`viewer_test: no cellphys executable at "${exe}"`); process.exit(1); }
if (!existsSync(CHROMIUM)) {
  console.log(`viewer_test: SKIPPED: no Chromium at ${CHROMIUM} (scripts/setup installs Debian's chromium)`);
  process.exit(77);
}
if (!existsSync(join(viewerDir, 'index.html'))) { console.error(`viewer_test: no built viewer at ${viewerDir} (npm run build in viewer/)`); process.exit(1); }

let failures = 0;
function check(ok, what, detail = '') {
  console.log(`${ok ? 'ok  ' : 'FAIL'} ${what}${detail ? ': ' + detail : ''}`);
  if (!ok) failures++;
  return ok;
}
const sleep = (ms) => new Promise((r) => setTimeout(r, ms));
async function until(what, fn, ms = 15000) {
  const end = Date.now() + ms;
  for (;;) {
    const v = await fn();
    if (v) return v;
    if (Date.now() > end) throw new Error(`timed out after ${ms} ms waiting for ${what}`);
    await sleep(50);
  }
}

const serve = (args) => harnessServe(exe, args, { viewerDir, scenesDir });

async function metrics(server, world) {
  const r = await fetch(new URL('/metrics', server.url));
  const m = await r.json();
  return m.worlds.find((w) => w.name === world);
}

const launched = await launchBrowser();
const browser = launched.context;
const servers = [];
const consoleErrors = [];
async function openPage(url, name) {
  const page = await browser.newPage();
  page.on('console', (m) => { if (m.type() === 'error') consoleErrors.push(`${name}: ${m.text()}`); });
  page.on('pageerror', (e) => consoleErrors.push(`${name}: ${e.message}`));
  page.on('request', (r) => { const u = new URL(r.url()); if (u.host !== new URL(url).host && u.protocol !== 'data:') consoleErrors.push(`${name}: request off the server: ${r.url()}`); });
  await page.goto(url);
  await page.waitForFunction(() => window.__viewer && window.__viewer.ready() && window.__viewer.frameCount() > 5, null, { timeout: 20000 });
  return page;
}

try {
  // ---- the pile, live ----
  const pile = await serve(['pile65']);
  servers.push(pile);
  const page = await openPage(`${pile.url}?token=${pile.token}`, 'pile65');
  const join1 = await page.evaluate(() => window.__viewer.join());
  const m0 = await metrics(pile, 'pile65');
  check(join1.name === 'pile65' && join1.canCommand, 'the page joined pile65 with commands', JSON.stringify(join1));
  const instances = await page.evaluate(() => window.__viewer.instanceCount());
  check(instances === join1.bodies, 'one instance a body', `${instances} instances, ${join1.bodies} bodies in the join`);
  const dynamic = await page.evaluate(() => window.__viewer.bodies().filter((b) => !b.static).length);
  check(dynamic === m0.bodies, 'dynamic bodies as the server counts them', `${dynamic} in the page, ${m0.bodies} in /metrics`);

  // Not blank: the frame's pixels are not one colour, and the centre region (the pile) differs from the corner (background).
  const pixels = await page.evaluate(() => {
    const c = document.getElementById('view');
    const g = document.createElement('canvas');
    g.width = 64; g.height = 40;
    const x = g.getContext('2d');
    x.drawImage(c, 0, 0, 64, 40);
    const d = x.getImageData(0, 0, 64, 40).data;
    const colours = new Set();
    for (let i = 0; i < d.length; i += 4) colours.add((d[i] >> 3) << 10 | (d[i + 1] >> 3) << 5 | (d[i + 2] >> 3));
    return { colours: colours.size, w: c.width, h: c.height };
  });
  check(pixels.colours > 20, 'the frame of the pile is not blank', `${pixels.colours} distinct colours in a 64x40 reduction of ${pixels.w}x${pixels.h}`);
  if (images) { mkdirSync(images, { recursive: true }); await page.screenshot({ path: join(images, 'viewer_pile65.png') }); }

  // ---- the stage chart: ms per stage, stacked, under the names the server times them by ----
  const legendOf = (pg) => pg.evaluate(() => Array.from(document.querySelectorAll('#chart-stages .u-legend .u-series .u-label')).map((e) => e.textContent).filter((l) => l !== 't (s)'));
  await until('stage samples in the chart', async () => (await page.evaluate(() => window.__viewer.stageChart().points)) > 10);
  const serverStages = Object.keys(m0.stage_ms_mean).sort();
  const legend = await legendOf(page);
  check(JSON.stringify([...legend].sort()) === JSON.stringify(serverStages), 'the stage chart draws every stage the server times, by name',
        `legend ${legend.join(' ')}; /metrics ${serverStages.join(' ')}`);

  // ---- pause, then one step ----
  await page.click('#play');
  await until('the world to pause', async () => (await metrics(pile, 'pile65')).state === 'paused');
  const s0 = (await metrics(pile, 'pile65')).step;
  await sleep(300);
  const s0b = (await metrics(pile, 'pile65')).step;
  check(s0b === s0, 'paused: the step counter holds', `${s0} then ${s0b} 300 ms later`);
  check(await page.evaluate(() => window.__viewer.paused()), 'the page shows the world paused');
  await page.click('#step');
  await until('one step', async () => (await metrics(pile, 'pile65')).step !== s0);
  await sleep(300);
  const s1 = (await metrics(pile, 'pile65')).step;
  check(s1 === s0 + 1, 'single step advances the server by one', `${s0} -> ${s1}`);
  await until('the page to show that step', async () => (await page.evaluate(() => window.__viewer.step())) === s1);
  await page.click('#play');
  await until('the world to run', async () => (await metrics(pile, 'pile65')).state === 'running');
  // The speed selector paces the live world: half speed, 30 steps a real second.
  await page.selectOption('#speed', '0.5');
  await until('the world at half speed', async () => (await metrics(pile, 'pile65')).speed === 0.5, 5000).catch(() => null);
  await sleep(2500); // the metrics' rate is over the last 2 s
  const slow = await metrics(pile, 'pile65');
  check(slow.speed === 0.5 && slow.tick_hz_target === 30 && slow.tick_hz > 20 && slow.tick_hz < 36,
        'the speed selector sets the live world\'s pace', `speed ${slow.speed}, ${slow.tick_hz.toFixed(1)} steps a second (target ${slow.tick_hz_target})`);
  await page.selectOption('#speed', '1');
  await until('the world at full speed', async () => (await metrics(pile, 'pile65')).speed === 1, 5000);

  // ---- overlays: contacts as the server's debug message reports them; bounding boxes ----
  await page.click('#ov-contacts');
  await until('a debug message', async () => (await page.evaluate(() => window.__viewer.debug())) !== null);
  const shownContacts = await page.evaluate(() => ({ debug: window.__viewer.debug(), markers: window.__viewer.contactMarkers() }));
  check(shownContacts.markers > 0 && shownContacts.markers === shownContacts.debug.contacts,
        'with contacts on, the pile draws one marker per contact the debug message reported',
        `${shownContacts.markers} markers, ${shownContacts.debug.contacts} contacts at step ${shownContacts.debug.step}`);
  // Every box of the pile rests on something: at least one contact a dynamic body.
  check(shownContacts.debug.contacts >= dynamic && shownContacts.debug.bodies === dynamic,
        'the debug message covers the pile', `${shownContacts.debug.contacts} contacts, ${shownContacts.debug.bodies} bodies, ${dynamic} dynamic`);
  // The debug messages are kept with the timeline: scrubbed back, the overlays are that step's.
  await until('debug messages kept', async () => (await page.evaluate(() => window.__viewer.debugKept())) >= 30);
  const back = await page.evaluate(() => {
    const v = window.__viewer, s = document.getElementById('scrub');
    s.value = String(v.frameCount() - 20);
    s.dispatchEvent(new Event('input'));
    return { step: v.step(), debug: v.debug(), markers: v.contactMarkers() };
  });
  check(back.debug && back.debug.step === back.step && back.markers === back.debug.contacts,
        "scrubbed back, the overlays show that step's debug message", `step ${back.step}, debug of step ${back.debug?.step}, ${back.markers} markers for ${back.debug?.contacts} contacts`);
  await page.click('#live');
  await page.click('#ov-boxes');
  const boxes = await page.evaluate(() => window.__viewer.boxCount());
  check(boxes === instances - 1, 'bounding boxes on demand: one a body but the ground plane', `${boxes} boxes, ${instances} instances`);
  await page.click('#ov-normals');
  await page.click('#ov-islands');
  await sleep(300);
  if (images) await page.screenshot({ path: join(images, 'viewer_overlays.png') });
  for (const id of ['#ov-contacts', '#ov-normals', '#ov-islands', '#ov-boxes']) await page.click(id);

  // ---- drag: pick the highest box and pull it up; a second page without the token sees it move ----
  const watcher = await openPage(pile.url, 'pile65 watcher');
  check(!(await watcher.evaluate(() => window.__viewer.join().canCommand)), 'a page without the token cannot command');
  const target = await page.evaluate(() => {
    const v = window.__viewer;
    const bs = v.bodies().filter((b) => !b.static).map((b) => v.bodyState(b.id));
    bs.sort((a, b) => b.position[2] - a.position[2]);
    return { id: bs[0].id, z: bs[0].position[2], screen: v.screenOf(bs[0].id) };
  });
  const before = await watcher.evaluate((id) => window.__viewer.bodyState(id).position, target.id);
  await page.mouse.move(target.screen.x, target.screen.y);
  await page.mouse.down();
  check((await page.evaluate(() => window.__viewer.selected())) === target.id, 'the click picked the box under it', `box ${target.id}`);
  for (let k = 1; k <= 10; ++k) { await page.mouse.move(target.screen.x, target.screen.y - 25 * k); await sleep(60); }
  await sleep(1200);
  const held = await watcher.evaluate((id) => window.__viewer.bodyState(id).position, target.id);
  await page.mouse.up();
  check(held[2] > before[2] + 0.5, 'a drag moves the picked body on the server (seen by another client)', `z ${before[2].toFixed(3)} -> ${held[2].toFixed(3)}`);
  // The pick panel shows the picked body's mass, as the scene file gives it.
  const scene = JSON.parse(readFileSync(join(scenesDir, 'pile65.json'), 'utf8'));
  const label = scene.bodies[target.id].id;  // the server numbers a scene's bodies in their order
  const sceneMass = scene.bodies[target.id].mass;
  await until('the pick panel to show a mass', async () => /mass\s+[0-9.]+ kg/.test(await page.evaluate(() => window.__viewer.selection())), 5000).catch(() => null);
  const panel = await page.evaluate(() => window.__viewer.selection());
  const panelMass = Number(/mass\s+([0-9.e+-]+) kg/.exec(panel)?.[1]);
  check(panelMass === sceneMass && /island /.test(panel), 'the pick panel shows the body\'s mass and island', `${label}: panel "${panel.split('\n').find((l) => l.startsWith('mass')) ?? panel}", scene mass ${sceneMass}`);

  // ---- spawn: shift-click on the ground adds a body ----
  const nBefore = await page.evaluate(() => window.__viewer.instanceCount());
  const ground = await page.evaluate(() => ({ x: innerWidth * 0.3, y: innerHeight * 0.85 }));
  await page.keyboard.down('Shift');
  await page.mouse.click(ground.x, ground.y);
  await page.keyboard.up('Shift');
  await until('the spawned box', async () => (await page.evaluate(() => window.__viewer.instanceCount())) === nBefore + 1, 5000).catch(() => null);
  check((await page.evaluate(() => window.__viewer.instanceCount())) === nBefore + 1, 'shift-click spawns a box', await page.evaluate(() => window.__viewer.status()));
  // A sphere, in a world of boxes only: the server adds one to the dictionary to spawn.
  await page.selectOption('#spawnshape', 'sphere');
  await page.keyboard.down('Shift');
  await page.mouse.click(ground.x + 120, ground.y);
  await page.keyboard.up('Shift');
  await until('the spawned sphere', async () => /\(sphere\)/.test(await page.evaluate(() => window.__viewer.status())), 5000).catch(() => null);
  const sphereId = Number(/spawned body (\d+) \(sphere\)/.exec(await page.evaluate(() => window.__viewer.status()))?.[1]);
  await until('the sphere in a tick', async () => (await page.evaluate((id) => window.__viewer.bodyState(id), sphereId)) !== null, 5000).catch(() => null);
  const sphere = await page.evaluate((id) => window.__viewer.bodyState(id), sphereId);
  check(sphere !== null && sphere.shape_type === 0 && (await page.evaluate(() => window.__viewer.instanceCount())) === nBefore + 2,
        'with sphere chosen, shift-click spawns a sphere', `${await page.evaluate(() => window.__viewer.status())}; shape type ${sphere?.shape_type}`);
  await page.selectOption('#spawnshape', 'box');

  // ---- the timeline scrubs back over received ticks ----
  const fc = await page.evaluate(() => window.__viewer.frameCount());
  await page.evaluate(() => { const s = document.getElementById('scrub'); s.value = '0'; s.dispatchEvent(new Event('input')); });
  const oldest = await page.evaluate(() => window.__viewer.step());
  const live = (await metrics(pile, 'pile65')).step;
  check(fc > 60 && oldest < live - 60, 'the timeline scrubs back over received ticks', `${fc} frames kept, showing step ${oldest} while the server is at ${live}`);
  await page.click('#live');
  await watcher.close();
  await page.close();

  // ---- cut couplings: the reference pile in a 16 KiB local store, kept awake: it settles into
  // columns of a few boxes, each an island too big for the store, cut in parts every step (split,
  // not computed whole). (At 32 KiB the columns that land apart fit whole.) ----
  const cutDir = mkdtempSync(join(tmpdir(), 'cellphys-viewer-cut-'));
  const cutScene = JSON.parse(readFileSync(join(scenesDir, 'pile65.json'), 'utf8'));
  Object.assign(cutScene.settings, { local_store_bytes: 16384, whole_island_bytes: 0, sleeping: false });
  writeFileSync(join(cutDir, 'pile65_cut.json'), JSON.stringify(cutScene));
  const cut = await serve([join(cutDir, 'pile65_cut.json')]);
  servers.push(cut);
  const cpage = await openPage(cut.url, 'pile65_cut');
  await cpage.click('#ov-cuts');
  const cuts = await until('a debug message with cut couplings', () => cpage.evaluate(() => {
    const d = window.__viewer.debug();
    return d && d.cuts > 0 ? { cuts: d.cuts, lines: window.__viewer.cutLines(), step: d.step } : null;
  }));
  check(cuts.lines === cuts.cuts, 'cut couplings: one line a coupling the debug message says decoupling cut', `${cuts.lines} lines, ${cuts.cuts} cut at step ${cuts.step}`);
  if (images) { await cpage.click('#ov-islands'); await sleep(300); await cpage.screenshot({ path: join(images, 'viewer_cuts.png') }); }
  await cpage.close();
  cut.stop();
  rmSync(cutDir, { recursive: true, force: true });

  // ---- world1000 ----
  const world = await serve(['world1000']);
  servers.push(world);
  const wpage = await openPage(world.url, 'world1000');
  const wj = await wpage.evaluate(() => window.__viewer.join());
  check((await wpage.evaluate(() => window.__viewer.instanceCount())) === wj.bodies, 'world1000: one instance a body', `${wj.bodies} bodies`);
  await sleep(1500);
  const fps = await wpage.evaluate(async () => { const a = window.__viewer.framesDrawn(); await new Promise((r) => setTimeout(r, 2000)); return (window.__viewer.framesDrawn() - a) / 2; });
  console.log(`info world1000: ${fps.toFixed(1)} frames a second drawn (headless, software WebGL: not a measure of a GPU)`);
  if (images) await wpage.screenshot({ path: join(images, 'viewer_world1000.png') });
  await wpage.close();

  // ---- level geometry: a height field (a bowl) and a mesh (a pyramid), live and from the scene file ----
  const terrainFile = join(here, 'terrain.json');
  const terrainScene = JSON.parse(readFileSync(terrainFile, 'utf8'));
  const bowl = terrainScene.shapes.find((s) => s.type === 'height_field'), pyramid = terrainScene.shapes.find((s) => s.type === 'mesh');
  const terrain = await serve([terrainFile]);
  servers.push(terrain);
  const tpage = await openPage(`${terrain.url}?token=${terrain.token}`, 'terrain');
  const tj = await tpage.evaluate(() => window.__viewer.join());
  check((await tpage.evaluate(() => window.__viewer.instanceCount())) === tj.bodies, 'terrain: one instance a body, the bowl and the pyramid among them', `${tj.bodies} bodies`);
  // A triangle as its vertices (to 1e-5 m), rotated to start at the smallest: the winding kept,
  // the order of the triangles and the numbering of the vertices not.
  const triangleKeys = (tris) => tris.map((t) => {
    const v = t.map((p) => p.map((x) => x.toFixed(5)).join(' '));
    const k = v.indexOf([...v].sort()[0]);
    return [...v.slice(k), ...v.slice(0, k)].join(' | ');
  }).sort();
  const drawn = await tpage.evaluate(() => window.__viewer.surfaces());
  const drawnBowl = drawn.find((d) => d.type === 6), drawnPyramid = drawn.find((d) => d.type === 5);
  const bowlTriangles = 2 * (bowl.rows - 1) * (bowl.columns - 1);
  check(drawn.length === 2 && drawnBowl?.instances === 1 && drawnBowl.triangles.length === bowlTriangles,
        'the height field is drawn once, as its grid\'s triangles', `${drawnBowl?.triangles.length} triangles drawn, ${bowlTriangles} in a ${bowl.rows} x ${bowl.columns} grid`);
  check(drawnPyramid?.instances === 1 && drawnPyramid.triangles.length === pyramid.triangles.length,
        'the mesh is drawn once, as its triangles', `${drawnPyramid?.triangles.length} drawn, ${pyramid.triangles.length} in the scene`);
  // Against the scene file's own numbers: the mesh's triangles as given, the grid's as the scene format describes it
  // (row i along y, column j along x, centred on the body origin; two triangles a cell, counter-clockwise from +z).
  const gridVertex = (i, j) => [(j - 0.5 * (bowl.columns - 1)) * Math.fround(bowl.spacing[0]), (i - 0.5 * (bowl.rows - 1)) * Math.fround(bowl.spacing[1]),
    bowl.heights[i * bowl.columns + j]].map(Math.fround);
  const gridTriangles = [];
  for (let i = 0; i + 1 < bowl.rows; ++i)
    for (let j = 0; j + 1 < bowl.columns; ++j)
      gridTriangles.push([gridVertex(i, j), gridVertex(i, j + 1), gridVertex(i + 1, j + 1)], [gridVertex(i, j), gridVertex(i + 1, j + 1), gridVertex(i + 1, j)]);
  const pyramidTriangles = pyramid.triangles.map((t) => t.map((k) => pyramid.vertices[k].map(Math.fround)));
  const sameTriangles = (a, b) => JSON.stringify(triangleKeys(a)) === JSON.stringify(triangleKeys(b));
  check(drawnBowl && sameTriangles(drawnBowl.triangles, gridTriangles), 'the height field\'s drawn triangles are the scene\'s grid, winding and all');
  check(drawnPyramid && sameTriangles(drawnPyramid.triangles, pyramidTriangles), 'the mesh\'s drawn triangles are the scene\'s');
  // On screen: a grid vertex on the near half of the bowl (nearer the camera than the balls in it),
  // 120 px or more from every ball on screen (clear of their shadows), shows the terrain's green.
  const near = [];
  for (let i = 1; i + 1 < bowl.rows; ++i) for (let j = 1; j + 1 < bowl.columns; ++j) if (gridVertex(i, j)[1] < -0.9) near.push(gridVertex(i, j));
  const seen = await tpage.evaluate((points) => {
    const v = window.__viewer, c = document.getElementById('view'), r = c.getBoundingClientRect();
    const ballsAt = v.bodies().filter((b) => !b.static).map((b) => v.screenOf(b.id));
    const onScreen = points.map((p) => ({ p, at: v.screenOfPoint(p) })).filter(({ at }) =>
      at.x > r.left + 20 && at.x < r.right - 20 && at.y > r.top + 20 && at.y < r.bottom - 20 &&
      ballsAt.every((b) => Math.hypot(b.x - at.x, b.y - at.y) > 120));
    if (!onScreen.length) return null;
    const centre = { x: (r.left + r.right) / 2, y: (r.top + r.bottom) / 2 };
    onScreen.sort((a, b) => Math.hypot(a.at.x - centre.x, a.at.y - centre.y) - Math.hypot(b.at.x - centre.x, b.at.y - centre.y));
    const { p, at } = onScreen[0];
    const x = Math.round((at.x - r.left) * c.width / r.width), y = Math.round((at.y - r.top) * c.height / r.height);
    const g = document.createElement('canvas');
    g.width = 5; g.height = 5;
    g.getContext('2d').drawImage(c, x - 2, y - 2, 5, 5, 0, 0, 5, 5);
    const d = g.getContext('2d').getImageData(0, 0, 5, 5).data, sum = [0, 0, 0];
    for (let i = 0; i < d.length; i += 4) for (let k = 0; k < 3; ++k) sum[k] += d[i + k] / 25;
    return { rgb: sum.map(Math.round), x, y, point: p, screen: at };
  }, near);
  const [red, green, blue] = seen?.rgb ?? [0, 0, 0];
  check(seen && green > red + 10 && green > blue + 10, 'the height field is on screen in its grass green',
        seen ? `rgb ${seen.rgb.join(' ')} at pixel ${seen.x},${seen.y} (the bowl at ${seen.point.map((x) => x.toFixed(2)).join(' ')})` : 'no point of its near slope on screen clear of the balls');
  // Bounding boxes: one a body, the bowl and the pyramid too (there is no plane).
  await tpage.click('#ov-boxes');
  const tboxes = await tpage.evaluate(() => window.__viewer.boxCount());
  check(tboxes === tj.bodies, 'bounding boxes: one a body, level geometry included', `${tboxes} boxes, ${tj.bodies} bodies`);
  await tpage.click('#ov-boxes');
  if (images) { await sleep(1500); await tpage.screenshot({ path: join(images, 'viewer_terrain.png') }); }
  // A click on the bowl picks nothing (it is the ground); shift-click spawns a box onto it (the
  // scene has balls only: the server adds a box to spawn).
  const onSlope = await tpage.evaluate((p) => window.__viewer.screenOfPoint(p), seen?.point ?? near[0]);
  await tpage.mouse.click(onSlope.x, onSlope.y);
  check((await tpage.evaluate(() => window.__viewer.selected())) === null, 'a click on the height field picks no body');
  const tBefore = await tpage.evaluate(() => window.__viewer.instanceCount());
  await tpage.keyboard.down('Shift');
  await tpage.mouse.click(onSlope.x, onSlope.y);
  await tpage.keyboard.up('Shift');
  await until('the spawned box', async () => (await tpage.evaluate(() => window.__viewer.instanceCount())) === tBefore + 1, 5000).catch(() => null);
  check((await tpage.evaluate(() => window.__viewer.instanceCount())) === tBefore + 1 && /spawned body \d+ \(box\)/.test(await tpage.evaluate(() => window.__viewer.status())),
        'shift-click on the height field spawns a box', await tpage.evaluate(() => window.__viewer.status()));
  // Offline: a trajectory of the scene, dropped with the scene file, draws the same triangles as the server sent.
  const tdir = mkdtempSync(join(tmpdir(), 'cellphys-viewer-terrain-'));
  const tcsv = join(tdir, 'terrain.csv');
  execFileSync(exe, ['run', terrainFile, '--duration', '0.5', '--out', tcsv, '--every', '6'], { stdio: ['ignore', 'ignore', 'inherit'] });
  await tpage.setInputFiles('#file', [tcsv, terrainFile]);
  await until('the terrain file to load', () => tpage.evaluate(() => window.__viewer.source() === 'file'));
  const offline = await tpage.evaluate(() => ({ surfaces: window.__viewer.surfaces(), instances: window.__viewer.instanceCount(), status: window.__viewer.status() }));
  const offBowl = offline.surfaces.find((d) => d.type === 6), offPyramid = offline.surfaces.find((d) => d.type === 5);
  check(offline.instances === terrainScene.bodies.length && offBowl && offPyramid && sameTriangles(offBowl.triangles, drawnBowl.triangles) &&
        sameTriangles(offPyramid.triangles, drawnPyramid.triangles),
        'from the scene file, the bowl and the pyramid are drawn with the triangles the server sent', `${offline.instances} instances; ${offline.status}`);
  await tpage.close();
  terrain.stop();
  rmSync(tdir, { recursive: true, force: true });

  // ---- compounds: a table, a dumbbell, a lamp and a static arch, each one body drawn as its parts ----
  const compoundFile = join(here, 'compounds.json');
  const compoundScene = JSON.parse(readFileSync(compoundFile, 'utf8'));
  // What the scene says, worked out here: each compound's parts in its body frame, the frame
  // centred on the parts' centre of mass at uniform density as the engine centres it (the volumes
  // in closed form; the lamp's hull is a tetrahedron, a b c / 6, centred on its own centroid).
  const sceneShapes = new Map(compoundScene.shapes.map((s) => [s.name, s]));
  const unitVolume = (s) => s.type === 'sphere' ? 4 / 3 * Math.PI * s.radius ** 3
    : s.type === 'box' ? 8 * s.half_extents[0] * s.half_extents[1] * s.half_extents[2]
    : s.type === 'capsule' ? Math.PI * s.radius ** 2 * 2 * s.half_height + 4 / 3 * Math.PI * s.radius ** 3
    : s.type === 'hull' ? Math.abs(s.points[1][0] * s.points[2][1] * s.points[3][2]) / 6 : NaN;
  const expectedParts = new Map();
  for (const s of compoundScene.shapes.filter((x) => x.type === 'compound')) {
    const parts = s.parts.map((p) => {
      const q = p.orientation ?? [1, 0, 0, 0], n = Math.hypot(...q);
      return { shape: sceneShapes.get(p.shape), position: p.position ?? [0, 0, 0], orientation: q.map((x) => x / n), scale: p.scale ?? 1 };
    });
    const volumes = parts.map((p) => unitVolume(p.shape) * p.scale ** 3), V = volumes.reduce((a, b) => a + b, 0);
    const com = [0, 1, 2].map((k) => parts.reduce((a, p, i) => a + volumes[i] * p.position[k], 0) / V);
    expectedParts.set(s.name, parts.map((p) => ({ ...p, position: p.position.map((x, k) => x - com[k]) })));
  }
  const qmul = (q, r) => [q[0] * r[0] - q[1] * r[1] - q[2] * r[2] - q[3] * r[3], q[0] * r[1] + q[1] * r[0] + q[2] * r[3] - q[3] * r[2],
    q[0] * r[2] - q[1] * r[3] + q[2] * r[0] + q[3] * r[1], q[0] * r[3] + q[1] * r[2] - q[2] * r[1] + q[3] * r[0]];
  const qrot = (q, v) => qmul(qmul(q, [0, ...v]), [q[0], -q[1], -q[2], -q[3]]).slice(1);
  const TYPE = { sphere: 0, capsule: 1, box: 2, hull: 3 };
  // Live, a body's id is its index in the scene (the server numbers them in order); from a trajectory, its label.
  const compoundBodies = compoundScene.bodies.map((b, index) => ({ ...b, index })).filter((b) => sceneShapes.get(b.shape).type === 'compound');
  const liveId = (label) => compoundScene.bodies.findIndex((b) => b.id === label);
  const partCount = compoundBodies.reduce((n, b) => n + expectedParts.get(b.shape).length, 0);
  const wantInstances = compoundScene.bodies.length - compoundBodies.length + partCount;
  // Every compound's drawn parts against the scene's, at the pose the page shows the body at:
  // each part's type, position (to 0.1 mm), orientation (to 1e-4, either sign) and scale.
  async function checkCompounds(pg, where, live) {
    const got = await pg.evaluate((ids) => ids.map((id) => ({ id, body: window.__viewer.bodyState(id), parts: window.__viewer.drawnParts(id) })),
      compoundBodies.map((b) => (live ? b.index : b.id)));
    const bad = [];
    for (const g of got) {
      const { body, parts } = g, sb = compoundBodies.find((b) => (live ? b.index : b.id) === g.id), id = g.id = sb.id, want = expectedParts.get(sb.shape), sc = sb.scale ?? 1;
      if (!body || !parts || parts.length !== want.length) { bad.push(`${id}: ${parts?.length} parts drawn, ${want.length} in the scene`); continue; }
      want.forEach((w, k) => {
        const p = parts[k], at = qrot(body.orientation, w.position.map((x) => x * sc)).map((x, i) => x + body.position[i]);
        const q = qmul(body.orientation, w.orientation), dot = Math.abs(q.reduce((a, x, i) => a + x * p.orientation[i], 0));
        const off = Math.max(...at.map((x, i) => Math.abs(x - p.position[i])));
        if (p.type !== TYPE[w.shape.type] || off > 1e-4 || dot < 1 - 1e-4 || Math.abs(p.scale - sc * w.scale) > 1e-5)
          bad.push(`${id} part ${k}: ${JSON.stringify(p)}, want at ${JSON.stringify(at)} scale ${sc * w.scale} (off ${off.toExponential(2)})`);
      });
    }
    check(bad.length === 0, `${where}: every compound is drawn as its parts, each at its part pose about the body's centre of mass`,
          bad.length ? bad.join('; ') : `${got.length} compounds, ${partCount} parts`);
    return got;
  }
  // A body's world box from the drawn parts' poses, worked out here for boxes, spheres and capsules.
  function partsBox(parts, want) {
    const lo = [Infinity, Infinity, Infinity], hi = [-Infinity, -Infinity, -Infinity];
    parts.forEach((p, k) => {
      const s = want[k].shape, axis = (i) => qrot(p.orientation, [0, 1, 2].map((j) => (j === i ? 1 : 0)));
      const half = [0, 1, 2].map((i) => s.type === 'box' ? p.scale * [0, 1, 2].reduce((a, j) => a + Math.abs(axis(j)[i]) * s.half_extents[j], 0)
        : s.type === 'sphere' ? p.scale * s.radius : p.scale * (Math.abs(axis(2)[i]) * s.half_height + s.radius));
      for (let i = 0; i < 3; ++i) { lo[i] = Math.min(lo[i], p.position[i] - half[i]); hi[i] = Math.max(hi[i], p.position[i] + half[i]); }
    });
    return { min: lo, max: hi };
  }
  const compounds = await serve([compoundFile]);
  servers.push(compounds);
  const cpg = await openPage(compounds.url, 'compounds'); // no token: a click picks, it does not drag
  const cj = await cpg.evaluate(() => window.__viewer.join());
  check(cj.bodies === compoundScene.bodies.length && (await cpg.evaluate(() => window.__viewer.instanceCount())) === wantInstances,
        'compounds: one instance a part of each compound, one a body of the others', `${await cpg.evaluate(() => window.__viewer.instanceCount())} instances, want ${wantInstances}`);
  await until('the compounds to settle', async () => (await metrics(compounds, 'compounds')).bodies_awake === 0, 10000).catch(() => null);
  await sleep(300);
  const liveParts = await checkCompounds(cpg, 'live', true);
  // Boxes: one a body but the plane; a compound's the union of its parts' (table and dumbbell).
  await cpg.click('#ov-boxes');
  const cboxes = await cpg.evaluate(() => window.__viewer.boxCount());
  check(cboxes === compoundScene.bodies.length - 1, 'compounds: bounding boxes, one a body but the ground plane', `${cboxes} boxes`);
  for (const id of ['table', 'dumbbell']) {
    const drawnNow = await cpg.evaluate((i) => ({ box: window.__viewer.boxOf(i), parts: window.__viewer.drawnParts(i) }), liveId(id));
    const want = partsBox(drawnNow.parts, expectedParts.get(compoundBodies.find((b) => b.id === id).shape));
    const off = Math.max(...[0, 1, 2].flatMap((i) => [Math.abs(drawnNow.box.min[i] - want.min[i]), Math.abs(drawnNow.box.max[i] - want.max[i])]));
    check(off < 1e-5, `the ${id}'s box is the union of its parts' boxes`, `${JSON.stringify(drawnNow.box)} (off ${off.toExponential(2)})`);
  }
  await cpg.click('#ov-boxes');
  // Picking meets the parts: a click on a front leg picks the table, and the selected table draws
  // every part yellow (its top and that leg on screen); a click inside the dumbbell's box but off
  // its parts (above its bar, between the balls) picks nothing.
  const table = liveParts.find((g) => g.id === 'table'), dumbbell = liveParts.find((g) => g.id === 'dumbbell');
  const frontLeg = table.parts.slice(1).reduce((a, p) => (p.position[1] < a.position[1] || (p.position[1] === a.position[1] && p.position[0] > a.position[0]) ? p : a));
  const topFace = [table.parts[0].position[0], table.parts[0].position[1], table.parts[0].position[2] + 0.04];
  const pixelAt = (pg, v) => pg.evaluate((p) => {
    const c = document.getElementById('view'), r = c.getBoundingClientRect(), at = window.__viewer.screenOfPoint(p);
    const x = Math.round((at.x - r.left) * c.width / r.width), y = Math.round((at.y - r.top) * c.height / r.height);
    const g = document.createElement('canvas');
    g.width = 3; g.height = 3;
    g.getContext('2d').drawImage(c, x - 1, y - 1, 3, 3, 0, 0, 3, 3);
    const d = g.getContext('2d').getImageData(0, 0, 3, 3).data, sum = [0, 0, 0];
    for (let i = 0; i < d.length; i += 4) for (let k = 0; k < 3; ++k) sum[k] += d[i + k] / 9;
    return sum.map(Math.round);
  }, v);
  const yellow = ([r, g, b]) => r > b + 50 && g > b + 40;
  const unpicked = [await pixelAt(cpg, topFace), await pixelAt(cpg, frontLeg.position)];
  const legAt = await cpg.evaluate((p) => window.__viewer.screenOfPoint(p), frontLeg.position);
  await cpg.mouse.click(legAt.x, legAt.y);
  check((await cpg.evaluate(() => window.__viewer.selected())) === liveId('table'), 'a click on a leg picks the table', `at ${legAt.x.toFixed(0)},${legAt.y.toFixed(0)}`);
  await sleep(300);
  const after = [await pixelAt(cpg, topFace), await pixelAt(cpg, frontLeg.position)];
  check(!unpicked.some(yellow) && after.every(yellow), 'the picked table is drawn yellow, its top and its leg where they should be',
        `top rgb ${unpicked[0].join(" ")} -> ${after[0].join(" ")}, leg ${unpicked[1].join(" ")} -> ${after[1].join(" ")}`);
  check(/compound of 5 parts/.test(await cpg.evaluate(() => window.__viewer.selection())), 'the pick panel names a compound of 5 parts', (await cpg.evaluate(() => window.__viewer.selection())).split('\n')[0]);
  if (images) await cpg.screenshot({ path: join(images, 'viewer_compounds.png') });
  const dbBody = dumbbell.body, gap = qrot(dbBody.orientation, [0, 0, 0.12]).map((x, i) => x + dbBody.position[i]);
  const gapAt = await cpg.evaluate((p) => window.__viewer.screenOfPoint(p), gap);
  await cpg.mouse.click(gapAt.x, gapAt.y);
  check((await cpg.evaluate(() => window.__viewer.selected())) === null, "a click inside the dumbbell's box, off its parts, picks nothing", `at ${gap.map((x) => x.toFixed(3)).join(' ')}`);
  const dbCentre = await cpg.evaluate((p) => window.__viewer.screenOfPoint(p), dumbbell.parts[0].position);
  await cpg.mouse.click(dbCentre.x, dbCentre.y);
  check((await cpg.evaluate(() => window.__viewer.selected())) === liveId('dumbbell'), 'a click on a ball of the dumbbell picks it');
  // A client of an older revision (one that gives none, as every client before revision 4) is
  // told in an error message, and the connection closed, rather than sent a join it would misread.
  const oldClient = await cpg.evaluate(() => new Promise((resolve) => {
    const ws = new WebSocket(`ws://${location.host}/ws?world=compounds`), got = [];
    ws.binaryType = 'arraybuffer';
    ws.onmessage = (e) => {
      const dv = new DataView(e.data), fb = dv.getUint16(16, true), rb = dv.getUint16(18, true), t = (a, n) => new TextDecoder().decode(new Uint8Array(e.data, a, n));
      got.push({ type: dv.getUint16(4, true), code: dv.getUint16(14, true), field: t(24, fb), reason: t(24 + fb, rb) });
    };
    ws.onclose = (e) => resolve({ got, code: e.code, reason: e.reason });
  }));
  check(oldClient.got.length === 1 && oldClient.got[0].type === 4 && oldClient.got[0].field === 'revision' && /revision=4/.test(oldClient.got[0].reason) &&
        oldClient.code === 1008 && /revision 4/.test(oldClient.reason),
        'a client that gives no revision gets an error naming the revision it needs, then a close, and no join', JSON.stringify(oldClient));
  // Offline: a trajectory of the scene with the scene file: the parts centred here as the engine
  // centres them, at the same places.
  const cdir = mkdtempSync(join(tmpdir(), 'cellphys-viewer-compounds-'));
  const ccsv = join(cdir, 'compounds.csv');
  execFileSync(exe, ['run', compoundFile, '--duration', '0.5', '--out', ccsv, '--every', '6'], { stdio: ['ignore', 'ignore', 'inherit'] });
  await cpg.setInputFiles('#file', [ccsv, compoundFile]);
  await until('the compounds file to load', () => cpg.evaluate(() => window.__viewer.source() === 'file'));
  await cpg.evaluate(() => { const s = document.getElementById('scrub'); s.value = s.max; s.dispatchEvent(new Event('input')); });
  check((await cpg.evaluate(() => window.__viewer.instanceCount())) === wantInstances, 'trajectory: one instance a part of each compound, as live',
        `${await cpg.evaluate(() => window.__viewer.instanceCount())} instances, ${await cpg.evaluate(() => window.__viewer.status())}`);
  await checkCompounds(cpg, 'trajectory', false);
  await cpg.click('#ov-boxes');
  check((await cpg.evaluate(() => window.__viewer.boxCount())) === compoundScene.bodies.length - 1, 'trajectory: a box for every compound');
  await cpg.click('#ov-boxes');
  await cpg.close();
  compounds.stop();
  rmSync(cdir, { recursive: true, force: true });

  // ---- offline: a trajectory CSV scrubbed to a tick ----
  const dir = mkdtempSync(join(tmpdir(), 'cellphys-viewer-csv-'));
  const csv = join(dir, 'pile.csv');
  execFileSync(exe, ['run', 'pile65', '--duration', '1', '--out', csv, '--every', '6'], { env: { ...process.env, CELLPHYS_SCENES: scenesDir }, stdio: ['ignore', 'ignore', 'inherit'] });
  const rows = readFileSync(csv, 'utf8').trim().split('\n').slice(1).map((l) => l.split(','));
  const steps = [...new Set(rows.map((r) => Number(r[0])))];
  const pick = steps[Math.floor(steps.length / 2)];
  const row = rows.find((r) => Number(r[0]) === pick && r[2] === 'box07');
  const opage = await openPage(pile.url, 'offline');
  await opage.setInputFiles('#file', [csv, join(scenesDir, 'pile65.json')]);
  await until('the file to load', () => opage.evaluate(() => window.__viewer.source() === 'file'));
  check((await opage.evaluate(() => window.__viewer.frameCount())) === steps.length, 'one frame a step written', `${steps.length} steps in the CSV`);
  const idx = steps.indexOf(pick);
  await opage.evaluate((i) => { const s = document.getElementById('scrub'); s.value = String(i); s.dispatchEvent(new Event('input')); }, idx);
  const shown = await opage.evaluate(() => ({ step: window.__viewer.step(), body: window.__viewer.bodyState('box07'), drawn: window.__viewer.drawnPosition('box07') }));
  const want = row.slice(3, 6).map(Number);
  const close = (a) => a && a.every((x, k) => Math.abs(x - want[k]) <= 1e-6 * Math.max(1, Math.abs(want[k])));
  check(shown.step === pick, 'scrubbed to the tick', `step ${shown.step}, wanted ${pick}`);
  check(close(shown.body.position) && close(shown.drawn), "the scrubbed frame shows that tick's position", `box07 at ${JSON.stringify(shown.drawn)}, CSV ${JSON.stringify(want)}`);
  check((await opage.evaluate(() => window.__viewer.instanceCount())) === 70, 'the scene file adds its static bodies', 'pile65: 65 boxes, ground, 4 walls');
  await opage.close();
  rmSync(dir, { recursive: true, force: true });

  // ---- a recording of a real `cellphys serve --record` run (a spawn, then a reset), opened and scrubbed ----
  const recDir = mkdtempSync(join(tmpdir(), 'cellphys-viewer-rec-'));
  const rec = join(recDir, 'pile.rec');
  const recording = await serve(['pile65', '--record', rec, '--record-debug', 'on']);
  const rpage = await openPage(`${recording.url}?token=${recording.token}`, 'recorded');
  await rpage.keyboard.down('Shift');
  await rpage.mouse.click(...(await rpage.evaluate(() => [innerWidth * 0.3, innerHeight * 0.85])));
  await rpage.keyboard.up('Shift');
  await until('the spawned box', async () => /spawned body/.test(await rpage.evaluate(() => window.__viewer.status())), 5000);
  await sleep(700);
  await rpage.click('#reset');
  await until('the reset', async () => (await rpage.evaluate(() => window.__viewer.join().epoch)) === 1, 5000);
  await sleep(700);
  await rpage.close();
  await new Promise((r) => { recording.proc.on('exit', r); recording.stop(); });
  const traj = join(recDir, 'replayed.csv');
  const replayed = execFileSync(exe, ['replay', rec, '--out', traj], { encoding: 'utf8' });
  const framesMatched = Number(/(\d+) frames and \d+ stages and (\d+) debug messages matched/.exec(replayed)?.[1]);
  const debugMatched = Number(/(\d+) debug messages matched/.exec(replayed)?.[1]);
  check(framesMatched > 60 && debugMatched === framesMatched && / 2 commands/.test(replayed), 'cellphys replay re-made every recorded frame and its debug message', replayed.split('\n')[0]);
  // The replayed trajectory by epoch (a reset takes the step counter back), step and body id.
  const replayedAt = [new Map()];
  let lastRowStep = -1;
  for (const l of readFileSync(traj, 'utf8').trim().split('\n').slice(1)) {
    const f = l.split(',');
    if (Number(f[0]) < lastRowStep) replayedAt.push(new Map());
    lastRowStep = Number(f[0]);
    const at = replayedAt[replayedAt.length - 1];
    if (!at.has(f[0])) at.set(f[0], new Map());
    at.get(f[0]).set(f[2], f.slice(3, 6).map(Number));
  }
  const vpage = await openPage(pile.url, 'recording');
  await vpage.setInputFiles('#file', rec);
  await until('the recording to load', () => vpage.evaluate(() => window.__viewer.source() === 'recording'));
  const rcount = await vpage.evaluate(() => window.__viewer.frameCount());
  check(rcount === framesMatched, 'the timeline holds every frame of the recording', `${rcount} frames in the page, ${framesMatched} replayed`);
  const scrubTo = (i) => vpage.evaluate((k) => { const s = document.getElementById('scrub'); s.value = String(k); s.dispatchEvent(new Event('input')); return window.__viewer.step(); }, i);
  const epochs = await vpage.evaluate(() => window.__viewer.frameEpochs());
  const firstStep = await scrubTo(0), lastStep = await scrubTo(rcount - 1);
  check(firstStep === 0 && replayedAt.length === 2 && epochs[0] === 0 && epochs[rcount - 1] === 1 && replayedAt[1].has(String(lastStep)),
        'it scrubs from the first frame to the last, across the reset', `steps ${firstStep} to ${lastStep}, epochs ${epochs[0]} to ${epochs[rcount - 1]}`);
  // The last tick before the reset (the spawned box in it) and one in the middle of the epoch after:
  // every body where cellphys replay puts it at that step, and drawn once, there.
  const beforeReset = epochs.lastIndexOf(0), afterReset = Math.floor((epochs.indexOf(1) + rcount) / 2);
  for (const [index, epoch] of [[beforeReset, 0], [afterReset, 1]]) {
    const step = await scrubTo(index);
    const want = replayedAt[epoch].get(String(step));
    const ids = [...want.keys()];
    const shown = await vpage.evaluate((list) => ({
      states: list.map((id) => window.__viewer.bodyState(Number(id))?.position ?? null),
      drawn: list.map((id) => window.__viewer.drawnPosition(Number(id))), instances: window.__viewer.instanceCount(),
    }), ids);
    const same = (p, id) => p && p.every((x, c) => x === Math.fround(want.get(id)[c]));
    const wrong = ids.filter((id, k) => !same(shown.states[k], id) || !same(shown.drawn[k], id));
    check(want.size >= 70 && shown.instances === want.size && wrong.length === 0,
          `epoch ${epoch}: the scrubbed frame draws every body at replay's position for that step`,
          `step ${step}: ${want.size} bodies replayed, ${shown.instances} drawn, ${wrong.length} differ${wrong.length ? ` (body ${wrong[0]}: ${JSON.stringify(shown.drawn[ids.indexOf(wrong[0])])} vs ${JSON.stringify(want.get(wrong[0]))})` : ''}`);
  }
  // Recorded with --record-debug on: a scrubbed frame's contact overlay is its own step's.
  await vpage.click('#ov-contacts');
  const recDebug = await vpage.evaluate(() => {
    const v = window.__viewer, s = document.getElementById('scrub');
    s.value = String(Math.floor(v.frameCount() / 3));
    s.dispatchEvent(new Event('input'));
    return { step: v.step(), debug: v.debug(), markers: v.contactMarkers() };
  });
  check(recDebug.debug && recDebug.debug.step === recDebug.step && recDebug.markers > 0 && recDebug.markers === recDebug.debug.contacts,
        "a recording's frame shows its own step's contacts", `step ${recDebug.step}, debug of step ${recDebug.debug?.step}, ${recDebug.markers} markers for ${recDebug.debug?.contacts} contacts`);
  await vpage.click('#ov-contacts');
  const recordedStages = await vpage.evaluate(() => window.__viewer.stageChart());
  const recLegend = await legendOf(vpage);
  check(recordedStages.points > 10 && JSON.stringify([...recLegend].sort()) === JSON.stringify(serverStages),
        "the recording's stage timings in the stage chart", `${recordedStages.points} points, ${recLegend.join(' ')}`);
  // A recording cut short (a server killed mid-write) shows up to its last whole record, and says so.
  // The cut falls strictly inside the record that holds the file's middle byte (a cut on a
  // record boundary is a whole recording that lacks its end record, a different warning).
  const recBytes = readFileSync(rec);
  let recordAt = 16;
  while (recordAt + 16 + recBytes.readUInt32LE(recordAt + 4) <= recBytes.length / 2) recordAt += 16 + recBytes.readUInt32LE(recordAt + 4);
  await vpage.setInputFiles('#file', { name: 'cut.rec', mimeType: 'application/octet-stream', buffer: recBytes.subarray(0, recordAt + 16 + 1) });
  await until('the cut recording', async () => /^cut\.rec:/.test(await vpage.evaluate(() => window.__viewer.status())), 5000).catch(() => null);
  const cutShort = await vpage.evaluate(() => ({ text: window.__viewer.status(), frames: window.__viewer.frameCount() }));
  check(/warning: record \d+ \(byte \d+\) is cut short/.test(cutShort.text) && cutShort.frames > 10 && cutShort.frames < rcount,
        'a recording cut short plays up to its last whole record, with a warning', `${cutShort.frames} frames: ${cutShort.text}`);
  // Files that are not recordings this page can draw: a clear message in the page.
  for (const [bytes, wanted, what] of [
    [Buffer.from('CELLREC1\x09\0\0\0\x01\0\0\0', 'latin1'), /bad\.rec: recording version 9 is not one this viewer reads/, 'an unknown version'],
    [Buffer.from('not a recording at all', 'latin1'), /bad\.rec: not a cellphys recording/, 'not a recording'],
    [readFileSync(rec).subarray(0, 40), /bad\.rec: the recording has no sound world record \(record 0 \(byte 16\) is cut short/, 'cut in its first record'],
  ]) {
    await vpage.setInputFiles('#file', { name: 'bad.rec', mimeType: 'application/octet-stream', buffer: bytes });
    await until(`the page to refuse ${what}`, async () => wanted.test(await vpage.evaluate(() => window.__viewer.status())), 5000).catch(() => null);
    const st = await vpage.evaluate(() => ({ text: window.__viewer.status(), err: document.getElementById('status').className === 'err' }));
    check(wanted.test(st.text) && st.err, `a recording that is ${what} is refused in the page`, st.text);
  }
  await vpage.close();
  rmSync(recDir, { recursive: true, force: true });

  check(consoleErrors.length === 0, 'no console error on any page', consoleErrors.join(' | '));
} catch (e) {
  check(false, 'viewer test ran to the end', e.stack || String(e));
} finally {
  await launched.close();
  for (const s of servers) s.stop();
}
console.log(failures ? `viewer_test: ${failures} check(s) failed` : 'viewer_test: all checks passed');
process.exit(failures ? 1 : 0);
