// What the viewer's browser test and its frame-cost benchmark share: `cellphys serve` on a free
// port, and Debian's Chromium, headless with software WebGL, driven by playwright-core.
import { spawn } from 'node:child_process';
import { existsSync, mkdtempSync, rmSync } from 'node:fs';
import { tmpdir } from 'node:os';
import { join } from 'node:path';
import { createInterface } from 'node:readline';

export const CHROMIUM = '/usr/bin/chromium';

/// `cellphys serve ARGS --port 0`; resolves with its URL and token from the first two lines.
export function serve(exe, args, { viewerDir, scenesDir }) {
  return new Promise((resolveServe, reject) => {
    const p = spawn(exe, ['serve', ...args, '--port', '0', '--viewer', viewerDir], { stdio: ['ignore', 'pipe', 'inherit'], env: { ...process.env, CELLPHYS_SCENES: scenesDir } });
    const lines = [];
    const rl = createInterface({ input: p.stdout });
    rl.on('line', (l) => {
      lines.push(l);
      if (lines.length === 2) {
        const url = /^listening on (http:\/\/\S+)$/.exec(lines[0])?.[1], token = /^token (\S+)$/.exec(lines[1])?.[1];
        if (!url || !token) reject(new Error(`unexpected server output: ${lines.join(' | ')}`));
        else resolveServe({ url, token, proc: p, stop: () => { p.kill('SIGTERM'); } });
      }
    });
    p.on('exit', (code) => { if (lines.length < 2) reject(new Error(`cellphys serve exited with ${code} before printing its URL`)); });
  });
}

/// Chromium with a fresh profile; `close()` closes it and removes the profile. Null when playwright-core
/// or Chromium is missing (the caller says why).
export async function launchBrowser(viewport = { width: 1280, height: 800 }) {
  if (!existsSync(CHROMIUM)) return null;
  const { chromium } = await import('playwright-core');
  const userData = mkdtempSync(join(tmpdir(), 'cellphys-viewer-chromium-'));
  const context = await chromium.launchPersistentContext(userData, {
    executablePath: CHROMIUM,
    headless: true,
    viewport,
    args: ['--headless', '--no-sandbox', '--disable-gpu', '--disable-quic', '--no-first-run', '--disable-background-networking',
      '--disable-component-update', '--disable-sync',
      // WebGL without a GPU: Chromium's software rasteriser, which it no longer falls back to unasked.
      '--use-angle=swiftshader', '--enable-unsafe-swiftshader'],
  });
  return { context, close: async () => { await context.close(); rmSync(userData, { recursive: true, force: true }); } };
}
