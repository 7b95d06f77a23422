// Benchmark of the web path tracer in headless Chromium (SwiftShader here): frame time at
// 640x480, 1 sample per pixel per frame, and navigation-to-first-frame with a cold and a warm
// client cache, per scene, with bundle sizes. Ratios are against the Cornell box measured in
// the same run (the machine is shared: compare ratios, not absolute times, across runs).
//
//   node tests/web/bench.mjs --lightport target/release/lightport [--frames 5] [--size 640x480]
//        [--apis webgl2,webgpu] [--rounds 1]
//
// Each API (the page's `api=`) runs every scene; the table puts them side by side with the
// WebGPU / WebGL2 frame-time ratio.
//
// Needs web/pkg (scripts/build-web.sh), `npm ci` in tests/web, and the benchmark scenes, which
// are not in the repository: the data folder `../shared` beside it, or `$LIGHTPORT_SHARED`.
// Not part of the test suite.

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
const shared = join(process.env.LIGHTPORT_SHARED || join(root, '../shared'), 'scenes');
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

// Each API in its own pass over the scenes (same browser build, same server), alternated
// `--rounds` times; the table shows per scene and API the median over the rounds.
const apis = (args.apis || 'webgl2,webgpu').split(',');
const rounds = Number(args.rounds || '1');
const median = (v) => [...v].sort((x, y) => x - y)[Math.floor(v.length / 2)];

try {
  const scenes = (await (await fetch(new URL('scenes.json', url))).json()).scenes;
  const runs = {}; // api -> scene -> [row]
  const infos = {};
  for (let round = 0; round < rounds; round++) {
    for (const api of round % 2 ? [...apis].reverse() : apis) {
      const out = join(tmpdir(), `lightport-bench-${process.pid}.json`);
      execFileSync('node', [join(here, 'run.mjs'), 'bench', '--url', url, '--out', out, '--size', size, '--frames', frames,
        '--api', api, '--scenes', scenes.map((s) => s.name).join(',')], { stdio: 'inherit' });
      const { results } = JSON.parse(readFileSync(out, 'utf8'));
      rmSync(out, { force: true });
      for (const r of results) {
        if (r.info.api.toLowerCase() !== api) throw new Error(`${r.scene}: asked for ${api}, ran ${r.info.api}`);
        ((runs[api] ||= {})[r.scene] ||= []).push(r);
        infos[api] = r.info;
      }
    }
  }
  const info = infos[apis[0]];
  console.log(`\nWeb path tracer, headless Chromium: ${apis.map((a) => `${infos[a].api} on ${infos[a].adapter}`).join('; ')}; ${size}, 1 spp/frame, MIS, depth ${info.maxDepth}, venice_sunset sky; mean of ${frames} frames after 3 warm-up frames; medians of ${rounds} alternated round(s).`);
  console.log('Shared, noisy 2-core machine: compare the ratios (same run), not absolute times.\n');
  const head = ['scene', 'triangles', 'bundle (raw)', 'bundle (gzip)'];
  for (const api of apis) head.push(`${api} frame (ms)`, `${api} first frame cold (ms)`, `${api} first frame warm (ms)`);
  if (apis.length === 2) head.push(`frame ${apis[1]} / ${apis[0]}`);
  console.log(`| ${head.join(' | ')} |`);
  console.log(`|${head.map(() => '---').join('|')}|`);
  for (const s of scenes) {
    const mb = (n) => `${(n / 1e6).toFixed(2)} MB`;
    const cells = [s.name, s.triangles.toLocaleString('en'), mb(s.bytes.raw), mb(s.bytes.gzip)];
    const frame = {};
    for (const api of apis) {
      const rows = runs[api][s.name];
      frame[api] = median(rows.map((r) => r.frameMs));
      cells.push(frame[api].toFixed(0), median(rows.map((r) => r.coldFirstFrameMs)).toFixed(0),
        median(rows.map((r) => r.warmFirstFrameMs)).toFixed(0));
      for (const r of rows) {
        if (r.coldFromCache || !r.warmFromCache) console.log(`  (unexpected: ${api} ${s.name}: cold visit from cache ${r.coldFromCache}, warm visit from cache ${r.warmFromCache})`);
      }
    }
    if (apis.length === 2) cells.push(`${(frame[apis[1]] / frame[apis[0]]).toFixed(2)}x`);
    console.log(`| ${cells.join(' | ')} |`);
  }

  // Where the cold first frame's time goes: the page's startup marks (web/www/main.js), as
  // the median duration of each step from the previous mark (the first from navigation start).
  const steps = [['wasm', 'wasm ready'], ['device', 'WebGPU device'], ['scenes', 'scenes.json'],
    ['fetched', 'bundle fetched'], ['installed', 'installed'], ['first', 'first frame on screen']];
  console.log('\nCold first frame, step by step (ms from the previous step; median over rounds):\n');
  const stepHead = ['scene', 'api', ...steps.map(([, label]) => label), 'total'];
  console.log(`| ${stepHead.join(' | ')} |`);
  console.log(`|${stepHead.map(() => '---').join('|')}|`);
  for (const s of scenes) {
    for (const api of apis) {
      const rows = runs[api][s.name];
      const durations = steps.map(([key]) => median(rows.map((r) => {
        const marks = { ...r.coldStartup, first: r.coldFirstFrameMs };
        const at = steps.map(([k]) => marks[k]);
        const i = steps.findIndex(([k]) => k === key);
        if (at[i] === undefined) return NaN;
        const previous = at.slice(0, i).filter((t) => t !== undefined).at(-1) ?? 0;
        return at[i] - previous;
      })));
      const cell = (ms) => (Number.isFinite(ms) ? ms.toFixed(0) : '–');
      console.log(`| ${s.name} | ${api} | ${durations.map(cell).join(' | ')} | ${cell(median(rows.map((r) => r.coldFirstFrameMs)))} |`);
    }
  }
} finally {
  server.kill();
}
