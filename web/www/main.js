// The page around the wasm viewer: the frame loop, camera input, controls, read-outs, the
// scene list and the bundle cache. Query parameters (for tests and benchmarks):
//   scene=NAME        the served scene to open first (default: the first listed; `scene=`
//                     with no name: none)
//   bundle=URL        open the scene bundle at URL instead (fetched as is, not cached: what
//                     `lightport chart` renders; its driver hands the page the chart's own bundle)
//   size=WxH          a fixed render size instead of the canvas size x resolution scale
//   strategy=mis|nee|bsdf, seed=N (the random sequence; default 1),
//   tonemap=neutral|aces|agx|none, exposure=EV (the display, as the CLI's --tonemap and
//                     --exposure; default neutral at 0 EV),
//   denoise=0|1       the denoiser (default 1: the canvas shows the accumulation denoised at 4
//                     spp, then each time the spp double; web/src/denoise/mod.rs),
//   paused=1          no frame loop: frames only through the test hook,
//   preview=0|1       the preview (default 1: a new renderer's first image, and the first
//                     after each restart (a camera move, a pose), is rendered at a quarter of
//                     each side and shown upscaled until the first full-resolution frame is
//                     complete; never accumulated: web/src/runtime/preview.rs),
//   prepare=0|1       compile a served scene's kernel while its bundle is decoded (default 1;
//                     web/src/viewer/prepare.rs); 0: after, as a comparison,
//   budget=BYTES      the cache budget,
//   bandBudget=MS     the longest one GPU submission (a band of a frame) should take, default
//                     100; 0: frames are not split (one submission per frame),
//   api=auto|webgpu|webgl2  the graphics API (default auto: WebGPU if the browser gives a device
//                     and the scene fits its limits, else WebGL2; the "API" control reloads with it),
//   schedule=auto|megakernel|wavefront  how WebGPU organises a frame (default auto: measured
//                     per scene load once its first frame shows: see measureSchedule; the
//                     wavefront needs WebGPU; the "Schedule" control reloads with it),
//   autoScheduleTimes=MK,WF  test only: auto decides on these ms per frame of the megakernel
//                     and the wavefront instead of the measured ones (the measurement still runs),
//   maxTextureSize=N, maxStorageBuffers=N  pretend the device allows at most N (WebGL2's texture
//                     size; WebGPU's storage buffers per shader stage).

import init, { Viewer } from './pkg/lightport_web.js';
import { BundleCache, DEFAULT_BUDGET_BYTES } from './cache.js';
import { movingText, setUpAnimationControls, showAnimation } from './animation.js';
import { setUpCameraInput } from './camera_input.js';
import { FirstFrame } from './first_frame.js';
import { measureSchedules } from './schedule_measure.js';
import { createTestHook } from './test_hook.js';
import { apiReadout, formatBytes, formatRate, setIfChanged, setText } from './readouts.js';
import { WebGpuRecovery } from './webgpu_recovery.js';

const params = new URLSearchParams(location.search);
const $ = (id) => document.getElementById(id);
// The canvas: the viewer's (it replaces the element when it switches between WebGL2 and WebGPU,
// which a canvas cannot do: it keeps its first kind of context). Input listeners sit on the stage.
const view = () => (viewer ? viewer.canvas : $('view'));
const stage = $('stage');
const api = (params.get('api') || 'auto').toLowerCase();
const schedule = (params.get('schedule') || 'auto').toLowerCase();

const cache = new BundleCache(Number(params.get('budget')) || DEFAULT_BUDGET_BYTES);
// The scene list is requested now, beside the wasm module's download and compile, rather than
// after them (20-60 ms sooner on this machine); a failure is reported where it is awaited.
// (Asking for a WebGPU adapter this early too, to start Chromium's WebGPU sooner, measured no
// gain: the device came at 472-607 ms against 486-561 ms. Nor did requesting the first scene's
// bundle as soon as the list names it, to download it beside the wasm module's compile: on this
// 2-core machine the two share the CPU, and the bundle reached the load no sooner (4 alternated
// cold visits, medians, with against without: Cornell box 656 / 701 ms on WebGL2, 1208 / 1235 ms
// on WebGPU; LittlestTokyo 745 / 718 and 1183 / 1148 ms).)
const sceneList = fetch('scenes.json');
sceneList.catch(() => {});
let viewer = null;
let wasm = null; // the WebAssembly instance's exports (its memory), once loaded
let scenes = [];
let currentName = '';
let paused = params.get('paused') === '1';
let lost = false;
let busy = false; // a scene is being loaded
let hasScene = false;
const fixedSize = /^(\d+)x(\d+)$/.exec(params.get('size') || '');
// Whether bundles are loaded with their kernel compiled while they are decoded (`prepare=0`: not).
const prepareBundles = params.get('prepare') !== '0';

// The test hook (test_hook.js): what the browser tests and benchmarks read and drive.
const hook = createTestHook({
  viewer: () => viewer,
  wasm: () => wasm,
  cache,
  $,
  setPaused: (on) => { paused = on; },
  previewShown,
  timeFrames,
  measureSchedule,
  loadServedScene,
  loadBundleUrl,
  guarded,
  yieldToBrowser,
  clearCache,
});
window.lightport = hook;

// The time to the first frame, accounted for (first_frame.js).
const firstFrame = new FirstFrame(hook, () => viewer, $);

// The scene's geometry in words: its triangles, and for a two-level scene (meshes stored once
// and placed by instances) how many placements.
function geometryText(info) {
  const triangles = `${info.triangles.toLocaleString()} triangles`;
  const geometry = info.placements > 0
    ? `${triangles} stored, ${info.placements.toLocaleString()} placements (two levels)`
    : triangles;
  return geometry + movingText(info);
}

// How long a notice (kind 'info': e.g. why WebGL2 runs) stays over the image; errors stay.
const NOTICE_MS = 10000;

function showMessage(text, kind = 'error') {
  const box = $('message');
  box.textContent = text;
  box.className = kind;
  box.hidden = false;
  if (kind === 'error') {
    hook.error = text;
    console.error(text);
  } else {
    setTimeout(() => { if (box.textContent === text && box.className === kind) box.hidden = true; }, NOTICE_MS);
  }
}

function hideMessage() {
  $('message').hidden = true;
}

// Why the scene runs on WebGL2 although WebGPU was possible (auto), or nothing.
function showNotice() {
  const info = viewer.sceneInfo();
  if (info.notice) {
    hook.notice = info.notice;
    showMessage(info.notice, 'info');
  } else {
    hideMessage();
  }
}

// A loaded scene's warnings (e.g. "lit by a uniform white sky"), or else the notice.
function showWarningsOrNotice(name, warnings) {
  hook.warnings = warnings || null;
  if (warnings) showMessage(`${name}: ${warnings}`, 'info');
  else showNotice();
}

// Resolves after the browser has run what was queued (tasks, the GPU process's replies).
function yieldToBrowser() {
  return new Promise((resolve) => {
    const channel = new MessageChannel();
    channel.port1.onmessage = () => resolve();
    channel.port2.postMessage(null);
  });
}

function guarded(action) {
  try {
    return action();
  } catch (e) {
    showMessage(String(e.message || e));
    return undefined;
  }
}

// ---- auto's schedule, measured (schedule_measure.js) ------------------------------------

function measureSchedule() {
  return measureSchedules(viewer, {
    frameDone,
    showMessage,
    showNotice,
    // The frame loop's frame time starts again after the measurement's frames.
    over: () => { frameMs = null; lastFrameAt = null; },
  });
}

// ---- frame loop -------------------------------------------------------------------------

let frameMs = null; // moving average of the time between completed frames
let lastFrameAt = null;
let pendingRestart = null; // the last restart whose first image (preview or band) is not done yet

function frameDone() {
  hook.frames++;
  firstFrame.frameDone();
}

// A preview was submitted and drawn at `at`.
function previewShown(at) {
  const p = viewer.sceneInfo().preview;
  hook.previews.push({ at, width: p.width, height: p.height });
  // One per restart while a drag or an animation plays: keep the latest.
  if (hook.previews.length > 256) hook.previews.shift();
  firstFrame.previewSubmitted(at);
}

// `n` frames rendered now (in bands of `rows` submitted back to back, else each in one
// submission), waited for on the GPU: milliseconds per frame (renderFrames,
// renderFramesInBands).
async function timeFrames(n, rows) {
  const start = performance.now();
  for (let i = 0; i < n; i++) {
    while (!frame(rows)) await viewer.sync();
  }
  await viewer.sync();
  return (performance.now() - start) / Math.max(n, 1);
}

// One whole frame in one submission (in bands of `rows` submitted back to back); or (a
// wavefront's) the next submission of it: whether it is done (or failed).
function frame(rows) {
  if (!viewer || lost) return true;
  let done;
  try {
    firstFrame.markSubmitted(performance.now());
    done = rows === undefined ? viewer.frame() : viewer.frameInBands(rows);
  } catch (e) {
    showMessage(String(e.message || e));
    paused = true;
    return true;
  }
  if (done) frameDone();
  return done;
}

// The frame loop: a few bands of a frame queued on the GPU, up to three budgets of work
// (Viewer.step polls their fences, on WebGPU their onSubmittedWorkDone, without blocking, and
// tops the queue up), so input runs between bands and a restart waits for those bands, not a
// whole frame.
function tick(now) {
  if (viewer && !webGpu.recovering && viewer.webGpuLost()) webGpu.recover(viewer.webGpuLost());
  // While auto measures the schedules (measureSchedule), its loop renders the frames.
  const measuring = viewer && viewer.measuringSchedule();
  // The denoiser's WebGPU promises and due denoises, also while paused (test hook frames).
  if (!busy && viewer && !lost && !webGpu.recovering && hasScene && !measuring) {
    try {
      viewer.pollDenoise();
    } catch (e) {
      showMessage(String(e.message || e));
    }
  }
  if (!paused && !busy && viewer && !lost && !webGpu.recovering && hasScene && !measuring) {
    applyHeldKeys(now);
    let status = 0;
    const before = performance.now();
    try {
      status = viewer.step(before);
      if (status === 3) previewShown(before);
      else if (status > 0) firstFrame.markSubmitted(before);
    } catch (e) {
      showMessage(String(e.message || e));
      paused = true;
    }
    if (status > 0) {
      const at = performance.now();
      if (status !== 3) hook.bands++;
      if (pendingRestart && pendingRestart.submittedAt !== null) {
        // The restarted accumulation's first image (its preview, on a slow device, or its first
        // band) is done: nothing new could be submitted before it was seen done.
        pendingRestart.doneAt = at;
        hook.restarts.push(pendingRestart);
        pendingRestart = null;
      } else if (pendingRestart) {
        pendingRestart.submittedAt = at;
      }
    }
    if (status === 2) {
      frameDone();
      // The scene's first frame has shown: under schedule=auto on WebGPU, measure the schedules.
      if (viewer.scheduleMeasurementDue()) measureSchedule();
      if (lastFrameAt !== null) {
        const dt = now - lastFrameAt;
        frameMs = frameMs === null ? dt : 0.9 * frameMs + 0.1 * dt;
      }
      lastFrameAt = now;
    }
  } else {
    lastFrameAt = null;
  }
  const readoutsAt = performance.now();
  updateReadouts();
  hook.readoutMs.push(performance.now() - readoutsAt);
  if (hook.readoutMs.length > 64) hook.readoutMs.shift();
  requestAnimationFrame(tick);
}

function updateReadouts() {
  if (!viewer) return;
  const info = viewer.sceneInfo();
  setText('api-info', info.api ? apiReadout(info) : '–');
  setIfChanged($('api-info'), 'title', info.notice || '');
  setText('spp', info.spp);
  showAnimation($, info);
  setText('denoise-info', info.preview && info.preview.showing
    ? `preview ${info.preview.width}×${info.preview.height}, upscaled (full resolution on the way)`
    : info.denoise.readout);
  setText('size', `${info.width}×${info.height}`);
  if (frameMs !== null) {
    const samples = (info.width * info.height * 1000) / frameMs;
    const segmentRays = info.strategy === 'bsdf' ? 1 : 2;
    setText('frame-time', `${frameMs.toFixed(1)} ms`);
    setText('samples-rate', formatRate(samples));
    setText('ray-rate', formatRate(samples * info.maxDepth * segmentRays));
  }
  setText('frame-split', !info.bandBudgetMs
    ? 'not split (one submission per frame)'
    : info.bands > 1
      ? `frame split into ${info.bands} bands of ≤${info.bandBudgetMs} ms` +
        ` (${info.bandRows} rows each)`
      : `1 band per frame (under ${info.bandBudgetMs} ms)`);
  setText('bytes-fetched', formatBytes(cache.bytesFetched));
}

function updateCacheReadout() {
  const u = cache.usage();
  $('cache-use').textContent = cache.available
    ? `${formatBytes(u.bytes)} of ${formatBytes(u.budget)}, ${u.scenes} scene${u.scenes === 1 ? '' : 's'}`
    : 'unavailable (the Cache API needs a secure context)';
}

// ---- size ---------------------------------------------------------------------------------

function renderSize() {
  if (fixedSize) return [Number(fixedSize[1]), Number(fixedSize[2])];
  const scale = Number($('scale').value);
  const dpr = window.devicePixelRatio || 1;
  const w = Math.max(1, Math.round(stage.clientWidth * dpr * scale));
  const h = Math.max(1, Math.round(stage.clientHeight * dpr * scale));
  return [w, h];
}

function applySize() {
  if (!viewer) return;
  const [w, h] = renderSize();
  guarded(() => viewer.setSize(w, h));
  frameMs = null;
}

// ---- scenes -------------------------------------------------------------------------------

// Loads a bundle, its kernel compiled while it is decoded (web/src/viewer/prepare.rs): the
// renderer is created from the bundle's features first, and the browser's GPU process compiles
// while the bundle is decoded here. On WebGPU the page yields first, so that the GPU process
// gets the pipeline (WebGPU sends its commands once this task ends); on WebGL2 the commands are
// sent already, and a yield would wait for the compile (the rendering update between tasks
// waits for the GPU process). `?prepare=0` loads without (the comparison).
async function compileWhileDecoding(bytes) {
  const data = new Uint8Array(bytes);
  const preparedOn = prepareBundles ? viewer.prepareBundle(data) : undefined;
  if (preparedOn) hook.startup.prepared ??= performance.now();
  if (preparedOn === 'WebGPU') {
    await yieldToBrowser();
    hook.startup.yielded ??= performance.now();
  }
  return viewer.loadBundle(data);
}

async function loadServedScene(name) {
  const scene = scenes.find((s) => s.name === name);
  if (!scene) {
    showMessage(`unknown scene ${name}`);
    return;
  }
  busy = true;
  // The page's first scene counts from the navigation's start.
  firstFrame.begin(scene.name, hook.startup.fetched === undefined ? 0 : performance.now());
  showMessage(`loading ${scene.name} (${formatBytes(scene.bytes.raw)})…`, 'info');
  try {
    firstFrame.fetchStarted();
    const { bytes, fromCache } = await cache.fetch(scene.url, (received) => {
      showMessage(`downloading ${scene.name}: ${formatBytes(received)}`, 'info');
    });
    firstFrame.fetched();
    hook.bundleSources.push({ name: scene.name, fromCache, bytes: bytes.byteLength });
    hook.startup.fetched ??= performance.now();
    const info = await compileWhileDecoding(bytes);
    hook.startup.installed ??= performance.now();
    hasScene = true;
    currentName = scene.name;
    $('scene').value = scene.name;
    $('screenshot').disabled = false;
    $('scene-info').textContent = `${scene.name}: ${geometryText(info)}${fromCache ? ' (cached)' : ''}`;
    showWarningsOrNotice(scene.name, (scene.warnings || []).join('; '));
  } catch (e) {
    showMessage(`${scene.name}: ${e.message || e}`);
    firstFrame.cancel();
  } finally {
    busy = false;
    frameMs = null;
    updateCacheReadout();
  }
}

async function loadBundleUrl(url) {
  busy = true;
  firstFrame.begin(url, hook.startup.fetched === undefined ? 0 : performance.now());
  showMessage(`loading ${url}…`, 'info');
  try {
    firstFrame.fetchStarted();
    const response = await fetch(url, { cache: 'no-store' });
    if (!response.ok) throw new Error(`HTTP ${response.status}`);
    const bytes = await response.arrayBuffer();
    firstFrame.fetched();
    hook.startup.fetched ??= performance.now();
    hook.bundleSources.push({ name: url, fromCache: false, bytes: bytes.byteLength });
    const info = await compileWhileDecoding(bytes);
    hasScene = true;
    currentName = info.name || url;
    $('scene').value = '';
    $('screenshot').disabled = false;
    $('scene-info').textContent = `${currentName}: ${geometryText(info)}`;
    showWarningsOrNotice(currentName, '');
  } catch (e) {
    showMessage(`${url}: ${e.message || e}`);
    firstFrame.cancel();
  } finally {
    busy = false;
    frameMs = null;
  }
}

async function loadFiles(fileList) {
  const files = Array.from(fileList || []);
  if (files.length === 0) return;
  busy = true;
  showMessage(`loading ${files.map((f) => f.name).join(', ')}…`, 'info');
  try {
    for (const file of files) {
      const bytes = new Uint8Array(await file.arrayBuffer());
      viewer.addDroppedFile(file.webkitRelativePath || file.name, bytes);
    }
    const info = viewer.loadDropped();
    // Files from the disk: the read-out splits served bundles' first frames only.
    firstFrame.notMeasured();
    hasScene = true;
    currentName = info.name;
    $('scene').value = '';
    $('screenshot').disabled = false;
    $('scene-info').textContent =
      `${info.name}: ${geometryText(info)}, loaded in ${info.loadMs.toFixed(0)} ms, ` +
      `BVH + pack ${info.buildAndPackMs.toFixed(0)} ms`;
    showAnimation($, info);
    showWarningsOrNotice(info.name, info.warnings);
  } catch (e) {
    showMessage(`could not open the dropped files: ${e.message || e}`);
  } finally {
    busy = false;
    frameMs = null;
  }
}

async function clearCache() {
  await cache.clear();
  updateCacheReadout();
}

// ---- camera input -------------------------------------------------------------------------

// Listeners for events on the canvas, on the stage (the canvas element may be replaced);
// capturing, so that events that do not bubble (WebGL context loss) arrive too.
function onView(type, handler, options = {}) {
  stage.addEventListener(type, (e) => { if (e.target === view()) handler(e); }, { capture: true, ...options });
}

// `at`: the input's time (an event's timeStamp), for the restart latency the hook records.
function cameraAction(action, at = performance.now()) {
  guarded(action);
  frameMs = null;
  lastFrameAt = null;
  pendingRestart = { inputAt: at, handledAt: performance.now(), submittedAt: null, doneAt: null };
}

const applyHeldKeys = setUpCameraInput({
  onView, view, getViewer: () => viewer, isFly: () => $('mode').value === 'fly', cameraAction,
});

// ---- drop zone ----------------------------------------------------------------------------

let dragDepth = 0;
document.addEventListener('dragenter', (e) => {
  e.preventDefault();
  dragDepth++;
  $('drop-hint').hidden = false;
});
document.addEventListener('dragleave', () => {
  dragDepth = Math.max(0, dragDepth - 1);
  if (dragDepth === 0) $('drop-hint').hidden = true;
});
document.addEventListener('dragover', (e) => e.preventDefault());
document.addEventListener('drop', (e) => {
  e.preventDefault();
  dragDepth = 0;
  $('drop-hint').hidden = true;
  loadFiles(e.dataTransfer && e.dataTransfer.files);
});
$('file-input').addEventListener('change', (e) => {
  loadFiles(e.target.files);
  e.target.value = '';
});

// ---- controls -----------------------------------------------------------------------------

$('scene').addEventListener('change', (e) => { if (e.target.value) loadServedScene(e.target.value); });
$('strategy').addEventListener('change', (e) => cameraAction(() => viewer.setStrategy(e.target.value)));
$('tonemap').addEventListener('change', (e) => hook.setToneMap(e.target.value));
$('exposure').addEventListener('input', (e) => hook.setExposure(Number(e.target.value)));
$('denoise').addEventListener('change', (e) => hook.setDenoise(e.target.checked));
$('scale').addEventListener('change', applySize);
$('reset-camera').addEventListener('click', () => cameraAction(() => viewer.resetCamera()));
setUpAnimationControls($, () => viewer, guarded);
$('clear-cache').addEventListener('click', clearCache);
$('screenshot').addEventListener('click', async () => {
  try {
    const png = await viewer.screenshotPng();
    const link = document.createElement('a');
    link.href = URL.createObjectURL(new Blob([png], { type: 'image/png' }));
    link.download = `${currentName.replace(/\.[^.]*$/, '') || 'lightport'}-${viewer.spp()}spp.png`;
    link.click();
    setTimeout(() => URL.revokeObjectURL(link.href), 10000);
  } catch (e) {
    showMessage(String(e.message || e));
  }
});

if (!fixedSize) {
  stage.classList.add('fill');
  let resizeTimer = null;
  new ResizeObserver(() => {
    clearTimeout(resizeTimer);
    resizeTimer = setTimeout(applySize, 200); // recreating the renderer is not free
  }).observe(stage);
  holdReadoutHeight();
}

// The read-outs below the image wrap by their text, and their text changes as the image
// converges ("preview …" becomes "raw …", the API's line tells the schedule's measurement).
// A footer that grew and shrank again resized the stage, the new size restarted the
// accumulation and the restart put the old text back, for ever: DamagedHelmet on WebGPU in a
// 900x700 window never got past its first sample (tests/cli/web/layout.rs). The footer keeps
// the tallest height it has had since the window last changed size, so text alone resizes the
// stage a bounded number of times.
function holdReadoutHeight() {
  const footer = document.querySelector('footer');
  let held = 0;
  new ResizeObserver(() => {
    const height = footer.getBoundingClientRect().height;
    if (height > held) {
      held = height;
      footer.style.minHeight = `${height}px`;
    }
  }).observe(footer);
  window.addEventListener('resize', () => {
    held = 0;
    footer.style.minHeight = '';
  });
}

// ---- context loss -------------------------------------------------------------------------

onView('webglcontextlost', (e) => {
  e.preventDefault(); // tells the browser the page will handle restoration
  lost = true;
  if (viewer) viewer.contextLost();
  showMessage('The WebGL context was lost (GPU reset or too many contexts); waiting for the browser to restore it…', 'info');
});
onView('webglcontextrestored', () => {
  lost = false;
  if (!viewer) return;
  try {
    viewer.contextRestored();
    hideMessage();
  } catch (e) {
    showMessage(`restoring the WebGL context failed: ${e.message || e}`);
  }
});

// ---- WebGPU device loss ---------------------------------------------------------------------

// The first WebGPU device, and a new one after a loss (webgpu_recovery.js).
const webGpu = new WebGpuRecovery({
  api,
  hook,
  getViewer: () => viewer,
  showMessage,
  showNotice,
  guarded,
  pause: () => { paused = true; },
});

// The API and Schedule controls: reload the page with `api=` or `schedule=` (the scene comes
// back from the cache).
for (const [id, value, values] of [
  ['api', api, ['auto', 'webgpu', 'webgl2']],
  ['schedule', schedule, ['auto', 'megakernel', 'wavefront']],
]) {
  $(id).value = values.includes(value) ? value : 'auto';
  $(id).addEventListener('change', (e) => {
    const url = new URL(location.href);
    url.searchParams.set(id, e.target.value);
    location.href = url.toString();
  });
}

// ---- start --------------------------------------------------------------------------------

async function main() {
  try {
    wasm = await init();
    hook.startup.wasm = performance.now();
  } catch (e) {
    showMessage(`the WebAssembly module did not load: ${e.message || e}`);
    hook.ready = true;
    return;
  }
  try {
    viewer = new Viewer($('view'));
    viewer.setApi(api);
    viewer.setSchedule(schedule);
  } catch (e) {
    showMessage(String(e.message || e));
    hook.ready = true;
    return;
  }
  if (params.get('maxStorageBuffers')) viewer.setMaxStorageBuffers(Number(params.get('maxStorageBuffers')));
  const injected = /^([\d.]+),([\d.]+)$/.exec(params.get('autoScheduleTimes') || '');
  if (injected) viewer.setScheduleTimesForTest(Number(injected[1]), Number(injected[2]));
  await webGpu.start();
  const [w, h] = renderSize();
  guarded(() => viewer.setSize(w, h));
  if (params.get('maxTextureSize')) viewer.setMaxTextureSize(Number(params.get('maxTextureSize')));
  if (params.has('bandBudget')) guarded(() => viewer.setBandBudget(Number(params.get('bandBudget'))));
  if (params.has('preview')) {
    const on = params.get('preview');
    if (on === '0' || on === '1') viewer.setPreview(on === '1');
    else showMessage(`invalid preview=${on} (0: off, 1: on, the default)`);
  }
  if (params.has('prepare') && !['0', '1'].includes(params.get('prepare'))) {
    showMessage(`invalid prepare=${params.get('prepare')} (0: compile after the decode, 1: while it, the default)`);
  }
  if (params.get('strategy')) hook.setStrategy(params.get('strategy'));
  if (params.get('tonemap')) hook.setToneMap(params.get('tonemap'));
  if (params.has('exposure')) hook.setExposure(Number(params.get('exposure')));
  if (params.has('denoise')) {
    const on = params.get('denoise');
    if (on === '0' || on === '1') hook.setDenoise(on === '1');
    else showMessage(`invalid denoise=${on} (0: off, 1: on, the default)`);
  }
  if (params.get('seed')) {
    const seed = Number(params.get('seed'));
    if (Number.isInteger(seed) && seed >= 0 && seed <= 0xffffffff) guarded(() => viewer.setSeed(seed));
    else showMessage(`invalid seed ${params.get('seed')} (an integer 0..=4294967295)`);
  }
  await cache.reconcile().catch((e) => console.warn(`cache: ${e}`));
  updateCacheReadout();
  try {
    // Relative to the page, and each bundle's URL relative to the list: a site exported by
    // `lightport export` works under any path of a static host.
    const response = await sceneList;
    if (!response.ok) throw new Error(`HTTP ${response.status}`);
    scenes = (await response.json()).scenes || [];
    // The cache keys on the absolute path.
    for (const s of scenes) s.url = new URL(s.url, response.url).pathname;
    hook.startup.scenes = performance.now();
  } catch (e) {
    showMessage(`the scene list (scenes.json) did not load: ${e.message || e}; drop a .glb to render it`);
  }
  const select = $('scene');
  for (const s of scenes) {
    const option = document.createElement('option');
    option.value = s.name;
    option.textContent = `${s.name} (${s.triangles.toLocaleString()} triangles, ${formatBytes(s.bytes.raw)})`;
    select.append(option);
  }
  select.disabled = scenes.length === 0;
  if (params.get('bundle')) {
    await loadBundleUrl(params.get('bundle'));
  } else {
    const first = params.has('scene') ? params.get('scene') : scenes[0] && scenes[0].name;
    if (first) await loadServedScene(first);
  }
  hook.ready = true;
  requestAnimationFrame(tick);
}

main();
