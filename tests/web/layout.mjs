// The `layout` scenario: the page as a person opens it, sized by its window (no `size=`), the
// frame loop running, every setting the page's default. After the first frame it watches the
// render size and the samples per pixel for `--seconds` (default 12), polling between tasks:
// every change of size (each recreates the renderer and restarts the accumulation), every
// restart (spp falling) and the most samples per pixel reached. The read-outs below the image
// wrap by their text, and the text changes as the image converges: the render size must not
// follow it back and forth.

import { rmSync } from 'node:fs';
import { freshProfile, open, withBrowser } from './page.mjs';

export async function layout(o) {
  const profile = freshProfile();
  try {
    return await withBrowser(profile, async (context) => {
      const { page, error } = await open(context, o.url, { scene: o.scene });
      if (error) return { error };
      await page.waitForFunction(() => window.lightport.frames > 0 || window.lightport.error, null, { timeout: 240000 });
      const watched = await page.evaluate(async (seconds) => {
        const l = window.lightport;
        const size = () => { const i = l.info(); return `${i.width}x${i.height}`; };
        const sizes = [size()];
        let restarts = 0;
        let last = l.spp();
        let maxSpp = last;
        const end = performance.now() + seconds * 1000;
        while (performance.now() < end && !l.error) {
          await new Promise((r) => setTimeout(r, 5));
          const s = size();
          if (s !== sizes.at(-1)) sizes.push(s);
          const spp = l.spp();
          if (spp < last) restarts++;
          last = spp;
          maxSpp = Math.max(maxSpp, spp);
        }
        return { sizes, restarts, maxSpp, spp: l.spp() };
      }, Number(o.seconds || '12'));
      const info = await page.evaluate(() => window.lightport.info());
      const pageError = await page.evaluate(() => window.lightport.error);
      return { error: pageError, ...watched, info };
    });
  } finally {
    rmSync(profile, { recursive: true, force: true });
  }
}
