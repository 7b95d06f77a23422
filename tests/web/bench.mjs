// Benchmark of the web path tracer in headless Chromium (SwiftShader here): frame time at
// 640x480, 1 sample per pixel per frame, and navigation to the first image (the preview, a
// quarter of each side: web/src/runtime/preview.rs) and to the first full-resolution frame with
// a cold and a warm client cache, per scene, with bundle sizes; the first frame's time split
// into download, decode, upload, compile, the preview's GPU time and the first frame's GPU time
// (the page's own accounting, window.lightport.firstImage and firstFrame); and what alpha masks cost: LittlestTokyo as shipped against a
// copy made here with every material's alphaMode removed (opaque), frame time per API. Ratios
// are measured in the same run (the machine is shared: compare ratios, not absolute times,
// across runs).
//
//   node tests/web/bench.mjs --lightport target/release/lightport [--frames 5] [--size 640x480]
//        [--apis webgl2,webgpu] [--rounds 1] [--scenes cornell-box,LittlestTokyo,...] [--depths 8,32]
//        [--auto 1]
//
// `--auto 1`: on WebGPU (`schedule=auto`, the page's default), what the page's own measurement
// of the two schedules chooses per scene (its medians, ratio and choice), after the warm visit's
// frames, one row per round.
//        [--preview 0] [--play SECONDS]
//
// `--preview 0`: the page without the preview (`preview=0`): the first image is the first frame.
//
// An API entry `webgl2:prepare0` (or `webgpu:prepare0`): the page's `prepare=0`, its kernel
// compiled after the bundle's decode instead of while it (web/src/viewer/prepare.rs).
//
// `--play SECONDS`: for each scene that moves (LittlestTokyo), in the warm visit, the frame loop
// with the animation playing at real speed and paused, in turns of that long, alternated
// (animation.mjs's playAndPause): poses, previews and whole frames per second, and the pose's
// host time; medians over turns and rounds.
//
// `--loop SECONDS`: a third visit per scene and API (warm cache) with the frame loop running, as
// a person sees the page (frames in bands; a moving scene's animation paused): its first image
// and first full frame, and its time per frame over that many seconds, beside the frame in one
// submission that the other columns time; and the page's long tasks (a main-thread task over
// 50 ms: a tick that waited for the GPU): their ms between the first image and the first full
// frame, their share of the loop's time after it.
//
// `--band-rows 1,2,4,8`: in the warm visit, a frame in bands of that many rows submitted back to
// back (the test hook's renderFramesInBands), per value, against the frame in one submission:
// what a band costs beyond its rows (2x2 fragment quads and 8x8 workgroups: a band across
// blocks of rows pays for the whole blocks; backend/frame_split.rs). The values are alternated
// with the whole frame, each `--frames` frames.
//
// `--depths 8,32`: the frame time at each path depth (the page's setMaxDepth, in the warm
// visit; the first frames are at the bundle's depth, 8), a column per API and depth.
//
// Each API (the page's `api=`; `webgpu:wavefront` for WebGPU with `schedule=wavefront`) runs
// every scene; the table puts them side by side with each one's frame-time ratio to the first.
//
// Needs web/pkg (scripts/build-web.sh), `npm ci` in tests/web, and the benchmark scenes, which
// are not in the repository: the data folder `../shared` beside it, or `$LIGHTPORT_SHARED`.
// Not part of the test suite.

import { spawn, execFileSync } from 'node:child_process';
import { createInterface } from 'node:readline';
import { mkdtempSync, readFileSync, rmSync, writeFileSync } from 'node:fs';
import { tmpdir } from 'node:os';
import { join, dirname } from 'node:path';
import { fileURLToPath } from 'node:url';
import { median } from './page.mjs';

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

// `glb` with every material's alphaMode (and alphaCutoff) removed: the same scene, opaque. The
// JSON chunk is rewritten (padded with spaces to 4 bytes, as the format requires); the binary
// chunk is copied as it is.
function opaqueGlb(glb) {
  if (glb.readUInt32LE(0) !== 0x46546c67) throw new Error('not a GLB file');
  const jsonLength = glb.readUInt32LE(12);
  if (glb.readUInt32LE(16) !== 0x4e4f534a) throw new Error('the GLB does not start with a JSON chunk');
  const gltf = JSON.parse(glb.subarray(20, 20 + jsonLength).toString('utf8'));
  let masked = 0;
  for (const m of gltf.materials || []) {
    if (m.alphaMode !== undefined && m.alphaMode !== 'OPAQUE') masked++;
    delete m.alphaMode;
    delete m.alphaCutoff;
  }
  if (masked === 0) throw new Error('the GLB has no alpha-masked or blended material: nothing to compare');
  let json = Buffer.from(JSON.stringify(gltf), 'utf8');
  json = Buffer.concat([json, Buffer.alloc((4 - (json.length % 4)) % 4, 0x20)]);
  const rest = glb.subarray(20 + jsonLength);
  const header = Buffer.alloc(20);
  header.writeUInt32LE(0x46546c67, 0);
  header.writeUInt32LE(2, 4);
  header.writeUInt32LE(20 + json.length + rest.length, 8);
  header.writeUInt32LE(json.length, 12);
  header.writeUInt32LE(0x4e4f534a, 16);
  return { bytes: Buffer.concat([header, json, rest]), masked };
}
const maskedScene = join(shared, 'threejs/LittlestTokyo.glb');
const tempDir = mkdtempSync(join(tmpdir(), 'lightport-bench-'));
// Removed however the run ends ('exit' also follows an uncaught error).
process.on('exit', () => rmSync(tempDir, { recursive: true, force: true }));
// Named after the original: `lightport serve` names a scene by its file stem.
const opaqueScene = join(tempDir, 'LittlestTokyo-opaque.glb');
const opaque = opaqueGlb(readFileSync(maskedScene));
writeFileSync(opaqueScene, opaque.bytes);
scenePaths.push(opaqueScene);

// Every scene under the same HDR sky (Avocado has no lights of its own).
const sky = join(shared, 'hdri/venice_sunset_1k.hdr');
// The page and wasm of this checkout (web/www, web/pkg), not those built into the binary.
const server = spawn(lightport, ['serve', '--port', '0', '--web', join(root, 'web'), '--sky', sky, ...scenePaths], { stdio: ['ignore', 'pipe', 'inherit'] });
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

try {
  // `--scenes a,b`: only those (by name; default every served scene).
  const only = args.scenes ? args.scenes.split(',') : null;
  const scenes = (await (await fetch(new URL('scenes.json', url))).json()).scenes
    .filter((s) => !only || only.includes(s.name));
  const runs = {}; // api -> scene -> [row]
  const infos = {};
  for (let round = 0; round < rounds; round++) {
    for (const api of round % 2 ? [...apis].reverse() : apis) {
      const out = join(tmpdir(), `lightport-bench-${process.pid}.json`);
      // `webgl2:prepare0`: the page's `prepare=0` (the kernel compiled after the decode).
      const [pageApi, option] = api.split(':');
      const prepare = option === 'prepare0' ? '0' : undefined;
      const schedule = prepare ? undefined : option;
      execFileSync('node', [join(here, 'run.mjs'), 'bench', '--url', url, '--out', out, '--size', size, '--frames', frames,
        '--api', pageApi, ...(schedule ? ['--schedule', schedule] : []), ...(args.depths ? ['--depths', args.depths] : []),
        ...(args.preview ? ['--preview', args.preview] : []), ...(prepare ? ['--prepare', prepare] : []),
        ...(args.auto ? ['--auto', args.auto] : []), ...(args.play ? ['--play', args.play] : []),
        ...(args.loop ? ['--loop', args.loop] : []), ...(args['band-rows'] ? ['--band-rows', args['band-rows']] : []),
        '--scenes', scenes.map((s) => s.name).join(',')], { stdio: 'inherit' });
      const { results } = JSON.parse(readFileSync(out, 'utf8'));
      rmSync(out, { force: true });
      for (const r of results) {
        if (r.info.api.toLowerCase() !== pageApi) throw new Error(`${r.scene}: asked for ${pageApi}, ran ${r.info.api}`);
        if (schedule && r.info.schedule !== schedule) throw new Error(`${r.scene}: asked for ${schedule}, ran ${r.info.schedule}`);
        ((runs[api] ||= {})[r.scene] ||= []).push(r);
        infos[api] = r.info;
      }
    }
  }
  const info = infos[apis[0]];
  console.log(`\nWeb path tracer, headless Chromium: ${apis.map((a) => `${infos[a].api} on ${infos[a].adapter}`).join('; ')}; ${size}, 1 spp/frame, MIS, depth ${args.depths ? `${args.depths} (the first frames at the bundle's 8)` : info.maxDepth}, venice_sunset sky; mean of ${frames} frames after 3 warm-up frames; medians of ${rounds} alternated round(s).`);
  console.log('Shared, noisy 2-core machine: compare the ratios (same run), not absolute times.\n');
  const head = ['scene', 'triangles', 'bundle (raw)', 'bundle (gzip)'];
  for (const api of apis) {
    head.push(`${api} frame (ms)`, `${api} first image cold (ms)`, `${api} first frame cold (ms)`,
      `${api} first image warm (ms)`, `${api} first frame warm (ms)`);
  }
  for (const api of apis.slice(1)) head.push(`frame ${api} / ${apis[0]}`);
  const depths = args.depths ? args.depths.split(',').map(Number) : [];
  if (depths.length) {
    for (const d of depths) for (const api of apis) head.push(`${api} frame depth ${d} (ms)`);
    for (const d of depths) for (const api of apis.slice(1)) head.push(`depth ${d}: ${api} / ${apis[0]}`);
  }
  console.log(`| ${head.join(' | ')} |`);
  console.log(`|${head.map(() => '---').join('|')}|`);
  for (const s of scenes) {
    const mb = (n) => `${(n / 1e6).toFixed(2)} MB`;
    const cells = [s.name, s.triangles.toLocaleString('en'), mb(s.bytes.raw), mb(s.bytes.gzip)];
    const frame = {};
    for (const api of apis) {
      const rows = runs[api][s.name];
      frame[api] = median(rows.map((r) => r.frameMs));
      cells.push(frame[api].toFixed(0));
      for (const visit of ['cold', 'warm']) {
        cells.push(median(rows.map((r) => r[`${visit}FirstImageMs`])).toFixed(0),
          median(rows.map((r) => r[`${visit}FirstFrameMs`])).toFixed(0));
      }
      for (const r of rows) {
        if (r.coldFromCache || !r.warmFromCache) console.log(`  (unexpected: ${api} ${s.name}: cold visit from cache ${r.coldFromCache}, warm visit from cache ${r.warmFromCache})`);
      }
    }
    for (const api of apis.slice(1)) cells.push(`${(frame[api] / frame[apis[0]]).toFixed(2)}x`);
    const atDepth = (api, d) => median(runs[api][s.name].map((r) => r.frameMsByDepth[d]));
    for (const d of depths) for (const api of apis) cells.push(atDepth(api, d).toFixed(0));
    for (const d of depths) for (const api of apis.slice(1)) cells.push(`${(atDepth(api, d) / atDepth(apis[0], d)).toFixed(2)}x`);
    console.log(`| ${cells.join(' | ')} |`);
  }

  // Where the first frame's time goes (web/www/main.js, window.lightport.firstFrame): the
  // bundle's download (warm: its read from the page's cache), its decode in wasm, the scene's
  // upload to GPU textures or buffers, the shader compile (generation, compile and link, or
  // pipeline creation until the device's verdict), the first frame on the GPU (its submission
  // until it is finished), and the rest (page, wasm and WebGPU device start, scenes.json, the
  // driver's round trips). Medians over the rounds, each column on its own.
  const parts = [['downloadMs', 'download'], ['decodeMs', 'decode'], ['uploadMs', 'upload'], ['compileMs', 'compile'],
    ['previewMs', 'preview GPU'], ['gpuMs', 'first frame GPU'], ['otherMs', 'other'],
    ['firstImageMs', 'first image'], ['totalMs', 'first full frame']];
  console.log('\nTime to the first frame, split (ms from navigation start; median over rounds):\n');
  const splitHead = ['scene', 'api', 'cache', ...parts.map(([, label]) => label)];
  console.log(`| ${splitHead.join(' | ')} |`);
  console.log(`|${splitHead.map(() => '---').join('|')}|`);
  for (const s of scenes) {
    for (const api of apis) {
      for (const visit of ['cold', 'warm']) {
        const rows = runs[api][s.name].map((r) => r[`${visit}Split`]).filter(Boolean);
        const cell = (key) => (rows.length ? median(rows.map((r) => r[key])).toFixed(0) : '–');
        console.log(`| ${s.name} | ${api} | ${visit} | ${parts.map(([key]) => cell(key)).join(' | ')} |`);
      }
    }
  }

  // `--loop SECONDS`: the page as a person sees it, the frame loop running (bands).
  if (args.loop) {
    console.log(`\nThe frame loop, as a person sees the page (warm cache, frames in bands, the animation paused; ms, medians over rounds; frame: between the first and last frame completed in ${args.loop} s):\n`);
    console.log('| scene | api | first image | first full frame | long tasks between | frame (frame loop) | frame (one submission) | loop / one submission | long tasks, share of the loop |');
    console.log('|---|---|---|---|---|---|---|---|---|');
    for (const s of scenes) {
      for (const api of apis) {
        const rows = runs[api][s.name];
        const cell = (key) => {
          const values = rows.map((r) => r[key]).filter((v) => typeof v === 'number');
          return values.length ? median(values) : null;
        };
        const [loop, whole] = [cell('loopFrameMs'), cell('frameMs')];
        const show = (v) => (v === null ? '–' : v.toFixed(0));
        const ratio = loop !== null && whole ? `${(loop / whole).toFixed(2)}x` : '–';
        const share = cell('loopLongTaskShare');
        console.log(`| ${s.name} | ${api} | ${show(cell('loopFirstImageMs'))} | ${show(cell('loopFirstFrameMs'))} | ` +
          `${show(cell('loopLongTaskMsToFirstFrame'))} | ${show(loop)} | ${show(whole)} | ${ratio} | ` +
          `${share === null ? '–' : `${(100 * share).toFixed(0)} %`} |`);
      }
    }
  }

  // `--band-rows`: frames in bands of N rows back to back against whole frames.
  if (args['band-rows']) {
    const bandRows = args['band-rows'].split(',');
    console.log('\nA frame in bands of N rows submitted back to back, against the whole frame in one submission (ms per frame, medians over rounds; in parentheses: / the whole frame in the same turns):\n');
    console.log(`| scene | api | whole frame | ${bandRows.map((n) => `${n} rows`).join(' | ')} |`);
    console.log(`|---|---|---|${bandRows.map(() => '---').join('|')}|`);
    for (const s of scenes) {
      for (const api of apis) {
        const rows = runs[api][s.name].filter((r) => r.bandRowsMs);
        if (!rows.length) continue;
        const whole = median(rows.map((r) => r.bandRowsMs.whole));
        const cells = bandRows.map((n) => {
          const ms = median(rows.map((r) => r.bandRowsMs[n]));
          return `${ms.toFixed(0)} (${(ms / whole).toFixed(2)}x)`;
        });
        console.log(`| ${s.name} | ${api} | ${whole.toFixed(0)} | ${cells.join(' | ')} |`);
      }
    }
  }

  // `--auto 1`: what `schedule=auto` chose per scene on WebGPU, each round's measurement.
  if (args.auto === '1') {
    console.log('\nschedule=auto on WebGPU, measured by the page (median ms per frame of each schedule\'s turns):\n');
    console.log('| scene | round | state | megakernel (ms) | wavefront (ms) | wavefront / megakernel | chosen |');
    console.log('|---|---|---|---|---|---|---|');
    for (const s of scenes) {
      for (const api of apis.filter((a) => a === 'webgpu')) {
        runs[api][s.name].forEach((r, round) => {
          const c = r.scheduleChoice || {};
          const ms = (v) => (typeof v === 'number' ? v.toFixed(0) : '–');
          const ratio = typeof c.ratio === 'number' ? `${c.ratio.toFixed(2)}x` : '–';
          console.log(`| ${s.name} | ${round + 1} | ${c.state || '–'} | ${ms(c.measuredMegakernelMs)} | ${ms(c.measuredWavefrontMs)} | ${ratio} | ${c.chosen || '–'} |`);
        });
      }
    }
  }

  // `--play SECONDS`: the page's frame loop while a scene plays, against paused.
  if (args.play) {
    console.log(`\nPlaying at real speed against paused, the frame loop for ${args.play} s turns, alternated (medians over turns and rounds; per second):\n`);
    console.log('| scene | api | playing: poses | playing: previews | playing: whole frames | paused: whole frames | pose on the host (ms) |');
    console.log('|---|---|---|---|---|---|---|');
    for (const s of scenes) {
      for (const api of apis) {
        const turns = runs[api][s.name].flatMap((r) => r.play || []);
        if (!turns.length) continue;
        const of = (playing, key) => median(turns.filter((t) => t.playing === playing).map((t) => t[key]));
        console.log(`| ${s.name} | ${api} | ${of(true, 'posesPerS').toFixed(1)} | ${of(true, 'previewsPerS').toFixed(1)} | ${of(true, 'framesPerS').toFixed(2)} | ${of(false, 'framesPerS').toFixed(2)} | ${of(true, 'poseMs').toFixed(1)} |`);
      }
    }
  }

  // What alpha masks cost: LittlestTokyo as shipped against its opaque copy, frame time.
  const masked = scenes.find((s) => s.name === 'LittlestTokyo');
  const opaqueRow = scenes.find((s) => s.name === 'LittlestTokyo-opaque');
  if (masked && opaqueRow) {
    console.log(`\nAlpha masks: LittlestTokyo as shipped (${opaque.masked} masked or blended materials) and made opaque (every alphaMode removed), frame time (ms, median over rounds):\n`);
    // Each round visits the two back to back: the ratio within a round pairs frames measured
    // under the same load, steadier on a shared machine than the ratio of the medians.
    console.log('| api | as shipped | opaque | as shipped / opaque | per round | median per round |');
    console.log('|---|---|---|---|---|---|');
    for (const api of apis) {
      const frames = (s) => runs[api][s.name].map((r) => r.frameMs);
      const [a, b] = [median(frames(masked)), median(frames(opaqueRow))];
      const paired = frames(masked).map((m, i) => m / frames(opaqueRow)[i]);
      const list = paired.map((r) => `${r.toFixed(2)}x`).join(', ');
      console.log(`| ${api} | ${a.toFixed(0)} | ${b.toFixed(0)} | ${(a / b).toFixed(2)}x | ${list} | ${median(paired).toFixed(2)}x |`);
    }
  }
} finally {
  server.kill();
}
