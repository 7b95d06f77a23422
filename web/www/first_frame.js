// The first frame, accounted for: the time from a served scene's load (the page's first scene:
// from the navigation's start) until its first image is on screen (the preview, rendered at a
// quarter of each side: web/src/runtime/preview.rs; without one, the first full frame) and until
// its first full-resolution frame is finished on the GPU, split into download, decode, upload,
// compile, the preview's GPU time, the full frame's GPU time and the rest (the read-out "first
// frame", the test hook's `firstImage` and `firstFrame`), and the test hook's `firstImageMs` and
// `firstFrameMs` (the page's first image and first full frame on screen).

// `hook`: the test hook (firstFrameMs and firstFrame are written there); `getViewer()`: the
// viewer; `$`: the page's getElementById (the read-out is #first-frame).
export class FirstFrame {
  constructor(hook, getViewer, $) {
    this.hook = hook;
    this.getViewer = getViewer;
    this.$ = $;
    // The scene load whose first frame is not finished yet: performance.now() marks of its steps
    // (start, fetchStart, fetched, submitted: the first band or frame submitted).
    this.loading = null;
    this.firstFrameWaited = false;
    this.firstImageWaited = false;
  }

  begin(name, start = performance.now()) {
    this.loading = {
      name, start, fetchStart: null, fetched: null, submitted: null, waiting: false,
      // The preview: submitted, finished on the GPU, its size and GPU time.
      preview: null,
    };
    this.hook.firstFrame = null;
    this.hook.firstImage = null;
    this.$('first-frame').textContent = '…';
  }

  // The bundle's fetch (or its read from the cache) starts, and is done.
  fetchStarted() {
    this.loading.fetchStart = performance.now();
  }

  fetched() {
    this.loading.fetched = performance.now();
  }

  // The load failed: its first frame is not accounted for.
  cancel() {
    this.loading = null;
  }

  // Files from the disk: the read-out splits served bundles' first frames only.
  notMeasured() {
    this.loading = null;
    this.$('first-frame').textContent = '–';
  }

  markSubmitted(at) {
    if (this.loading && this.loading.submitted === null) this.loading.submitted = at;
  }

  // A preview was submitted (and drawn) at `at`: it is waited for on the GPU.
  previewSubmitted(at) {
    const viewer = this.getViewer();
    if (!this.firstImageWaited) {
      this.firstImageWaited = true;
      viewer.sync().then(() => { this.hook.firstImageMs = performance.now(); });
    }
    const load = this.loading;
    if (!load || load.preview || load.submitted !== null) return;
    const info = viewer.sceneInfo().preview || {};
    load.preview = { submitted: at, doneAt: null, width: info.width, height: info.height, gpuMs: null };
    viewer.sync().then(() => this.previewDone(load, performance.now()));
  }

  // The preview of `load` is finished on the GPU (at `doneAt`): the first image's time.
  async previewDone(load, doneAt) {
    const s = await this.startup();
    if (load !== this.loading || !s) return;
    const p = load.preview;
    p.doneAt = doneAt;
    p.verdictAt = verdictBefore(s, doneAt);
    p.gpuMs = doneAt - Math.max(p.submitted, p.verdictAt ?? p.submitted);
    this.hook.firstImage = {
      preview: true, scene: load.name, width: p.width, height: p.height, totalMs: doneAt - load.start, gpuMs: p.gpuMs,
    };
    this.$('first-frame').textContent = `first image (preview ${p.width}×${p.height}) ${sec(doneAt - load.start)} s; ` +
      'full resolution…';
  }

  // sceneInfo().startup once WebGPU's verdict on the pipeline arrived (it comes as a promise:
  // a frame that ran after the compile finds it there, or nearly).
  async startup() {
    const viewer = this.getViewer();
    for (let i = 0; i < 50 && viewer.sceneInfo().startup && viewer.sceneInfo().startup.compiledAt === null; i++) {
      await new Promise((resolve) => setTimeout(resolve, 10));
    }
    return viewer.sceneInfo().startup;
  }

  // A frame was completed (queued): the page's first frame, and a load's first one, are waited
  // for on the GPU.
  frameDone() {
    const viewer = this.getViewer();
    if (!this.firstFrameWaited) {
      // The first frame counts once it is on screen, not when it is queued.
      this.firstFrameWaited = true;
      viewer.sync().then(() => {
        this.hook.firstFrameMs = performance.now();
        // Without a preview, the first image is the first frame.
        if (!this.firstImageWaited) this.hook.firstImageMs = this.hook.firstFrameMs;
        this.firstImageWaited = true;
      });
    }
    if (this.loading && !this.loading.waiting) {
      this.loading.waiting = true;
      const load = this.loading;
      viewer.sync().then(() => this.finish(load, performance.now()));
    }
  }

  // The first full-resolution frame of `load` is finished on the GPU (at `doneAt`): splits its
  // time from the page's marks and the viewer's own (sceneInfo().startup: decode, upload,
  // compile in wasm, and on WebGPU when the device's verdict on the pipeline arrived).
  async finish(load, doneAt) {
    const viewer = this.getViewer();
    const s = await this.startup();
    if (load !== this.loading) return; // another scene was loaded meanwhile
    // The preview's own wait resolves first (queued first), but may be later to read.
    for (let i = 0; i < 50 && load.preview && load.preview.doneAt === null; i++) {
      await new Promise((resolve) => setTimeout(resolve, 10));
    }
    if (load !== this.loading) return;
    this.loading = null;
    const info = viewer.sceneInfo();
    if (!s) return;
    const p = load.preview && load.preview.doneAt !== null ? load.preview : null;
    const verdictAt = p ? p.verdictAt : verdictBefore(s, doneAt);
    const split = {
      api: info.api,
      scene: load.name,
      totalMs: doneAt - load.start,
      downloadMs: load.fetched !== null && load.fetchStart !== null ? load.fetched - load.fetchStart : 0,
      decodeMs: s.decodeMs,
      uploadMs: s.uploadMs,
      // With the kernel compiled while the bundle was decoded (web/src/viewer/prepare.rs): the
      // calls before the decode and what the compile still took after it, not its whole time.
      compileMs: s.codegenMs + s.compileMs + Math.max(0, (verdictAt ?? s.createdAt) - s.createdAt),
      compiledWhileDecoding: s.compiledWhileDecoding,
      // The preview's GPU time (0 without one), then the full frame's, from its first band.
      previewMs: p ? p.gpuMs : 0,
      gpuMs: doneAt - Math.max(load.submitted ?? doneAt, verdictAt ?? 0, p ? p.doneAt : 0),
      // The first image on screen: the preview (its size), or this frame.
      firstImageMs: p ? p.doneAt - load.start : doneAt - load.start,
      preview: p ? { width: p.width, height: p.height } : null,
    };
    split.otherMs = split.totalMs - split.downloadMs - split.decodeMs - split.uploadMs - split.compileMs -
      split.previewMs - split.gpuMs;
    this.hook.firstFrame = split;
    if (!p) {
      this.hook.firstImage = {
        preview: false, scene: load.name, width: info.width, height: info.height, totalMs: split.totalMs,
        gpuMs: split.gpuMs,
      };
    }
    const image = p ? `first image (preview ${p.width}×${p.height}) ${sec(split.firstImageMs)} s; ` : '';
    this.$('first-frame').textContent = `${image}${sec(split.totalMs)} s: download ${sec(split.downloadMs)}, ` +
      `decode ${sec(split.decodeMs)}, upload ${sec(split.uploadMs)}, ` +
      `compile ${sec(split.compileMs)}${split.compiledWhileDecoding ? ' (beyond the decode)' : ''}, ` +
      `${p ? `preview GPU ${sec(split.previewMs)}, ` : ''}GPU ${sec(split.gpuMs)}`;
  }
}

function sec(ms) {
  return (ms / 1000).toFixed(2);
}

// The pipeline's verdict time (sceneInfo().startup.compiledAt) where it came before the work
// done at `doneAt` was (it then bounds the compile's end and the work's start); else null.
// WebGPU's verdict can arrive after the work it compiled for is done (a late notification, not
// a late compile): then when the compile ended is unknown, the compile counts only what was
// measured of it, and the wait counts as the work's GPU time rather than as none.
function verdictBefore(startup, doneAt) {
  const verdict = startup.compiledAt;
  return verdict != null && verdict < doneAt ? verdict : null;
}
