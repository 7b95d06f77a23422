// Drives the Lightport page in headless Chromium (Debian's /usr/bin/chromium through
// playwright-core) and writes what it observed as JSON. It decides nothing: the Rust side
// (tests/cli/web.rs, examples/bench_web.rs) does the statistics and the assertions.
//
//   node run.mjs SCENARIO --url http://127.0.0.1:PORT/ --out result.json [options]
//
// Scenarios: accumulate, cache, camera, slow, drop, limits, context, display, denoise,
// denoiseedges (see each function); bench, chart, compile, toplevel (measure.mjs); animation
// (animation.mjs); preview (preview.mjs); api, fallback, deviceloss, autoschedule (api.mjs);
// layout (layout.mjs). `--api auto|webgpu|webgl2` chooses the page's API (default webgl2),
// `--schedule auto|megakernel|wavefront` its schedule. `--deadline SECONDS` (any scenario): give
// up, close the browser and exit 3 after that long, so that a hung page never hangs the caller.
// `--exit-on-stdin-eof` (no value): exit 4, closing the browser, when stdin reaches its end: the
// caller holds the pipe's other end, which the kernel closes when the caller ends however it
// ends (src/serve_child.rs), so neither this driver nor its browser outlives a test binary that
// panics, aborts or is killed.

import { rmSync, writeFileSync, readFileSync } from 'node:fs';
import {
  freshProfile, loopPace, open, pageApi, setBrowserFlags, setPageApi, setPageSchedule, withBrowser,
} from './page.mjs';
import { animation } from './animation.mjs';
import { apiChoice, autoSchedule, deviceLoss, fallback } from './api.mjs';
import { preview } from './preview.mjs';
import { layout } from './layout.mjs';
import { bench, chart, compile, topLevel } from './measure.mjs';

function parseArgs(argv) {
  const [scenario, ...rest] = argv;
  const options = { scenario };
  for (let i = 0; i < rest.length; i += 2) {
    if (!rest[i].startsWith('--')) throw new Error(`unexpected argument ${rest[i]}`);
    if (rest[i] === '--exit-on-stdin-eof') {
      options.exitOnStdinEof = true;
      i -= 1;
      continue;
    }
    options[rest[i].slice(2)] = rest[i + 1];
  }
  for (const required of ['url', 'out']) {
    if (!options[required]) throw new Error(`--${required} is required`);
  }
  return options;
}

function bundleRequests(requests) {
  return requests.filter((p) => p.includes('/bundles/'));
}

// Renders `batches` x `frames` frames of a scene at a small size, reading the accumulation
// back after each batch: independent batch means for the statistics.
async function accumulate(o) {
  const profile = freshProfile();
  try {
    return await withBrowser(profile, async (context) => {
      const { page, error, info, consoleErrors } =
        await open(context, o.url, {
          scene: o.scene, size: o.size, strategy: o.strategy, paused: '1', autoScheduleTimes: o.autoScheduleTimes,
        });
      if (error) return { error, consoleErrors };
      // `--preview 1`: first the preview, as the frame loop renders it after a load (it must
      // leave the accumulation alone).
      const previewShown = o.preview === '1' ? await page.evaluate(() => window.lightport.renderPreview()) : null;
      // `--measure 1`: one frame, then auto's schedule measurement (with `--autoScheduleTimes`:
      // its outcome injected); the batches follow on the schedule it chose.
      let choice = null;
      if (o.measure === '1') {
        choice = await page.evaluate(async () => {
          await window.lightport.renderFrames(1);
          return window.lightport.measureSchedule();
        });
      }
      const batches = [];
      for (let b = 0; b < Number(o.batches); b++) {
        await page.evaluate((n) => window.lightport.renderFrames(n), Number(o.frames));
        batches.push(await page.evaluate(() => window.lightport.readAccumulation()));
      }
      const shownInfo = choice ? await page.evaluate(() => window.lightport.info()) : info;
      // The scene's warnings as the page shows them (served: from scenes.json).
      const warnings = await page.evaluate(() => window.lightport.warnings);
      return { info: shownInfo, choice, preview: previewShown, batches, warnings, consoleErrors };
    });
  } finally {
    rmSync(profile, { recursive: true, force: true });
  }
}

// Two visits with the same browser profile: the second must take the scene from the page's
// cache. Reports the bundle requests and bytes of each visit, and the cache read-out.
async function cache(o) {
  const profile = freshProfile();
  const visit = async () => withBrowser(profile, async (context) => {
    const { page, requests, error, consoleErrors } = await open(context, o.url, { scene: o.scene, size: o.size });
    if (error) return { error, consoleErrors, bundleRequests: bundleRequests(requests), bytesFetched: 0 };
    await page.waitForFunction(() => window.lightport.frames > 0, null, { timeout: 120000 });
    return {
      error,
      // What the frames rendered: the sum of the accumulated radiance (0 for a black image).
      sum: await page.evaluate(async () => {
        const a = await window.lightport.readAccumulation();
        let sum = 0;
        for (let i = 0; i < a.data.length; i += 4) sum += a.data[i] + a.data[i + 1] + a.data[i + 2];
        return sum;
      }),
      consoleErrors,
      bundleRequests: bundleRequests(requests),
      bytesFetched: await page.evaluate(() => window.lightport.bytesFetched),
      sources: await page.evaluate(() => window.lightport.bundleSources),
      usage: await page.evaluate(() => window.lightport.cacheUsage()),
      readout: await page.textContent('#cache-use'),
    };
  });
  try {
    const first = await visit();
    const second = await visit();
    // "Clear cache" empties it: a third visit downloads again.
    const cleared = await withBrowser(profile, async (context) => {
      const { page } = await open(context, o.url, { scene: o.scene, size: o.size });
      await page.click('#clear-cache');
      await page.waitForFunction(() => window.lightport.cacheUsage().scenes === 0, null, { timeout: 10000 });
      return { usage: await page.evaluate(() => window.lightport.cacheUsage()) };
    });
    const third = await visit();
    return { first, second, cleared, third };
  } finally {
    rmSync(profile, { recursive: true, force: true });
  }
}

// Mouse and wheel input on the canvas restart the accumulation.
async function camera(o) {
  const profile = freshProfile();
  try {
    return await withBrowser(profile, async (context) => {
      const { page, error } = await open(context, o.url, { scene: o.scene, size: o.size, paused: '1', prepare: o.prepare });
      if (error) return { error };
      const spp = () => page.evaluate(() => window.lightport.spp());
      const render = (n) => page.evaluate((k) => window.lightport.renderFrames(k), n);
      const image = () => page.evaluate(async () => (await window.lightport.readAccumulation()).data);
      const steps = {};
      await render(8);
      steps.beforeDrag = await spp();
      const before = await image();
      // Where the canvas is now: the read-outs above it change once the first frame is done
      // (the first-frame split's line can wrap), which moves a small canvas from under a point
      // measured earlier.
      const box = await page.locator('#view').boundingBox();
      const cx = box.x + box.width / 2;
      const cy = box.y + box.height / 2;
      await page.mouse.move(cx, cy);
      await page.mouse.down();
      await page.mouse.move(cx + 60, cy + 10, { steps: 4 });
      await page.mouse.up();
      steps.afterDrag = await spp();
      await render(8);
      steps.afterDragRendered = await spp();
      const after = await image();
      await page.mouse.move(cx, cy);
      await page.mouse.wheel(0, 200);
      await page.waitForTimeout(100);
      steps.afterWheel = await spp();
      await render(3);
      steps.afterWheelRendered = await spp();
      await page.selectOption('#strategy', 'nee');
      steps.afterStrategy = await spp();
      const errorAfter = await page.evaluate(() => window.lightport.error);
      return { steps, before, after, error: errorAfter };
    });
  } finally {
    rmSync(profile, { recursive: true, force: true });
  }
}

// A slow frame (`--size`, e.g. 640x480 on SwiftShader: seconds per frame) with the frame loop
// running, frames split into bands of `--bandBudget` ms (0: not split): waits until `--settle`
// bands were submitted, then drags the mouse on the canvas `--inputs` times, each at a random
// point of a band, and reports, per input, the page's record of the restart it caused (event
// time, first band of the restarted accumulation submitted and done on the GPU) and whether
// the sample counter was reset. Then the frame loop's time per frame (`--loopSeconds`, bands
// as it submits them), the time of one whole frame in one submission (renderFrames, paused),
// the page's split read-out and sceneInfo.
async function slow(o) {
  const profile = freshProfile();
  const inputs = Number(o.inputs || '5');
  try {
    return await withBrowser(profile, async (context) => {
      const { page, error } = await open(context, o.url, { scene: o.scene, size: o.size, bandBudget: o.bandBudget });
      if (error) return { error };
      const settle = Number(o.settle || '20');
      await page.waitForFunction((n) => window.lightport.bands >= n, settle, { timeout: 300000 });
      // Not locator.boundingBox(): it waits for rendering, which an unsplit slow frame holds up.
      const box = await page.evaluate(() => {
        const r = document.querySelector('#view').getBoundingClientRect();
        return { x: r.x, y: r.y, width: r.width, height: r.height };
      });
      const cx = box.x + box.width / 2;
      const cy = box.y + box.height / 2;
      const restarts = [];
      for (let i = 0; i < inputs; i++) {
        const before = await page.evaluate(() => window.lightport.restarts.length);
        // Somewhere inside a band (or, unsplit, a frame) in flight.
        await page.waitForTimeout(50 + Math.random() * 200);
        await page.mouse.move(cx, cy);
        await page.mouse.down();
        await page.mouse.move(cx + 12 * (i % 2 ? -1 : 1), cy + 3);
        const sppAfterInput = await page.evaluate(() => window.lightport.spp());
        await page.mouse.up();
        await page.waitForFunction((n) => window.lightport.restarts.length > n, before, { timeout: 300000 });
        restarts.push({ ...(await page.evaluate(() => window.lightport.restarts.at(-1))), sppAfterInput });
      }
      const loopFrameMs = await loopPace(page, Number(o.loopSeconds || '12') * 1000);
      const info = await page.evaluate(() => window.lightport.info());
      const readout = await page.textContent('#frame-split');
      // One whole frame in one submission, waited for (after a warm-up frame).
      const frameMs = await page.evaluate(async () => {
        window.lightport.pause();
        await window.lightport.renderFrames(1);
        return window.lightport.renderFrames(1);
      });
      return { restarts, info, readout, frameMs, loopFrameMs, error: await page.evaluate(() => window.lightport.error) };
    });
  } finally {
    rmSync(profile, { recursive: true, force: true });
  }
}

// A broken file dropped on the page shows an error and the page keeps rendering; then a
// good .gltf with its files (through the file input) replaces the scene.
async function drop(o) {
  const profile = freshProfile();
  try {
    return await withBrowser(profile, async (context) => {
      const { page, error } = await open(context, o.url, { scene: o.scene, size: o.size, paused: '1' });
      if (error) return { error };
      await page.evaluate(() => window.lightport.renderFrames(2));
      // A real drop event with a DataTransfer, as a file manager would send.
      await page.evaluate(() => {
        const data = new DataTransfer();
        data.items.add(new File([new Uint8Array([0x67, 0x6c, 0x54, 0x46, 2, 0, 0, 0, 99, 1, 2])], 'broken.glb'));
        document.dispatchEvent(new DragEvent('drop', { dataTransfer: data, bubbles: true, cancelable: true }));
      });
      await page.waitForFunction(() => window.lightport.error, null, { timeout: 30000 });
      const badError = await page.evaluate(() => window.lightport.error);
      const messageVisible = await page.isVisible('#message');
      const messageText = await page.textContent('#message');
      const afterBad = await page.evaluate(async () => {
        const before = window.lightport.spp();
        await window.lightport.renderFrames(2);
        return { before, after: window.lightport.spp(), name: window.lightport.info().name };
      });
      const files = (o.files || '').split(',').filter(Boolean).map((path) => ({
        name: path.split('/').pop(),
        mimeType: 'application/octet-stream',
        buffer: readFileSync(path),
      }));
      let good = null;
      if (files.length) {
        await page.evaluate(() => { window.lightport.error = null; });
        await page.setInputFiles('#file-input', files);
        await page.waitForFunction(
          (name) => window.lightport.error || window.lightport.info().name === name,
          files[0].name,
          { timeout: 120000 },
        );
        const rendered = await page.evaluate(async () => {
          await window.lightport.renderFrames(2);
          const l = window.lightport;
          const message = document.querySelector('#message').textContent;
          return { spp: l.spp(), info: l.info(), error: l.error, warnings: l.warnings, message };
        });
        good = { ...rendered, readout: await page.textContent('#scene-info') };
      }
      return { badError, messageVisible, messageText, afterBad, good };
    });
  } finally {
    rmSync(profile, { recursive: true, force: true });
  }
}

// A device texture limit too small for the scene is reported on the page.
async function limits(o) {
  const profile = freshProfile();
  try {
    return await withBrowser(profile, async (context) => {
      const { page, error } =
        await open(context, o.url, { scene: o.scene, size: o.size, paused: '1', maxTextureSize: o.limit });
      return { error, messageText: await page.textContent('#message'), info: await page.evaluate(() => window.lightport.info()) };
    });
  } finally {
    rmSync(profile, { recursive: true, force: true });
  }
}

// WEBGL_lose_context: the page shows the loss, then recreates the renderer and continues.
async function contextLoss(o) {
  const profile = freshProfile();
  try {
    return await withBrowser(profile, async (context) => {
      const { page, error } = await open(context, o.url, { scene: o.scene, size: o.size, paused: '1' });
      if (error) return { error };
      await page.evaluate(() => window.lightport.renderFrames(4));
      await page.evaluate(() => {
        const gl = document.querySelector('#view').getContext('webgl2');
        window.__loseContext = gl.getExtension('WEBGL_lose_context');
        window.__loseContext.loseContext();
      });
      await page.waitForFunction(() => window.lightport.info().contextLost, null, { timeout: 10000 });
      const whileLost = await page.evaluate(() => ({
        message: document.querySelector('#message').textContent,
        spp: window.lightport.spp(),
      }));
      await page.evaluate(() => window.__loseContext.restoreContext());
      await page.waitForFunction(() => !window.lightport.info().contextLost, null, { timeout: 30000 });
      const restored = await page.evaluate(async () => {
        await window.lightport.renderFrames(3);
        const data = (await window.lightport.readAccumulation()).data;
        return { spp: window.lightport.spp(), error: window.lightport.error, sum: data.reduce((a, b) => a + b, 0) };
      });
      return { whileLost, restored };
    });
  } finally {
    rmSync(profile, { recursive: true, force: true });
  }
}

// The display pass: for each tone curve and exposure (the first given in the URL, the others
// chosen through the page's controls), the canvas's pixels (top row first, RGBA) and the
// accumulation they show, for tests/cli/web.rs to compare with the CLI's PNG conversion.
async function display(o) {
  const profile = freshProfile();
  try {
    return await withBrowser(profile, async (context) => {
      // Denoise off: the raw accumulation's display is what is compared here.
      const query = { scene: o.scene, size: o.size, paused: '1', tonemap: 'aces', exposure: '1.5', denoise: '0' };
      const { page, error, consoleErrors } = await open(context, o.url, query);
      if (error) return { error, consoleErrors };
      const shots = [];
      for (const [tonemap, exposure] of [[null, null], ['agx', '-1'], ['none', '0'], ['neutral', '0']]) {
        if (tonemap) {
          await page.selectOption('#tonemap', tonemap);
          await page.$eval('#exposure', (e, v) => { e.value = v; e.dispatchEvent(new Event('input')); }, exposure);
        }
        // Drawn and copied in one task: the WebGL drawing buffer is intact until it is composited.
        shots.push(await page.evaluate(async () => {
          // The frames are drawn at once; only the wait for the GPU is a promise.
          window.lightport.renderFrames(2);
          const view = document.querySelector('#view');
          const copy = document.createElement('canvas');
          copy.width = view.width;
          copy.height = view.height;
          const context2d = copy.getContext('2d');
          context2d.drawImage(view, 0, 0);
          const pixels = Array.from(context2d.getImageData(0, 0, view.width, view.height).data);
          const info = window.lightport.info();
          const accumulation = await window.lightport.readAccumulation();
          return { toneMap: info.toneMap, exposure: info.exposure, pixels, accumulation };
        }));
      }
      return { shots, consoleErrors, error: await page.evaluate(() => window.lightport.error) };
    });
  } finally {
    rmSync(profile, { recursive: true, force: true });
  }
}

// The canvas copied in one task with a redraw (the drawing buffer, WebGL2's or WebGPU's, is
// intact until it is composited): RGBA, top row first; and the read-outs it goes with.
async function canvasShot(page) {
  return page.evaluate(() => {
    window.lightport.draw();
    const view = window.lightport.viewer.canvas;
    const copy = document.createElement('canvas');
    copy.width = view.width;
    copy.height = view.height;
    const context2d = copy.getContext('2d');
    context2d.drawImage(view, 0, 0);
    const pixels = Array.from(context2d.getImageData(0, 0, view.width, view.height).data);
    return { pixels, spp: window.lightport.spp(), denoise: window.lightport.denoise() };
  });
}

// The read-outs are written by the frame loop: wait for two animation frames.
async function readoutText(page) {
  await page.evaluate(() => new Promise((r) => requestAnimationFrame(() => requestAnimationFrame(r))));
  return page.textContent('#denoise-info');
}

// The denoiser: with `denoise=1` (or the page's default, `--default 1`) the page renders `--spp`
// frames (paused: through the test hook), waits until the canvas shows them denoised, and
// copies the canvas; then the Denoise control is switched off: the raw image, and its
// accumulation. With the read-out's text at each step and the denoiser's times.
async function denoise(o) {
  const profile = freshProfile();
  try {
    return await withBrowser(profile, async (context) => {
      const query = { scene: o.scene, size: o.size, paused: '1', seed: o.seed || '1' };
      if (!o.default) query.denoise = '1';
      const { page, error, consoleErrors } = await open(context, o.url, query);
      if (error) return { error, consoleErrors };
      const spp = Number(o.spp);
      await page.evaluate((n) => window.lightport.renderFrames(n), spp);
      await page.waitForFunction((n) => {
        const d = window.lightport.denoise();
        return window.lightport.error || (d && (d.shownSpp === n || d.error));
      }, spp, { timeout: 180000 });
      const readoutOn = await readoutText(page);
      const on = await canvasShot(page);
      const checked = await page.isChecked('#denoise');
      await page.click('#denoise');
      const readoutOff = await readoutText(page);
      const off = await canvasShot(page);
      const accumulation = await page.evaluate(() => window.lightport.readAccumulation());
      return {
        checked, readoutOn, readoutOff, on, off, accumulation, consoleErrors,
        info: await page.evaluate(() => window.lightport.info()),
        error: await page.evaluate(() => window.lightport.error),
      };
    });
  } finally {
    rmSync(profile, { recursive: true, force: true });
  }
}

// The denoiser given bad input: switched with no scene, a 1xN image, and (WebGL2) switched
// while the context is lost, then rendering after the restore. What the page said each time.
async function denoiseEdges(o) {
  const profile = freshProfile();
  try {
    return await withBrowser(profile, async (context) => {
      const { page, error } = await open(context, o.url, { scene: '', paused: '1', size: o.size });
      if (error) return { error };
      const steps = {};
      const state = async () => page.evaluate(() => ({
        error: window.lightport.error,
        denoise: window.lightport.denoise(),
        spp: window.lightport.spp(),
        message: document.querySelector('#message').hidden ? null : document.querySelector('#message').textContent,
      }));
      await page.evaluate(() => { window.lightport.setDenoise(false); window.lightport.setDenoise(true); });
      steps.noScene = { ...(await state()), readout: await readoutText(page) };
      await page.evaluate((name) => window.lightport.loadScene(name), o.scene);
      await page.evaluate(() => window.lightport.renderFrames(8));
      await page.waitForFunction(() => {
        const d = window.lightport.denoise();
        return window.lightport.error || (d && (d.shownSpp === 8 || d.error));
      }, null, { timeout: 120000 });
      steps.thin = { ...(await state()), readout: await readoutText(page), shot: await canvasShot(page) };
      if (pageApi === 'webgl2') {
        await page.evaluate(() => {
          const gl = window.lightport.viewer.canvas.getContext('webgl2');
          window.__loseContext = gl.getExtension('WEBGL_lose_context');
          window.__loseContext.loseContext();
        });
        await page.waitForFunction(() => window.lightport.info().contextLost, null, { timeout: 10000 });
        await page.evaluate(async () => {
          window.lightport.setDenoise(false);
          window.lightport.setDenoise(true);
          window.lightport.draw();
          await window.lightport.renderFrames(4);
        });
        steps.lost = { ...(await state()), readout: await readoutText(page) };
        await page.evaluate(() => window.__loseContext.restoreContext());
        await page.waitForFunction(() => !window.lightport.info().contextLost, null, { timeout: 30000 });
        await page.evaluate(() => window.lightport.renderFrames(4));
        await page.waitForFunction(() => {
          const d = window.lightport.denoise();
          return window.lightport.error || (d && (d.shownSpp === 4 || d.error));
        }, null, { timeout: 120000 });
        steps.restored = { ...(await state()), readout: await readoutText(page) };
      }
      return { steps };
    });
  } finally {
    rmSync(profile, { recursive: true, force: true });
  }
}

const SCENARIOS = {
  accumulate, cache, camera, slow, drop, limits, context: contextLoss, display, api: apiChoice, deviceloss: deviceLoss,
  fallback, autoschedule: autoSchedule,
  bench, chart, compile, denoise, denoiseedges: denoiseEdges, toplevel: topLevel, animation, preview, layout,
};

const options = parseArgs(process.argv.slice(2));
if (options.api) setPageApi(options.api);
if (options.schedule) setPageSchedule(options.schedule);
if (options.browser) setBrowserFlags(options.browser);
const run = SCENARIOS[options.scenario];
if (!run) {
  console.error(`unknown scenario ${options.scenario}: ${Object.keys(SCENARIOS).join(', ')}`);
  process.exit(2);
}
if (options.deadline !== undefined) {
  const seconds = Number(options.deadline);
  if (!(seconds > 0)) {
    console.error(`--deadline must be a positive number of seconds: ${options.deadline}`);
    process.exit(2);
  }
  // process.exit runs playwright's exit handler, which kills the browser it launched.
  setTimeout(() => {
    console.error(`run.mjs ${options.scenario}: gave up after the --deadline of ${seconds} s (the page did not finish)`);
    process.exit(3);
  }, seconds * 1000).unref();
}
if (options.exitOnStdinEof) {
  // process.exit runs playwright's exit handler, which kills the browser's process group.
  const orphaned = () => {
    console.error(`run.mjs ${options.scenario}: stdin closed (the caller ended): exiting`);
    process.exit(4);
  };
  process.stdin.on('end', orphaned);
  process.stdin.on('error', orphaned);
  process.stdin.resume();
  process.stdin.unref();
}
try {
  const result = await run(options);
  writeFileSync(options.out, JSON.stringify(result));
} catch (e) {
  console.error(e && e.stack ? e.stack : String(e));
  process.exit(1);
}
process.exit(0);
