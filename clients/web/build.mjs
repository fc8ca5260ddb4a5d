// Bundles the web client with esbuild into one folder the server serves at /:
// index.html (no-cache) plus content-hashed app-<HASH>.js / app-<HASH>.css
// (cached as immutable). Everything the page needs is in the bundle: it
// loads nothing from the internet at run time.
//
//   node build.mjs [--outdir DIR] [--node-modules DIR]
//   defaults: dist, ./node_modules (the build tree passes its own `npm ci` folder)
import { mkdirSync, readFileSync, rmSync, writeFileSync } from 'node:fs';
import { createRequire } from 'node:module';
import { basename, dirname, join, resolve } from 'node:path';
import { fileURLToPath } from 'node:url';

const here = dirname(fileURLToPath(import.meta.url));
const arg = (name, fallback) => {
  const i = process.argv.indexOf(name);
  return resolve(i > 0 ? process.argv[i + 1] : fallback);
};
const outdir = arg('--outdir', join(here, 'dist'));
const nodeModules = arg('--node-modules', join(here, 'node_modules'));
const esbuild = createRequire(join(nodeModules, 'index.js'))('esbuild');

rmSync(outdir, { recursive: true, force: true });
mkdirSync(outdir, { recursive: true });

const result = await esbuild.build({
  entryPoints: { app: join(here, 'src/main.js') },
  bundle: true,
  format: 'esm',
  target: ['es2020'],
  minify: true,
  sourcemap: false,
  entryNames: '[name]-[hash]',
  outdir,
  metafile: true,
  nodePaths: [nodeModules],
  logLevel: 'warning',
});

const outputs = Object.keys(result.metafile.outputs).map((p) => basename(p));
const js = outputs.find((f) => f.endsWith('.js'));
const css = outputs.find((f) => f.endsWith('.css'));
if (!js || !css) throw new Error(`bundle incomplete: ${outputs.join(', ')}`);
const html = readFileSync(join(here, 'src/index.html'), 'utf8')
  .replace('%APP_JS%', js)
  .replace('%APP_CSS%', css);
writeFileSync(join(outdir, 'index.html'), html);
console.log(`fesbench web client: ${outdir}/{index.html,${js},${css}}`);
