// Bundles the page into dist/ (main.js, main.css, index.html): everything it loads is its own.
import { copyFileSync, mkdirSync, rmSync, renameSync } from 'node:fs';
import { dirname, join } from 'node:path';
import { fileURLToPath } from 'node:url';

const here = dirname(fileURLToPath(import.meta.url));
const { build } = await import('esbuild').catch(() => {
  console.error(`viewer: esbuild is not installed in ${join(here, 'node_modules')} (scripts/setup runs npm ci there)`);
  process.exit(1);
});
const out = join(here, 'dist');
const tmp = join(here, 'dist.tmp');
rmSync(tmp, { recursive: true, force: true });
mkdirSync(tmp, { recursive: true });
await build({
  entryPoints: [join(here, 'src/main.js')],
  bundle: true, minify: true, sourcemap: true, format: 'iife', target: 'es2020',
  outfile: join(tmp, 'main.js'), logLevel: 'warning',
});
copyFileSync(join(here, 'src/index.html'), join(tmp, 'index.html'));
// Replace dist only once the whole build has succeeded: never a half-written viewer.
rmSync(out, { recursive: true, force: true });
renameSync(tmp, out);
console.log(`viewer: built ${out}`);
