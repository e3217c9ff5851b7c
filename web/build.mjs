// Bundle the demo into plain files: node build.mjs --assets DIR --out DIR
//   DIR of --assets: moglow_step.onnx + demo.json, written by `python -m course_lib.export DIR`
//   --out: index.html, demo.js (the code, one classic script), moglow-model.js (model + data), moglow-wasm.js
// The model and onnxruntime's wasm binary travel base64 inside classic scripts: a page opened as a file can
// load neither ES modules nor fetched .wasm, and nothing is fetched at run time.
import { build } from 'esbuild';
import { copyFileSync, mkdirSync, readFileSync, statSync, writeFileSync } from 'node:fs';
import { createRequire } from 'node:module';
import { dirname, join } from 'node:path';
import { fileURLToPath } from 'node:url';

const here = dirname(fileURLToPath(import.meta.url));
const arg = (name, dflt) => { const i = process.argv.indexOf(`--${name}`); return i > 0 ? process.argv[i + 1] : dflt; };
const assets = arg('assets', join(here, '..', 'build', 'web-assets'));
const out = arg('out', join(here, 'dist'));
mkdirSync(out, { recursive: true });

const require = createRequire(import.meta.url);
const wasm = readFileSync(require.resolve('onnxruntime-web/ort-wasm-simd-threaded.wasm'));
const model = readFileSync(join(assets, 'moglow_step.onnx'));
const demo = readFileSync(join(assets, 'demo.json'), 'utf8');

await build({
  entryPoints: [join(here, 'src', 'main.js')], bundle: true, format: 'iife', minify: true, target: 'es2020',
  outfile: join(out, 'demo.js'), logLevel: 'warning', legalComments: 'linked',
  define: { 'import.meta.url': '""' }, // ort asks for its own URL only to find a fetched wasm or workers: neither is used
});
writeFileSync(join(out, 'moglow-wasm.js'), `window.MOGLOW_ASSETS=window.MOGLOW_ASSETS||{};window.MOGLOW_ASSETS.wasm="${wasm.toString('base64')}";\n`);
writeFileSync(join(out, 'moglow-model.js'), `window.MOGLOW_ASSETS=window.MOGLOW_ASSETS||{};window.MOGLOW_ASSETS.model="${model.toString('base64')}";window.MOGLOW_ASSETS.demo=${demo};\n`);
copyFileSync(join(here, 'src', 'index.html'), join(out, 'index.html'));
const files = ['index.html', 'demo.js', 'moglow-model.js', 'moglow-wasm.js'];
const total = files.reduce((s, f) => s + statSync(join(out, f)).size, 0);
console.log(`built ${out}: ${files.map((f) => `${f} ${statSync(join(out, f)).size}`).join(', ')}; ${total} bytes in all`);
