// The `animation` scenario: a moving glTF (`--files PATH`) opened on the page, which plays it;
// without `--files`, the served scene `--scene NAME` (a bundle with a motion section), which
// plays the same way.
// Reports the animation's read-outs, the accumulation at three poses set while paused
// (0 s, 0.8 s, 0 s again: the accumulation restarts at each, the same pose renders the same
// image), and a few seconds of the frame loop playing (the time moves on, the accumulation
// keeps restarting) then paused (samples accumulate). `--soak SECONDS`: then plays at real
// speed that long (`--preview 0|1`: the page's preview per pose, default on) and reports, each second, the poses shown, the module's live heap, the
// WebAssembly memory and the JS heap (what the page keeps growing, if anything, while it poses the scene again and again).

import { readFileSync, rmSync } from 'node:fs';
import { freshProfile, median, open, withBrowser } from './page.mjs';

export async function animation(o) {
  const profile = freshProfile();
  try {
    return await withBrowser(profile, async (context) => {
      const { page, error } = await open(context, o.url, { scene: o.scene, size: o.size, paused: '1', preview: o.preview });
      if (error) return { error };
      let name = o.scene;
      if (o.files) {
        name = o.files.split('/').pop();
        const mimeType = name.toLowerCase().endsWith('.glb') ? 'model/gltf-binary' : 'model/gltf+json';
        const file = { name, mimeType, buffer: readFileSync(o.files) };
        await page.setInputFiles('#file-input', [file]);
      }
      await page.waitForFunction(
        (name) => window.lightport.error || window.lightport.info().name === name,
        name,
        { timeout: 120000 },
      );
      // The controls show with the loaded scene (or at the next read-out update).
      await page.waitForFunction(() => !document.getElementById('animation').hidden, null, { timeout: 10000 })
        .catch(() => {});
      const loaded = await page.evaluate(() => ({
        error: window.lightport.error,
        animation: window.lightport.animation(),
        controlsShown: !document.getElementById('animation').hidden,
        api: window.lightport.info().api,
      }));
      // A scene that does not play (no `animation`): what was loaded, for the caller to say so.
      if (loaded.error || !loaded.animation) return { loaded, error: loaded.error };
      const readout = await page.textContent('#scene-info');
      const poses = await page.evaluate(async () => {
        const l = window.lightport;
        l.setPlaying(false);
        const at = async (t) => {
          l.setAnimationTime(t);
          const restarted = l.spp();
          await l.renderFrames(2);
          const a = await l.readAccumulation();
          return { t, restarted, spp: a.spp, data: a.data };
        };
        return [await at(0), await at(0.8), await at(0)];
      });
      // Under schedule=auto on WebGPU the page measures the schedules once a frame has shown,
      // and the frame loop (and with it the animation) waits meanwhile: seconds of SwiftShader
      // on a loaded machine. Measured first, so the playing window times the frame loop alone.
      const scheduleChoice = await page.evaluate(() => window.lightport.measureSchedule());
      await page.waitForFunction(() => (window.lightport.info().scheduleChoice || {}).state !== 'measuring', null,
        { timeout: 120000 });
      const playing = await page.evaluate(async () => {
        const l = window.lightport;
        const wait = (ms) => new Promise((resolve) => setTimeout(resolve, ms));
        l.setAnimationSpeed(0.25);
        l.setPlaying(true);
        l.resume();
        const start = l.animation().time;
        const [framesBefore, previewsBefore, posesBefore] = [l.frames, l.info().preview.rendered, l.animation().poses];
        let maxSpp = 0;
        // The times shown, sampled: the time wraps over the animation's length, so the time at
        // the end of the window says nothing (4 s at 0.25x of a 1 s animation ends where it began).
        const times = new Set();
        // The band policy's estimate of a whole frame (its cost per row times the rows): a
        // restart is previewed only where it exceeds the budget.
        let maxFrameMsEstimate = null;
        // Sampled from the first pose on: until the frame loop's next tick poses the scene, the
        // accumulation is still the paused one (on a loaded machine that tick came after the
        // first sample, which then read the paused samples as accumulated while moving).
        const waitedFrom = performance.now();
        while (l.animation().poses === posesBefore && performance.now() - waitedFrom < 10000) await wait(5);
        const t0 = performance.now();
        while (performance.now() - t0 < 4000) {
          await wait(50);
          maxSpp = Math.max(maxSpp, l.spp());
          times.add(l.animation().time);
          const i = l.info();
          if (i.bandMs !== null) maxFrameMsEstimate = Math.max(maxFrameMsEstimate ?? 0, i.bandMs / i.bandRows * i.height);
        }
        const moved = l.animation().time;
        const posesWhilePlaying = l.animation().poses - posesBefore;
        const framesWhilePlaying = l.frames - framesBefore;
        const previewsWhilePlaying = l.info().preview.rendered - previewsBefore;
        l.setPlaying(false);
        await wait(200);
        const pausedAt = l.spp();
        await wait(4000);
        return {
          start, moved, timesShown: times.size, posesWhilePlaying, maxSppWhilePlaying: maxSpp, framesWhilePlaying,
          previewsWhilePlaying, maxFrameMsEstimate, bandBudgetMs: l.info().bandBudgetMs,
          pausedAt, afterPause: l.spp(), poseMs: l.animation().poseMs,
        };
      });
      const soak = o.soak ? await page.evaluate(playFor, Number(o.soak)) : null;
      return { loaded, readout, poses, scheduleChoice, playing, soak, error: await page.evaluate(() => window.lightport.error) };
    });
  } finally {
    rmSync(profile, { recursive: true, force: true });
  }
}

// In the page: plays the animation at real speed for `seconds`, sampling once a second what the
// page holds. The WebAssembly memory only grows (it is never given back), so a pose's arrays
// kept by mistake show as growth after the first seconds.
async function playFor(seconds) {
  const l = window.lightport;
  const wait = (ms) => new Promise((resolve) => setTimeout(resolve, ms));
  l.setAnimationSpeed(1);
  l.setPlaying(true);
  l.resume();
  const sample = (t) => ({
    t,
    poses: l.animation().poses,
    animationTime: l.animation().time,
    poseMs: l.animation().poseMs,
    wasmBytes: l.wasmMemoryBytes(),
    heapBytes: l.heapBytes(),
    jsHeapBytes: performance.memory ? performance.memory.usedJSHeapSize : null,
  });
  const samples = [sample(0)];
  const t0 = performance.now();
  for (let s = 1; s <= seconds; s++) {
    await wait(Math.max(0, t0 + s * 1000 - performance.now()));
    samples.push(sample(s));
  }
  l.setPlaying(false);
  return { seconds, samples, error: l.error };
}

// The bench's `--play SECONDS` (bench.mjs): in the page, the frame loop run with the animation
// playing at real speed for `seconds`, then paused as long, twice, alternated (play, pause,
// play, pause; half a second's settling before each turn, not counted). Per turn: poses shown,
// previews and whole frames completed per second, and the median time of a pose on the host.
export async function playAndPause(seconds) {
  const l = window.lightport;
  // Under schedule=auto on WebGPU a measurement due would stall the turns (a moving scene's is
  // skipped: its result is null at once).
  await l.measureSchedule();
  const wait = (ms) => new Promise((resolve) => setTimeout(resolve, ms));
  const turns = [];
  l.setAnimationSpeed(1);
  for (const playing of [true, false, true, false]) {
    l.setPlaying(playing);
    l.resume();
    await wait(500);
    const before = { frames: l.frames, poses: l.animation().poses, previews: l.info().preview.rendered };
    const poseMs = [];
    const t0 = performance.now();
    while (performance.now() - t0 < seconds * 1000) {
      await wait(100);
      poseMs.push(l.animation().poseMs);
    }
    const s = (performance.now() - t0) / 1000;
    turns.push({
      playing,
      seconds: s,
      framesPerS: (l.frames - before.frames) / s,
      posesPerS: (l.animation().poses - before.poses) / s,
      previewsPerS: (l.info().preview.rendered - before.previews) / s,
      poseMs: median(poseMs),
    });
  }
  l.setPlaying(false);
  l.pause();
  return turns;
}
