// The `preview` scenario: the page as a person opens it (the frame loop running, the denoiser
// off), `--preview 0|1` (default: the page's own, on). Reports the canvas copied while the
// preview shows (the first image: each of its pixels a block of the canvas), the read-out then,
// the page's record of the previews shown, its first-image and first-frame accounting
// (firstImage, firstFrame, firstImageMs, firstFrameMs), sceneInfo() and the read-outs once the
// first full-resolution frame is done; then one camera move (`orbit`): the canvas copied while
// the new view's preview shows (`afterMove`) and the preview's state once it is replaced.

import { rmSync } from 'node:fs';
import { freshProfile, open, withBrowser } from './page.mjs';

export async function preview(o) {
  const profile = freshProfile();
  try {
    return await withBrowser(profile, async (context) => {
      const { page, error } = await open(context, o.url, {
        scene: o.scene, size: o.size, denoise: '0', preview: o.preview, bandBudget: o.bandBudget,
      });
      if (error) return { error };
      // Each animation frame (after the page's own tick), until the first full frame is
      // accounted for: while the preview shows, the canvas copied in the same task as a redraw.
      const shot = await shotWhilePreviewShows(page, 1);
      await page.waitForFunction(() => window.lightport.firstFrame || window.lightport.error, null, { timeout: 240000 });
      // The read-outs are written by the frame loop: two animation frames later.
      await page.evaluate(() => new Promise((r) => requestAnimationFrame(() => requestAnimationFrame(r))));
      const settled = await page.evaluate(() => ({ info: window.lightport.info(), spp: window.lightport.spp() }));
      // A camera move restarts the accumulation: the new view is previewed too, then replaced.
      await page.evaluate(() => window.lightport.orbit(0.3, 0));
      const afterMove = await shotWhilePreviewShows(page, 2);
      await page.waitForFunction(() => window.lightport.error || window.lightport.spp() >= 1, null, { timeout: 240000 });
      const replaced = await page.evaluate(() => window.lightport.info().preview);
      return page.evaluate(({ shot, settled, afterMove, replaced }) => {
        const l = window.lightport;
        return {
          shot,
          previews: l.previews,
          firstImage: l.firstImage,
          firstImageMs: l.firstImageMs,
          firstFrame: l.firstFrame,
          firstFrameMs: l.firstFrameMs,
          info: l.info(),
          imageReadout: document.getElementById('denoise-info').textContent,
          firstFrameReadout: document.getElementById('first-frame').textContent,
          settled,
          afterMove,
          replacedAfterMove: replaced,
          error: l.error,
        };
      }, { shot, settled, afterMove, replaced });
    });
  } finally {
    rmSync(profile, { recursive: true, force: true });
  }
}

// The canvas copied while the `rendered`-th preview since the load shows (each animation frame,
// after the page's own tick, in the same task as a redraw), or null if the page finished a full
// frame first (or has previews off, or failed).
function shotWhilePreviewShows(page, rendered) {
  return page.evaluate((rendered) => new Promise((resolve) => {
    const look = () => {
      const l = window.lightport;
      const info = l.info();
      if (info.preview && info.preview.showing && info.preview.rendered >= rendered) {
        l.draw();
        const view = l.viewer.canvas;
        const copy = document.createElement('canvas');
        copy.width = view.width;
        copy.height = view.height;
        const context2d = copy.getContext('2d');
        context2d.drawImage(view, 0, 0);
        const pixels = Array.from(context2d.getImageData(0, 0, view.width, view.height).data);
        resolve({
          width: view.width, height: view.height, pixels, spp: l.spp(), preview: info.preview,
          readout: document.getElementById('denoise-info').textContent,
        });
      } else if (l.error || (rendered === 1 && l.firstFrame) || (rendered > 1 && (info.preview.state === 'off' || l.spp() > 0))) {
        resolve(null);
      } else {
        requestAnimationFrame(look);
      }
    };
    requestAnimationFrame(look);
  }), rendered);
}
