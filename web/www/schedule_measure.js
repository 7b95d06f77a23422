// `schedule=auto` on WebGPU (web/src/viewer/measure.rs, docs/wavefront.md): once the scene's
// first frame has shown on the megakernel, the wavefront is built beside it on the same device
// and the turns the viewer names (a warm-up frame of each, then megakernel and wavefront
// alternated, rounds of whole frames) are timed as renderFrames times frames: from the first
// submission until the queue is done after the last. The frame loop and the denoiser wait
// meanwhile; the megakernel's frames are shown. The viewer then keeps the faster schedule.

// Measures on `viewer` (or does nothing without one) and resolves to
// sceneInfo().scheduleChoice. `page`: the page's `frameDone()` (a megakernel frame was shown),
// `showMessage(text)`, `showNotice()` and `over()` (called once the measurement is over, however
// it ended).
export async function measureSchedules(viewer, page) {
  const id = viewer ? viewer.beginScheduleMeasurement() : 0;
  try {
    for (let turn = id && viewer.scheduleTurn(id); turn; turn = viewer.scheduleTurn(id)) {
      const start = performance.now();
      for (let i = 0; i < turn.frames; i++) {
        let answer;
        while ((answer = viewer.measureFrame(id)) === 0) await viewer.sync();
        if (answer === 2) return over();
        if (turn.schedule === 'megakernel') page.frameDone();
      }
      await viewer.sync();
      viewer.recordScheduleTurn(id, (performance.now() - start) / turn.frames);
    }
  } catch (e) {
    viewer.abandonScheduleMeasurement(id, `the page's measuring loop failed (${e.message || e})`);
    page.showMessage(String(e.message || e));
  }
  return over();

  function over() {
    page.over();
    const info = viewer ? viewer.sceneInfo() : {};
    // A wavefront that failed while measured: the notice says why the megakernel runs.
    if (info.scheduleChoice && info.scheduleChoice.state === 'failed') page.showNotice();
    return info.scheduleChoice || null;
  }
}
