// What the viewer's own work costs a frame, in Debian's Chromium (headless, software WebGL):
// for each world, the ms the page takes to take in a tick (decode, apply, update the instance
// matrices) and the ms of a frame's render call, medians and 95th percentiles over a few seconds
// of a live `cellphys serve` at 60 Hz, with the draw calls a frame. Without a GPU the render call
// includes the software rasteriser's work, so it is an upper bound; the tick's cost and the draw
// calls (one a shape of the dictionary, whatever the number of bodies) are what a GPU does not change.
//   node viewer/bench/frame_cost.mjs CELLPHYS_EXE [--seconds S] [WORLD ...]   (default: pile65 world1000)
import { existsSync } from 'node:fs';
import { dirname, resolve } from 'node:path';
import { fileURLToPath } from 'node:url';
import { launchBrowser, serve } from '../test/harness.mjs';

const here = dirname(fileURLToPath(import.meta.url));
const args = process.argv.slice(2);
const exe = args.shift();
const at = args.indexOf('--seconds');
const seconds = at >= 0 ? Number(args.splice(at, 2)[1]) : 8;
const worlds = args.length ? args : ['pile65', 'world1000'];
if (!exe || !existsSync(exe)) { console.error(`frame_cost: no cellphys executable at "${exe}"`); process.exit(2); }
if (!(seconds > 0)) { console.error('frame_cost: --seconds takes a number above 0'); process.exit(2); }
const dirs = { viewerDir: resolve(here, '..', 'dist'), scenesDir: resolve(here, '..', '..', 'examples', 'scenes') };
if (!existsSync(resolve(dirs.viewerDir, 'index.html'))) { console.error(`frame_cost: no built viewer at ${dirs.viewerDir} (npm run build in viewer/)`); process.exit(2); }

const browser = await launchBrowser();
if (!browser) { console.error('frame_cost: no Chromium at /usr/bin/chromium (scripts/setup installs it)'); process.exit(2); }
const quantile = (v, q) => { const s = [...v].sort((a, b) => a - b); return s.length ? s[Math.min(s.length - 1, Math.floor(q * s.length))] : NaN; };
const f = (x) => x.toFixed(2).padStart(7);
console.log('world        bodies   tick ms (median  p95)   render ms (median  p95)   draw calls   frames/s');
let failed = false;
for (const world of worlds) {
  const server = await serve(exe, [world], dirs);
  try {
    const page = await browser.context.newPage();
    await page.goto(server.url);
    await page.waitForFunction(() => window.__viewer && window.__viewer.ready() && window.__viewer.frameCount() > 5, null, { timeout: 30000 });
    await page.waitForTimeout(2000); // past the first frames' shader compiles
    const drawn0 = await page.evaluate(() => window.__viewer.framesDrawn());
    await page.waitForTimeout(seconds * 1000);
    const r = await page.evaluate(() => ({ ...window.__viewer.cost(), bodies: window.__viewer.join().bodies, drawn: window.__viewer.framesDrawn() }));
    const fps = (r.drawn - drawn0) / seconds;
    console.log(`${world.padEnd(12)} ${String(r.bodies).padStart(6)}        ${f(quantile(r.tick, 0.5))} ${f(quantile(r.tick, 0.95))}` +
                `             ${f(quantile(r.render, 0.5))} ${f(quantile(r.render, 0.95))}   ${String(r.drawCalls).padStart(10)}   ${fps.toFixed(1).padStart(8)}`);
    await page.close();
  } catch (e) {
    console.error(`frame_cost: ${world}: ${e.message}`);
    failed = true;
  } finally {
    server.stop();
  }
}
await browser.close();
process.exit(failed ? 1 : 0);
