// Build the page's viewer: bundle src/main.js with three.js (and the fflate inflater it ships)
// and meshoptimizer's decoder (the
// versions pinned in package-lock.json) into one minified classic script (classic, not a module:
// pages opened from file:// may not load modules), with the libraries' licences beside it.
//
//   cd web && npm ci && npm run build     → ../app/web/viewer/viewer.js + LICENSES.txt
//   node build.mjs --out DIR              → the same files into DIR (the tests rebuild and compare)
import { build } from 'esbuild';
import { mkdirSync, readFileSync, writeFileSync } from 'node:fs';
import { dirname, join } from 'node:path';
import { fileURLToPath } from 'node:url';

const here = dirname(fileURLToPath(import.meta.url));
const args = process.argv.slice(2);
const out = args[0] === '--out' ? args[1] : join(here, '..', 'app', 'web', 'viewer');
const LIBS = ['three', 'meshoptimizer'];
const version = (lib) => JSON.parse(readFileSync(join(here, 'node_modules', lib, 'package.json'), 'utf8')).version;
const banner = `/* Anatomesh web viewer (GPL-3.0-or-later) bundled with ${
  LIBS.map((l) => `${l} ${version(l)}`).join(', ')} (MIT): see LICENSES.txt */`;

mkdirSync(out, { recursive: true });
await build({
  entryPoints: [join(here, 'src', 'main.js')],
  bundle: true,
  minify: true,
  format: 'iife',
  target: 'es2020',
  legalComments: 'none',
  banner: { js: banner },
  outfile: join(out, 'viewer.js'),
  logLevel: 'warning',
});

/** The header fflate's file carries (name, licence, version). */
const fflateHeader = () => readFileSync(join(here, 'node_modules', 'three', 'examples', 'jsm', 'libs', 'fflate.module.js'), 'utf8')
  .match(/\/\*!([\s\S]*?)\*\//)[1].trim();
const licence = (lib, file) => readFileSync(join(here, 'node_modules', lib, file), 'utf8').trim();
writeFileSync(join(out, 'LICENSES.txt'), [
  'viewer.js bundles the following libraries, installed from npm (web/package-lock.json).',
  '',
  `== three.js ${version('three')} (https://threejs.org) ==`, licence('three', 'LICENSE'), '',
  `== meshoptimizer ${version('meshoptimizer')} decoder (https://github.com/zeux/meshoptimizer) ==`,
  licence('meshoptimizer', 'LICENSE.md'), '',
  '== fflate (https://github.com/101arrowz/fflate), as three.js bundles it (examples/jsm/libs/fflate.module.js) ==',
  fflateHeader(), '', licence('three', 'LICENSE').replace(/^Copyright.*$/m, 'Copyright (c) Arjun Barrett'), '',
  '== Anatomesh viewer code (web/src) ==',
  'GPL-3.0-or-later, as Anatomesh.', '',
].join('\n'));
