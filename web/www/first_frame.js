// The first frame, accounted for: the time from a served scene's load (the page's first scene:
// from the navigation's start) until its first frame is finished on the GPU, split into
// download, decode, upload, compile, GPU and the rest (the read-out "first frame", the test
// hook's `firstFrame`), and the test hook's `firstFrameMs` (the page's first frame on screen).

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
  }

  begin(name, start = performance.now()) {
    this.loading = { name, start, fetchStart: null, fetched: null, submitted: null, waiting: false };
    this.hook.firstFrame = null;
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

  // A frame was completed (queued): the page's first frame, and a load's first one, are waited
  // for on the GPU.
  frameDone() {
    const viewer = this.getViewer();
    if (!this.firstFrameWaited) {
      // The first frame counts once it is on screen, not when it is queued.
      this.firstFrameWaited = true;
      viewer.sync().then(() => { this.hook.firstFrameMs = performance.now(); });
    }
    if (this.loading && !this.loading.waiting) {
      this.loading.waiting = true;
      const load = this.loading;
      viewer.sync().then(() => this.finish(load, performance.now()));
    }
  }

  // The first frame of `load` is finished on the GPU (at `doneAt`): splits its time from the
  // page's marks and the viewer's own (sceneInfo().startup: decode, upload, compile in wasm, and
  // on WebGPU when the device's verdict on the pipeline arrived).
  async finish(load, doneAt) {
    const viewer = this.getViewer();
    // WebGPU's verdict arrives as a promise: the frame ran after the compile, so it is there.
    for (let i = 0; i < 50 && viewer.sceneInfo().startup && viewer.sceneInfo().startup.compiledAt === null; i++) {
      await new Promise((resolve) => setTimeout(resolve, 10));
    }
    if (load !== this.loading) return; // another scene was loaded meanwhile
    this.loading = null;
    const info = viewer.sceneInfo();
    const s = info.startup;
    if (!s) return;
    const compiledAt = Math.min(s.compiledAt ?? doneAt, doneAt);
    const split = {
      api: info.api,
      scene: load.name,
      totalMs: doneAt - load.start,
      downloadMs: load.fetched !== null && load.fetchStart !== null ? load.fetched - load.fetchStart : 0,
      decodeMs: s.decodeMs,
      uploadMs: s.uploadMs,
      compileMs: s.codegenMs + s.compileMs + Math.max(0, compiledAt - s.createdAt),
      gpuMs: doneAt - Math.max(load.submitted ?? doneAt, compiledAt),
    };
    split.otherMs = split.totalMs - split.downloadMs - split.decodeMs - split.uploadMs - split.compileMs - split.gpuMs;
    this.hook.firstFrame = split;
    const sec = (ms) => (ms / 1000).toFixed(2);
    this.$('first-frame').textContent = `${sec(split.totalMs)} s: download ${sec(split.downloadMs)}, decode ` +
      `${sec(split.decodeMs)}, upload ${sec(split.uploadMs)}, compile ${sec(split.compileMs)}, GPU ${sec(split.gpuMs)}`;
  }
}
