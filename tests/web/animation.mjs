// The `animation` scenario: a moving glTF (`--files PATH`) opened on the page, which plays it.
// Reports the animation's read-outs, the accumulation at three poses set while paused
// (0 s, 0.8 s, 0 s again: the accumulation restarts at each, the same pose renders the same
// image), and a few seconds of the frame loop playing (the time moves on, the accumulation
// keeps restarting) then paused (samples accumulate).

import { readFileSync, rmSync } from 'node:fs';
import { freshProfile, open, withBrowser } from './page.mjs';

export async function animation(o) {
  const profile = freshProfile();
  try {
    return await withBrowser(profile, async (context) => {
      const { page, error } = await open(context, o.url, { scene: o.scene, size: o.size, paused: '1' });
      if (error) return { error };
      const file = { name: o.files.split('/').pop(), mimeType: 'model/gltf+json', buffer: readFileSync(o.files) };
      await page.setInputFiles('#file-input', [file]);
      await page.waitForFunction(
        (name) => window.lightport.error || window.lightport.info().name === name,
        file.name,
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
      if (loaded.error) return loaded;
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
      const playing = await page.evaluate(async () => {
        const l = window.lightport;
        const wait = (ms) => new Promise((resolve) => setTimeout(resolve, ms));
        l.setAnimationSpeed(0.25);
        l.setPlaying(true);
        l.resume();
        const start = l.animation().time;
        let maxSpp = 0;
        const t0 = performance.now();
        while (performance.now() - t0 < 4000) {
          await wait(50);
          maxSpp = Math.max(maxSpp, l.spp());
        }
        const moved = l.animation().time;
        l.setPlaying(false);
        await wait(200);
        const pausedAt = l.spp();
        await wait(4000);
        return { start, moved, maxSppWhilePlaying: maxSpp, pausedAt, afterPause: l.spp(), poseMs: l.animation().poseMs };
      });
      return { loaded, readout, poses, playing, error: await page.evaluate(() => window.lightport.error) };
    });
  } finally {
    rmSync(profile, { recursive: true, force: true });
  }
}
