// The scenarios about which graphics API runs the page: `api` (the API chosen, and the split
// of the time to the first frame), `fallback` (auto's move to WebGL2 when WebGPU fails) and
// `deviceloss` (a new WebGPU device after a loss). Run through run.mjs.

import { rmSync } from 'node:fs';
import { freshProfile, open, withBrowser } from './page.mjs';

// Which API runs (`--api`, optionally `--maxStorageBuffers N` and `--prepare 0`): the page's info, its API
// read-out and message after two frames, and what the page reported.
export async function apiChoice(o) {
  const profile = freshProfile();
  try {
    return await withBrowser(profile, async (context) => {
      const { page, error, consoleErrors } = await open(context, o.url, {
        scene: o.scene, size: o.size, paused: '1', maxStorageBuffers: o.maxStorageBuffers, prepare: o.prepare,
      });
      const rendered = error ? null : await page.evaluate(async () => {
        await window.lightport.renderFrames(2);
        const a = await window.lightport.readAccumulation();
        return { spp: a.spp, sum: a.data.reduce((x, y) => x + y, 0) };
      });
      // The page's split of the time to its first frame, once it has made it.
      const firstFrame = error ? null : await page.waitForFunction(() => window.lightport.firstFrame, null, { timeout: 30000 })
        .then(() => page.evaluate(() => window.lightport.firstFrame), () => null);
      return {
        firstFrame,
        firstFrameMs: await page.evaluate(() => window.lightport.firstFrameMs),
        firstFrameReadout: await page.evaluate(() => document.getElementById('first-frame')?.textContent ?? null),
        error: await page.evaluate(() => window.lightport.error),
        firstError: error,
        notice: await page.evaluate(() => window.lightport.notice || null),
        info: await page.evaluate(() => window.lightport.info()),
        textureChecksum: await page.evaluate(() => window.lightport.textureChecksum()),
        // The read-outs' times over at least 8 more animation frames (the frame loop's).
        readoutMs: await page.evaluate(() => new Promise((resolve) => {
          let n = 0;
          const frame = () => (++n >= 8 ? resolve(window.lightport.readoutMs) : requestAnimationFrame(frame));
          requestAnimationFrame(frame);
        })),
        readout: await page.textContent('#api-info'),
        messageText: await page.textContent('#message'),
        rendered,
        consoleErrors,
      };
    });
  } finally {
    rmSync(profile, { recursive: true, force: true });
  }
}

// A WebGPU that fails under the page (e.g. `--browser webgl2` with `--api auto`: Chromium gives
// a device that dies at its first frame, and no new one): waits until the page settles on an
// API, then renders two frames. Reports the API, the notice, the message box and the frames.
export async function fallback(o) {
  const profile = freshProfile();
  try {
    return await withBrowser(profile, async (context) => {
      const { page, error } = await open(context, o.url, { scene: o.scene, size: o.size, paused: '1' });
      if (error) return { error };
      // Losses are noticed by the frame loop; frames give the device its chances to fail. A
      // promise of the dying device may reject on the way: recorded, not thrown.
      let settled = false;
      const rejections = [];
      for (const start = Date.now(); !settled && Date.now() - start < 120000;) {
        settled = await page.evaluate(async () => {
          const l = window.lightport;
          if (l.error || l.info().api === 'WebGL2') return true;
          await l.renderFrames(1);
          await new Promise((resolve) => setTimeout(resolve, 250));
          return false;
        }).catch((e) => { rejections.push(String(e)); return false; });
      }
      const rendered = await page.evaluate(async () => {
        await window.lightport.renderFrames(2);
        const a = await window.lightport.readAccumulation();
        return { spp: a.spp, sum: a.data.reduce((x, y) => x + y, 0) };
      }).catch((e) => ({ rejected: String(e) }));
      return {
        rejections,
        rendered,
        settled,
        error: await page.evaluate(() => window.lightport.error),
        notice: await page.evaluate(() => window.lightport.notice || null),
        info: await page.evaluate(() => window.lightport.info()),
        messageKind: await page.evaluate(() => document.getElementById('message').className),
        messageText: await page.textContent('#message'),
        readout: await page.textContent('#api-info'),
      };
    });
  } finally {
    rmSync(profile, { recursive: true, force: true });
  }
}

// WebGPU device loss (`GPUDevice.destroy()` through the hook): the page requests a new device
// and recreates the renderer from the scene in memory, then keeps rendering.
export async function deviceLoss(o) {
  const profile = freshProfile();
  try {
    return await withBrowser(profile, async (context) => {
      const { page, error, info } = await open(context, o.url, { scene: o.scene, size: o.size, paused: '1' });
      if (error) return { error };
      await page.evaluate(() => window.lightport.renderFrames(4));
      const before = await page.evaluate(() => window.lightport.spp());
      // `--losses N` (default 1): the device is lost N times, each once the page has recovered
      // from the last (or moved to WebGL2).
      for (let i = 0; i < Number(o.losses || 1); i++) {
        if (await page.evaluate(() => window.lightport.info().api !== 'WebGPU')) break;
        await page.evaluate(() => window.lightport.loseWebGpu());
        await page.waitForFunction((k) => window.lightport.deviceRecoveries > k || window.lightport.error
          || window.lightport.info().api === 'WebGL2', i, { timeout: 60000 });
      }
      const restored = await page.evaluate(async () => {
        const sppAfterLoss = window.lightport.spp();
        await window.lightport.renderFrames(3);
        const data = (await window.lightport.readAccumulation()).data;
        return {
          sppAfterLoss,
          spp: window.lightport.spp(),
          error: window.lightport.error,
          recoveries: window.lightport.deviceRecoveries,
          sum: data.reduce((a, b) => a + b, 0),
          info: window.lightport.info(),
        };
      });
      return { info, before, restored, error: restored.error };
    });
  } finally {
    rmSync(profile, { recursive: true, force: true });
  }
}

// `schedule=auto` on WebGPU measured in the page (web/src/viewer/measure.rs): the page opens
// unpaused, so its frame loop starts the measurement after the scene's first frame; waits until
// it is over, then pauses and renders two frames. `--autoScheduleTimes MK,WF` injects the times
// decided on (test only); `--during orbit|lose` turns the camera or loses the WebGPU device once
// the measurement is under way. Reports the choice, the read-out, notice and what rendered.
export async function autoSchedule(o) {
  const profile = freshProfile();
  try {
    return await withBrowser(profile, async (context) => {
      const { page, error, consoleErrors } = await open(context, o.url, {
        scene: o.scene, size: o.size, autoScheduleTimes: o.autoScheduleTimes, maxStorageBuffers: o.maxStorageBuffers,
      });
      if (error) return { error, consoleErrors };
      const state = () => page.evaluate(() => (window.lightport.info().scheduleChoice || {}).state || null);
      // An interrupted measurement starts again once the view stays put: not over yet.
      const over = (s) => s !== 'pending' && s !== 'measuring' && s !== 'interrupted';
      if (o.during) {
        await page.waitForFunction(() => {
          const c = window.lightport.info().scheduleChoice;
          return !c || c.state !== 'pending';
        }, null, { timeout: 300000 });
        if (o.during === 'orbit') await page.evaluate(() => window.lightport.orbit(0.2, 0));
        if (o.during === 'lose') {
          await page.evaluate(() => window.lightport.loseWebGpu());
          await page.waitForFunction(() => window.lightport.deviceRecoveries > 0 || window.lightport.error, null,
            { timeout: 120000 });
        }
      }
      const start = Date.now();
      while (!over(await state()) && Date.now() - start < 600000) await page.waitForTimeout(250);
      // The read-out is written at the next animation frame.
      await page.evaluate(() => new Promise((resolve) => requestAnimationFrame(() => requestAnimationFrame(resolve))));
      const readout = await page.textContent('#api-info');
      const framesBefore = await page.evaluate(() => window.lightport.frames);
      const rendered = await page.evaluate(async () => {
        window.lightport.pause();
        await window.lightport.renderFrames(2);
        const a = await window.lightport.readAccumulation();
        return { spp: a.spp, sum: a.data.reduce((x, y) => x + y, 0) };
      }).catch((e) => ({ rejected: String(e) }));
      return {
        info: await page.evaluate(() => window.lightport.info()),
        readout,
        framesBefore,
        rendered,
        error: await page.evaluate(() => window.lightport.error),
        notice: await page.evaluate(() => window.lightport.notice || null),
        messageKind: await page.evaluate(() => document.getElementById('message').className),
        deviceRecoveries: await page.evaluate(() => window.lightport.deviceRecoveries),
        consoleErrors,
      };
    });
  } finally {
    rmSync(profile, { recursive: true, force: true });
  }
}
