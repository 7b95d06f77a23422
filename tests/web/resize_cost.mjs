// What a resize costs, against a preview (docs/web.md, "The first image: a preview"): the
// Cornell box opened paused at 640x480; a preview (renderPreview) and the first full frame,
// timed; two more frames; then setSize(320, 240) (a new renderer: codegen, compile, upload)
// and its first frame, timed, and the new renderer's own startup times; then a second frame.
//
//   node tests/web/resize_cost.mjs --url http://127.0.0.1:PORT/ [--api webgl2|webgpu]
//
// Prints JSON. Not part of the test suite (a measurement; `lightport serve` must be running).

import { freshProfile, open, setPageApi, withBrowser } from './page.mjs';
import { rmSync } from 'node:fs';

const args = Object.fromEntries(process.argv.slice(2).reduce((pairs, a, i, all) => {
  if (a.startsWith('--')) pairs.push([a.slice(2), all[i + 1]]);
  return pairs;
}, []));
setPageApi(args.api || 'webgl2');
const profile = freshProfile();
try {
  const result = await withBrowser(profile, async (context) => {
    const { page, error } = await open(context, args.url, {
      scene: 'cornell-box', size: '640x480', paused: '1', denoise: '0', schedule: 'megakernel',
    });
    if (error) return { error };
    return page.evaluate(async () => {
      const l = window.lightport;
      const timed = async (f) => { const t = performance.now(); await f(); await l.viewer.sync(); return performance.now() - t; };
      const previewMs = await timed(() => l.renderPreview());
      const firstFrameMs = await timed(() => l.renderFrames(1));
      const laterFrameMs = await timed(() => l.renderFrames(2)) / 2;
      const resizeMs = await timed(() => l.viewer.setSize(320, 240));
      const startupAfterResize = l.info().startup;
      const firstFrameAfterResizeMs = await timed(() => l.renderFrames(1));
      const laterFrameAfterResizeMs = await timed(() => l.renderFrames(1));
      return {
        api: l.info().api, previewMs, firstFrameMs, laterFrameMs, resizeMs, startupAfterResize,
        firstFrameAfterResizeMs, laterFrameAfterResizeMs,
      };
    });
  });
  console.log(JSON.stringify(result));
} finally {
  rmSync(profile, { recursive: true, force: true });
}
