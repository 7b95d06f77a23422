// The viewer's WebGPU device: the first one requested (or, when none comes, WebGL2 under auto)
// and a new one after a device loss, with auto's fallback to WebGL2 when it cannot be recreated.

import { requestWebGpu } from './pkg/lightport_web.js';

// Devices recreated after a loss before auto gives WebGPU up for WebGL2.
const MAX_DEVICE_RECOVERIES = 2;
// Tries, a second apart, at moving a scene to WebGL2 after WebGPU failed under auto.
const WEBGL2_ATTEMPTS = 15;

// `api`: the page's api= (auto, webgpu or webgl2); `hook`: the test hook (startup.device and
// deviceRecoveries are written there); `getViewer()`: the viewer; `showMessage(text, kind)`,
// `showNotice()`, `guarded(action)`: the page's messages; `pause()`: stops the frame loop.
export class WebGpuRecovery {
  constructor({ api, hook, getViewer, showMessage, showNotice, guarded, pause }) {
    Object.assign(this, { api, hook, getViewer, showMessage, showNotice, guarded, pause });
    // A new device is being requested after a loss: no frames meanwhile.
    this.recovering = false;
  }

  // The page's first device (unless api=webgl2); without one, auto goes on with WebGL2 and
  // api=webgpu shows the error.
  async start() {
    const viewer = this.getViewer();
    if (this.api !== 'webgl2') {
      try {
        viewer.useWebGpu(await requestWebGpu());
        this.hook.startup.device = performance.now();
      } catch (e) {
        const why = String(e.message || e);
        this.guarded(() => viewer.webGpuUnavailable(why));
        if (this.api === 'webgpu') this.showMessage(`WebGPU was asked for (api=webgpu) but is not available: ${why}`);
      }
    }
  }

  // The device was lost (GPU reset, driver update, `device.destroy()`): request a new one and
  // recreate the renderer on it from the scene kept in memory, as after a WebGL context restore.
  // Under auto, a device that cannot be recreated, or is lost again and again, hands the scene
  // to WebGL2 with a notice; with `api=webgpu` a failed recreation is the error.
  async recover(reason) {
    const viewer = this.getViewer();
    const hook = this.hook;
    this.recovering = true;
    // Chromium's GPU process may be restarting after the device died, and WebGL2 contexts come
    // back with it: a failed move to WebGL2 is retried for a while before it is the error.
    const fallBack = async (why) => {
      for (let attempt = 1; ; attempt++) {
        try {
          viewer.webGpuUnavailable(why);
          break;
        } catch (e) {
          if (attempt >= WEBGL2_ATTEMPTS) {
            this.showMessage(String(e.message || e));
            return;
          }
          await new Promise((resolve) => setTimeout(resolve, 1000));
        }
      }
      this.showNotice();
    };
    try {
      if (this.api === 'auto' && hook.deviceRecoveries >= MAX_DEVICE_RECOVERIES) {
        await fallBack(`the WebGPU device was lost ${hook.deviceRecoveries + 1} times (last: ${reason})`);
        return;
      }
      this.showMessage(`The WebGPU device was lost (${reason}); requesting a new one…`, 'info');
      try {
        viewer.useWebGpu(await requestWebGpu());
        hook.deviceRecoveries++;
        this.showNotice();
      } catch (e) {
        const why = `a new WebGPU device could not be created after a loss (${reason}): ${e.message || e}`;
        if (this.api === 'auto') {
          await fallBack(why);
        } else {
          this.showMessage(why);
          this.pause();
        }
      }
    } finally {
      this.recovering = false;
    }
  }
}
