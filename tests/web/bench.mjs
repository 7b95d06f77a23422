// Benchmark of the web path tracer in headless Chromium (SwiftShader here): frame time at
// 640x480, 1 sample per pixel per frame, and navigation-to-first-frame with a cold and a warm
// client cache, per scene, with bundle sizes. Ratios are against the Cornell box measured in
// the same run (the machine is shared: compare ratios, not absolute times, across runs).
//
//   node tests/web/bench.mjs --lightport target/release/lightport [--frames 5] [--size 640x480]
//
// Needs web/pkg (scripts/build-web.sh) and `npm ci` in tests/web.

import { spawn, execFileSync } from 'node:child_process';
import { createInterface } from 'node:readline';
import { readFileSync, rmSync } from 'node:fs';
import { tmpdir } from 'node:os';
import { join, dirname } from 'node:path';
import { fileURLToPath } from 'node:url';

const here = dirname(fileURLToPath(import.meta.url));
const root = join(here, '../..');
const args = Object.fromEntries(process.argv.slice(2).reduce((pairs, a, i, all) => {
  if (a.startsWith('--')) pairs.push([a.slice(2), all[i + 1]]);
  return pairs;
}, []));
const lightport = args.lightport || join(root, 'target/release/lightport');
const size = args.size || '640x480';
const frames = args.frames || '5';
const shared = join(root, '../shared/scenes');
const scenePaths = [
  'khronos/Avocado/glTF/Avocado.gltf',
  'khronos/DamagedHelmet/glTF-Binary/DamagedHelmet.glb',
  'threejs/LittlestTokyo.glb',
].map((p) => join(shared, p));

// Every scene under the same HDR sky (Avocado has no lights of its own).
const sky = join(shared, 'hdri/venice_sunset_1k.hdr');
const server = spawn(lightport, ['serve', '--port', '0', '--sky', sky, ...scenePaths], { stdio: ['ignore', 'pipe', 'inherit'] });
const url = await new Promise((resolve, reject) => {
  const lines = createInterface({ input: server.stdout });
  lines.on('line', (line) => {
    process.stderr.write(`${line}\n`);
    const at = line.indexOf('http://');
    if (at >= 0) resolve(line.slice(at).trim());
  });
  server.on('exit', (code) => reject(new Error(`lightport serve exited (${code}) before printing its URL`)));
});

try {
  const scenes = (await (await fetch(new URL('scenes.json', url))).json()).scenes;
  const out = join(tmpdir(), `lightport-bench-${process.pid}.json`);
  execFileSync('node', [join(here, 'run.mjs'), 'bench', '--url', url, '--out', out, '--size', size, '--frames', frames,
    '--scenes', scenes.map((s) => s.name).join(',')], { stdio: 'inherit' });
  const { results } = JSON.parse(readFileSync(out, 'utf8'));
  rmSync(out, { force: true });
  const baseline = results[0];
  const info = results[0].info;
  console.log(`\nWeb path tracer, headless Chromium: ${info.glRenderer} (${info.glVersion}); ${size}, 1 spp/frame, MIS, depth ${info.maxDepth}, venice_sunset sky; mean of ${frames} frames after 3 warm-up frames.`);
  console.log('Shared, noisy 2-core machine: compare the ratios (same run), not absolute times.\n');
  console.log('| scene | triangles | bundle (raw) | bundle (gzip) | frame (ms) | frames/s | frame vs Cornell | first frame, cold cache (ms) | first frame, warm cache (ms) | warm / cold |');
  console.log('|---|---|---|---|---|---|---|---|---|---|');
  for (const r of results) {
    const s = scenes.find((x) => x.name === r.scene);
    const mb = (n) => `${(n / 1e6).toFixed(2)} MB`;
    console.log(`| ${r.scene} | ${s.triangles.toLocaleString('en')} | ${mb(s.bytes.raw)} | ${mb(s.bytes.gzip)} | ${r.frameMs.toFixed(0)} | ${(1000 / r.frameMs).toFixed(2)} | ${(r.frameMs / baseline.frameMs).toFixed(2)}x | ${r.coldFirstFrameMs.toFixed(0)} | ${r.warmFirstFrameMs.toFixed(0)} | ${(r.warmFirstFrameMs / r.coldFirstFrameMs).toFixed(2)} |`);
    if (r.coldFromCache || !r.warmFromCache) console.log(`  (unexpected: cold visit from cache ${r.coldFromCache}, warm visit from cache ${r.warmFromCache})`);
  }
} finally {
  server.kill();
}
