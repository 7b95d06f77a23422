// The scenarios that measure rather than check (run.mjs runs them): bench (frame time and the
// first frame, cold and warm), chart (`lightport chart --backends web`), compile
// (examples/feature_sizes.rs) and toplevel (the two-level scene's top-level rebuild).

import { rmSync, readFileSync } from 'node:fs';
import { freshProfile, longTaskMs, loopPace, median, open, watchLongTasks, withBrowser } from './page.mjs';
import { playAndPause } from './animation.mjs';

// Frame time at a fixed size, and navigation-to-first-frame with a cold and a warm cache, with
// the page's split of that time (window.lightport.firstFrame: download, decode, upload, compile,
// the first frame's GPU time).
export async function bench(o) {
  const results = [];
  for (const scene of o.scenes.split(',')) {
    const profile = freshProfile();
    try {
      const row = { scene };
      for (const visit of ['cold', 'warm']) {
        await withBrowser(profile, async (context) => {
          // Frame times without the denoiser (its time is measured by the denoise scenario).
          const { page, error, navigationStart } =
            await open(context, o.url, { scene, size: o.size, paused: '1', denoise: '0', preview: o.preview, prepare: o.prepare });
          if (error) throw new Error(`${scene}: ${error}`);
          // The first image: the preview, as the frame loop renders it after a load (`--preview
          // 0`: none; the page's own `preview=0`), then the first full frame in one submission.
          if (o.preview !== '0') await page.evaluate(() => window.lightport.renderPreview());
          await page.evaluate(() => window.lightport.renderFrames(1));
          // The page splits the first frame's time once the frame is finished on the GPU.
          await page.waitForFunction(() => window.lightport.firstFrame, null, { timeout: 60000 });
          const timing = await page.evaluate(() => ({
            firstImageMs: window.lightport.firstImageMs,
            firstImage: window.lightport.firstImage,
            firstFrameMs: window.lightport.firstFrameMs,
            startup: window.lightport.startup,
            split: window.lightport.firstFrame,
            fromCache: window.lightport.bundleSources.at(-1).fromCache,
            bytes: window.lightport.bundleSources.at(-1).bytes,
          }));
          row[`${visit}FirstFrameMs`] = timing.firstFrameMs;
          row[`${visit}FirstImageMs`] = timing.firstImageMs;
          row[`${visit}FirstImage`] = timing.firstImage;
          row[`${visit}Startup`] = timing.startup;
          row[`${visit}Split`] = timing.split;
          row[`${visit}FromCache`] = timing.fromCache;
          row.bundleBytes = timing.bytes;
          row[`${visit}WallMs`] = Date.now() - navigationStart;
          if (visit === 'warm') {
            // `--depths 8,32`: the frame time at each path depth (setMaxDepth), in this order;
            // `frameMs` is the first's. Default: the bundle's depth.
            const depths = o.depths ? o.depths.split(',').map(Number) : [null];
            row.frameMsByDepth = {};
            for (const depth of depths) {
              if (depth !== null) await page.evaluate((d) => window.lightport.setMaxDepth(d), depth);
              await page.evaluate(() => window.lightport.renderFrames(2)); // warm up
              const frames = Number(o.frames);
              const ms = await page.evaluate((n) => window.lightport.renderFrames(n), frames);
              const info = await page.evaluate(() => window.lightport.info());
              if (depth !== null && info.maxDepth !== depth) throw new Error(`${scene}: asked for depth ${depth}, the page runs ${info.maxDepth}`);
              row.frameMsByDepth[info.maxDepth] = ms;
              if (row.frameMs === undefined) {
                row.frameMs = ms;
                row.info = info;
              }
            }
            // `--band-rows 1,2,4`: a frame in bands of N rows submitted back to back, each value
            // alternated with the whole frame (medians of the turns).
            if (o['band-rows']) {
              const turns = { whole: [] };
              const values = o['band-rows'].split(',').map(Number);
              for (const turn of [0, 1, 2]) {
                for (const n of turn % 2 ? [...values].reverse() : values) {
                  turns.whole.push(await page.evaluate((k) => window.lightport.renderFrames(k), Number(o.frames)));
                  (turns[n] ||= []).push(await page.evaluate(([k, r]) => window.lightport.renderFramesInBands(k, r), [Number(o.frames), n]));
                }
              }
              row.bandRowsMs = Object.fromEntries(Object.entries(turns).map(([k, v]) => [k, median(v)]));
            }
            // `--play SECONDS`: a scene that moves, played by the frame loop and paused in turn.
            if (o.play && row.info.animation) row.play = await page.evaluate(playAndPause, Number(o.play));
            // `--auto 1`: what `schedule=auto` measures and chooses for this scene on WebGPU (the
            // page's own measurement, web/src/viewer/measure.rs), after the frames above.
            if (o.auto === '1' && row.info.api === 'WebGPU' && row.info.scheduleRequested === 'auto') {
              // A moving scene is measured paused (its animation playing, each pose restarts).
              row.scheduleChoice = await page.evaluate(() => {
                window.lightport.setPlaying(false);
                return window.lightport.measureSchedule();
              });
            }
          }
        });
      }
      // `--loop SECONDS`: the page as a person sees it (warm cache): the frame loop running,
      // frames in bands (a moving scene's animation paused), to its first full frame, then its
      // time per frame.
      if (o.loop) {
        await withBrowser(profile, async (context) => {
          const { page, error } = await open(context, o.url, { scene, size: o.size, denoise: '0', preview: o.preview });
          if (error) throw new Error(`${scene}: ${error}`);
          await watchLongTasks(page);
          await page.evaluate(() => window.lightport.setPlaying(false));
          await page.waitForFunction(() => window.lightport.firstFrame, null, { timeout: 120000 });
          const first = await page.evaluate(() => [window.lightport.firstImageMs, window.lightport.firstFrameMs]);
          [row.loopFirstImageMs, row.loopFirstFrameMs] = first;
          const paceFrom = await page.evaluate(() => performance.now());
          row.loopFrameMs = await loopPace(page, Number(o.loop) * 1000);
          // Long tasks' ms from the first image to the first full frame (the load's own before
          // it: decode, upload), and their share of the loop's time after it.
          const paceTo = await page.evaluate(() => performance.now());
          row.loopLongTaskMsToFirstFrame = await longTaskMs(page, first[0], first[1]);
          row.loopLongTaskShare = (await longTaskMs(page, paceFrom, paceTo)) / (paceTo - paceFrom);
        });
      }
      results.push(row);
      process.stderr.write(`${JSON.stringify(row)}\n`);
    } finally {
      rmSync(profile, { recursive: true, force: true });
    }
  }
  return { results };
}

// The browser's WebGL2 implementation (unmasked where the browser allows it).
async function webgl2Info(page) {
  return page.evaluate(() => {
    const gl = document.createElement('canvas').getContext('webgl2');
    if (!gl) return { renderer: 'no WebGL2', version: '', parallelCompile: false };
    const debug = gl.getExtension('WEBGL_debug_renderer_info');
    return {
      renderer: gl.getParameter(debug ? debug.UNMASKED_RENDERER_WEBGL : gl.RENDERER),
      version: gl.getParameter(gl.VERSION),
      parallelCompile: Boolean(gl.getExtension('KHR_parallel_shader_compile')),
    };
  });
}

// `lightport chart --backends web`: one line per strategy over the chart's own bundle (`--bundle
// FILE`, handed to the page at a URL of this driver's: the page and its wasm come from `lightport
// serve`), at cumulative `--checkpoints` (e.g. 1,2,4). The page times its own work: the frames
// (accumulation pass + display pass to the canvas) and the wait for the GPU (a 1-pixel read-back),
// with performance.now(); not the page load, bundle upload, shader compile, the untimed warm-up
// frame (the driver's shader JIT) or the float read-back after each checkpoint.
//
// `--denoise 1`: then a denoised line per strategy (reported after the raw ones, `denoised:
// true`), by the page's own denoiser: the renderer is recreated with the denoiser's guide (its
// schedule off: only the driver's requests denoise), warmed up by an untimed frame and an
// untimed denoise (the filter's shaders are JIT-compiled at the first), and each strategy rendered to each checkpoint again, timed as above; at each checkpoint the page
// denoises the accumulation (`denoiseNow`) and the point's `ms` is this line's rendering so far
// plus that denoise's whole time (`filterMs`: read-backs, passes, remodulation), as for a render
// to that many samples denoised once (the native twins' rule). Its `data` is the denoised image
// (rgb means, 3 values a pixel) and `accepted` the accumulation's finite samples.
export async function chart(o) {
  const strategies = (o.strategies || 'mis').split(',');
  const checkpoints = (o.checkpoints || '1').split(',').map(Number);
  if (!o.bundle) throw new Error('--bundle FILE is required');
  if (checkpoints.some((c, i) => !Number.isInteger(c) || c < 1 || (i > 0 && c <= checkpoints[i - 1]))) {
    throw new Error(`--checkpoints must be increasing positive integers: ${o.checkpoints}`);
  }
  const bundleBytes = readFileSync(o.bundle);
  const profile = freshProfile();
  try {
    return await withBrowser(profile, async (context) => {
      await context.route((url) => url.pathname === '/lightport-chart/scene.lpb', (route) =>
        route.fulfill({ status: 200, contentType: 'application/octet-stream', body: bundleBytes }));
      const { page, error, info, consoleErrors } = await open(context, o.url, {
        bundle: '/lightport-chart/scene.lpb', size: o.size, seed: o.seed || '1', strategy: strategies[0], paused: '1',
        denoise: '0', // the chart times the renderer alone
      });
      if (error) return { error, consoleErrors };
      const pageError = () => page.evaluate(() => window.lightport.error);
      // The warm-up frame: the driver compiles (JITs) the kernel at the first draw.
      const warmUpMs = await page.evaluate(() => window.lightport.renderFrames(1));
      // One line: `strategy` restarted (frame 0 of the seed's sequence, as a fresh renderer) and
      // rendered to each checkpoint, its frames timed; `point(spp, ms)` reads that checkpoint's
      // point, or returns a string: what went wrong. Returns the points, or { error }.
      const renderLine = async (strategy, point) => {
        await page.evaluate((s) => window.lightport.setStrategy(s), strategy);
        const points = [];
        let ms = 0;
        for (const spp of checkpoints) {
          const frames = spp - (await page.evaluate(() => window.lightport.spp()));
          ms += frames * (await page.evaluate((n) => window.lightport.renderFrames(n), frames));
          const e = await pageError();
          if (e) return { error: e };
          const p = await point(spp, ms);
          if (typeof p === 'string') return { error: `${strategy} at ${spp} spp: ${p}` };
          points.push(p);
        }
        return { points };
      };
      const lines = [];
      for (const strategy of strategies) {
        const { points, error: lineError } = await renderLine(strategy, async (spp, ms) => {
          const image = await page.evaluate(() => window.lightport.readAccumulation());
          if (image.spp !== spp) return `${image.spp} spp rendered`;
          return { spp, ms, width: image.width, height: image.height, data: image.data };
        });
        if (lineError) return { error: lineError, consoleErrors };
        lines.push({ strategy, points, info: await page.evaluate(() => window.lightport.info()) });
      }
      let guidedWarmUpMs = null;
      if (o.denoise === '1') {
        await page.evaluate(() => {
          window.lightport.setDenoiseSchedule(false);
          window.lightport.setDenoise(true);
        });
        // The new renderer's kernel (with the guide) is JIT-compiled at its first draw, and the
        // filter's passes at the first denoise: both untimed.
        guidedWarmUpMs = await page.evaluate(() => window.lightport.renderFrames(1));
        const e = await pageError();
        if (e) return { error: `switching the denoiser on: ${e}`, consoleErrors };
        try {
          await page.evaluate(() => window.lightport.denoiseNow());
        } catch (err) {
          return { error: `the warm-up denoise: ${err.message || err}`, consoleErrors };
        }
        for (const strategy of strategies) {
          const { points, error: lineError } = await renderLine(strategy, async (spp, ms) => {
            let denoised;
            try {
              denoised = await page.evaluate(() => window.lightport.denoiseNow());
            } catch (err) {
              return `${err.message || err}`;
            }
            if (!denoised || denoised.spp !== spp) return `denoised at ${denoised && denoised.spp} spp`;
            const accumulation = await page.evaluate(() => window.lightport.readAccumulation());
            let accepted = 0;
            for (let i = 3; i < accumulation.data.length; i += 4) accepted += accumulation.data[i];
            return {
              spp, ms: ms + denoised.filterMs, renderMs: ms, filterMs: denoised.filterMs,
              width: denoised.width, height: denoised.height, data: denoised.data, accepted,
            };
          });
          if (lineError) return { error: lineError, consoleErrors };
          lines.push({ strategy, denoised: true, points });
        }
      }
      return { info, gl: await webgl2Info(page), warmUpMs, guidedWarmUpMs, lines, consoleErrors };
    });
  } finally {
    rmSync(profile, { recursive: true, force: true });
  }
}

// examples/feature_sizes.rs: WebGL2 compile + link time of GLSL ES 3.00 programs. `--shaders
// FILE` holds { vertex, fragments: [{ name, source }] }; each repeat measures every fragment
// shader once, in order (the caller alternates variants with its baseline), in one browser whose
// GPU program caches are off (`--disable-gpu-program-cache`, `--disable-gpu-shader-disk-cache`;
// the page also makes every source unique), so that a repeat compiles again rather than finding
// the program cached. Reports per program `ms` (until LINK_STATUS) and `settledMs` (the work the
// GPU process still did after it: see the page's compileProgram).
export async function compile(o) {
  const { vertex, fragments } = JSON.parse(readFileSync(o.shaders, 'utf8'));
  const repeats = Number(o.repeats || '5');
  if (!Number.isInteger(repeats) || repeats < 1) throw new Error(`--repeats must be a positive integer: ${o.repeats}`);
  const profile = freshProfile();
  try {
    return await withBrowser(profile, async (context) => {
      const { page, error, consoleErrors } = await open(context, o.url, { scene: '', paused: '1' });
      if (error) return { error, consoleErrors };
      const times = fragments.map(() => []);
      const settled = fragments.map(() => []);
      for (let r = 0; r < repeats; r++) {
        for (const [i, f] of fragments.entries()) {
          const result = await page.evaluate(([v, s]) => window.lightport.compileProgram(v, s), [vertex, f.source]);
          if (!result.ok) return { error: `${f.name} does not compile or link in WebGL2: ${result.log}`, consoleErrors };
          times[i].push(result.ms);
          settled[i].push(result.settledMs);
        }
      }
      const gl = await webgl2Info(page);
      return { gl, times: fragments.map((f, i) => ({ name: f.name, ms: times[i], settledMs: settled[i] })), consoleErrors };
    }, ['--disable-gpu-program-cache', '--disable-gpu-shader-disk-cache']);
  } finally {
    rmSync(profile, { recursive: true, force: true });
  }
}

// The top level of a two-level scene built in wasm over 32², 100² and 317² placements (the
// stress field's), median of 5 each: what a frame in which placements move rebuilds
// (`Viewer.topLevelBuildMs`; native figures: examples/bench_instancing.rs).
export async function topLevel(o) {
  const profile = freshProfile();
  try {
    return await withBrowser(profile, async (context) => {
      const { page, error } = await open(context, o.url, { scene: '', paused: '1' });
      if (error) return { error };
      const rows = [];
      for (const side of [32, 100, 317]) {
        const ms = await page.evaluate((s) => window.lightport.viewer.constructor.topLevelBuildMs(s), side);
        rows.push({ placements: side * side, ms });
        process.stderr.write(`${JSON.stringify(rows.at(-1))}\n`);
      }
      return { rows };
    });
  } finally {
    rmSync(profile, { recursive: true, force: true });
  }
}
