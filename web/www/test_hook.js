// The test hook, `window.lightport`: what the browser tests and benchmarks read and drive (the
// page's state, timings, and actions). `page` is main.js's side: { viewer(), wasm(), cache, $,
// setPaused(on), and the page's functions the hook calls (previewShown, timeFrames,
// measureSchedule, loadServedScene, loadBundleUrl, guarded, yieldToBrowser, clearCache) }.

import { heapBytes } from './pkg/lightport_web.js';
import { compileProgram } from './compile.js';

export function createTestHook(page) {
  const viewer = () => page.viewer();
  const wasm = () => page.wasm();
  const hook = {
    ready: false, // wasm loaded, first scene shown (or failed: see `error`)
    frames: 0, // frames rendered by this page, all scenes together
    error: null, // the last error shown to the user
    warnings: null, // the last loaded scene's warnings shown (served: scenes.json's; dropped: the loader's)
    firstFrameMs: null, // performance.now() at the first frame drawn (from navigation start)
    // What the time to the first frame went on: performance.now() once the wasm module is
    // ready (wasm), the WebGPU device is (device), scenes.json is read (scenes), the first bundle
    // is fetched (fetched) and installed (installed: decoded, uploaded, kernel compile started).
    startup: {},
    // Where the time to the last loaded scene's first finished frame went, once it is done
    // (the read-out "first frame"): { api, scene, totalMs (from navigation start for the page's
    // first scene, else from the load's start), downloadMs (the bundle's fetch, or its read from
    // the cache), decodeMs (bundle decode in wasm), uploadMs (scene data to GPU textures or
    // buffers, until the driver has it), compileMs (shader generation, compile and link, or
    // pipeline creation until the device's verdict), gpuMs (the first frame: its first
    // submission, or the compile's end if later, until it is finished on the GPU), otherMs (the
    // rest: page and wasm start, device request, scene list, waits between steps) }.
    firstFrame: null,
    // The last loaded scene's first image on screen, once it is: { preview (whether it was one),
    // scene, width, height (its size), totalMs (as firstFrame's), gpuMs }; and the page's first
    // image on screen (performance.now(), as firstFrameMs).
    firstImage: null,
    firstImageMs: null,
    // Per preview shown by this page: { at (performance.now() at its submission), width, height }.
    previews: [],
    bands: 0, // bands submitted by the frame loop
    // What the read-outs took in the last 64 animation frames (ms). They run every frame, so
    // anything costly there stalls the frame loop: a checksum of every texel in sceneInfo() once
    // took ~185 ms a frame on LittlestTokyo, and its bands fell to one row (docs/web.md).
    readoutMs: [],
    // Per camera input that restarted the accumulation, once the restarted accumulation's first
    // image (its preview on a slow device, else its first band) is done on the GPU: { inputAt
    // (the event's timeStamp), handledAt, submittedAt (that image's submission), doneAt (seen
    // done) }, performance.now() times.
    restarts: [],
    bundleSources: [], // per loaded bundle: { name, fromCache, bytes }
    deviceRecoveries: 0, // WebGPU devices recreated after a loss
    // Runs auto's measurement of the schedules now if it is due (e.g. on a paused page after a
    // frame) and resolves to sceneInfo().scheduleChoice once it is over.
    measureSchedule: () => page.measureSchedule(),
    // Destroys the WebGPU device (GPUDevice.destroy()), as a GPU reset loses it.
    loseWebGpu: () => viewer().loseWebGpu(),
    get bytesFetched() { return page.cache.bytesFetched; },
    spp: () => (viewer() ? viewer().spp() : 0),
    info: () => (viewer() ? viewer().sceneInfo() : null),
    // Viewer.textureChecksum: reads every texel, so it is not in info().
    textureChecksum: () => (viewer() ? viewer().textureChecksum() : null),
    cacheUsage: () => page.cache.usage(),
    // The WebAssembly module's linear memory in bytes: it only ever grows, so growth after a
    // warm-up is memory the page kept (a pose's arrays not freed, say).
    wasmMemoryBytes: () => (wasm() ? wasm().memory.buffer.byteLength : 0),
    // Bytes the module has allocated and not freed (web/src/heap.rs): a leak shows here at once.
    heapBytes: () => (wasm() ? heapBytes() : 0),
    pause: () => page.setPaused(true),
    // Renders the pending preview now, as the frame loop's first step does, and waits for the
    // GPU; resolves to sceneInfo().preview ({ state, showing, width, height, ... }).
    async renderPreview() {
      const at = performance.now();
      if (viewer().renderPreview()) page.previewShown(at);
      await viewer().sync();
      return viewer().sceneInfo().preview;
    },
    resume: () => page.setPaused(false),
    // Renders `n` frames now and waits for the GPU; resolves to milliseconds per frame. (A
    // wavefront frame is done once its counters, read after each submission, say so.)
    renderFrames: (n) => page.timeFrames(n),
    // `renderFrames` with each frame's rows submitted in bands of `rows` back to back (a band's
    // cost beyond its rows: tests/web/bench.mjs --band-rows).
    renderFramesInBands: (n, rows) => page.timeFrames(n, rows),
    // Resolves to { width, height, spp, data: number[] (rgba per pixel, rows from the top; rgb
    // sum, a count) }.
    async readAccumulation() {
      const info = viewer().sceneInfo();
      const spp = viewer().spp();
      const data = Array.from(await viewer().readAccumulation());
      return { width: info.width, height: info.height, spp, data };
    },
    loadScene: (name) => page.loadServedScene(name),
    loadBundleUrl: (url) => page.loadBundleUrl(url),
    // Compiles and links `vertex` + `fragment` (GLSL ES 3.00) on a WebGL2 context of its own
    // and returns { ms, ok, log }: milliseconds from the first compile call until
    // getProgramParameter(LINK_STATUS) returns, which waits for the link whether or not the
    // browser compiles in parallel (KHR_parallel_shader_compile is never queried). The program
    // is deleted. A unique comment is appended to both sources, so that no cache keyed by the
    // source text (the browser's or the driver's) answers instead of a compile. For
    // examples/feature_sizes.rs (through tests/web/run.mjs compile).
    compileProgram: (vertex, fragment) => compileProgram(vertex, fragment),
    setStrategy: (name) => page.guarded(() => { viewer().setStrategy(name); page.$('strategy').value = name; }),
    setToneMap: (name) => page.guarded(() => { viewer().setToneMap(name); page.$('tonemap').value = name; }),
    setExposure: (stops) => page.guarded(() => {
      viewer().setExposure(stops);
      page.$('exposure').value = stops;
      page.$('exposure-value').textContent = `${stops} EV`;
    }),
    orbit: (yaw, pitch) => page.guarded(() => viewer().orbit(yaw, pitch)),
    // Longest path in segments (1..=64; the bundle's depth until set). Restarts the accumulation.
    setMaxDepth: (depth) => page.guarded(() => viewer().setMaxDepth(depth)),
    // The denoiser on or off (the Denoise control); `denoise()`: sceneInfo().denoise, what it
    // shows ({ enabled, shownSpp, pendingSpp, filterMs, guideMs, error, readout }).
    setDenoise: (on) => page.guarded(() => { viewer().setDenoise(on); page.$('denoise').checked = on; }),
    denoise: () => (viewer() ? viewer().sceneInfo().denoise : null),
    // Whether the page's rule denoises by itself (default true); false: only denoiseNow does.
    setDenoiseSchedule: (on) => viewer().setDenoiseSchedule(on),
    // Denoises the accumulation as it is now, whatever the page's rule says, and resolves once
    // the denoised image shows, to readDenoised()'s object (rejects with the denoiser's error, or
    // after `timeoutMs`). Polls the denoiser in a loop of its own (a message to itself: neither
    // an animation frame nor setTimeout's 4 ms clamp), so that filterMs is the denoise's time,
    // not the wait for the next poll.
    async denoiseNow(timeoutMs = 120000) {
      viewer().denoiseNow();
      const spp = viewer().spp();
      const start = performance.now();
      for (;;) {
        viewer().pollDenoise();
        const d = viewer().sceneInfo().denoise;
        if (d.error) throw new Error(`the denoiser failed: ${d.error}`);
        if (d.shownSpp === spp) return hook.readDenoised();
        if (performance.now() - start > timeoutMs) throw new Error(`no denoised image after ${timeoutMs} ms`);
        await page.yieldToBrowser();
      }
    },
    // The denoised image on show: { spp, width, height, data: number[] (rgb per pixel, rows from
    // the top: the mean, not a sum), filterMs (the whole denoise: read-backs, passes,
    // remodulation) }, or null when none shows.
    readDenoised() {
      const d = viewer().readDenoised();
      return d && { ...d, data: Array.from(d.data) };
    },
    // Draws the image again (the denoised one where shown): copy the canvas in the same task.
    draw: () => viewer() && viewer().draw(),
    clearCache: () => page.clearCache(),
    // A moving scene's animation (sceneInfo().animation: { duration, time, playing, speed,
    // moving, poseMs }, or null) and its controls.
    animation: () => (viewer() ? viewer().sceneInfo().animation || null : null),
    setPlaying: (on) => page.guarded(() => viewer().setPlaying(on)),
    setAnimationTime: (seconds) => page.guarded(() => viewer().setAnimationTime(seconds)),
    setAnimationSpeed: (speed) => page.guarded(() => viewer().setAnimationSpeed(speed)),
    get viewer() { return viewer(); },
  };
  return hook;
}
