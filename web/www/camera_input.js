// The camera's input on the canvas: drag to orbit (fly mode: drag to look), right- or
// shift-drag (or the middle button) to pan, the wheel to dolly, two fingers to pinch and pan,
// WASD/QE held to fly. `onView(type, handler, options)` listens for the canvas's events,
// `view()` is the canvas, `getViewer()` the viewer (or null), `isFly()` whether fly mode is
// chosen, and `cameraAction(action, at)` applies a camera change at the input's time (the
// page restarts the accumulation and records the latency). Returns `applyHeldKeys(now)`, which
// the frame loop calls each animation frame.

const FLY_KEYS = { w: [1, 0, 0], s: [-1, 0, 0], a: [0, -1, 0], d: [0, 1, 0], e: [0, 0, 1], q: [0, 0, -1] };

export function setUpCameraInput({ onView, view, getViewer, isFly, cameraAction }) {
  const pointers = new Map(); // pointerId -> {x, y, button, shift}
  const heldKeys = new Set();
  let lastKeysAt = null;

  onView('pointerdown', (e) => {
    view().setPointerCapture(e.pointerId);
    view().focus();
    pointers.set(e.pointerId, { x: e.clientX, y: e.clientY, button: e.button, shift: e.shiftKey });
  });

  onView('pointermove', (e) => {
    const p = pointers.get(e.pointerId);
    const viewer = getViewer();
    if (!p || !viewer) return;
    const height = view().clientHeight || 1;
    if (pointers.size === 2) {
      // Two fingers: pinch to dolly, move together to pan.
      const [a, b] = [...pointers.values()];
      const before = Math.hypot(a.x - b.x, a.y - b.y);
      const dx = (e.clientX - p.x) / 2;
      const dy = (e.clientY - p.y) / 2;
      p.x = e.clientX;
      p.y = e.clientY;
      const after = Math.hypot(a.x - b.x, a.y - b.y);
      cameraAction(() => {
        if (before > 0 && after > 0) viewer.dolly(before / after);
        viewer.pan(-dx / height, dy / height);
      }, e.timeStamp);
      return;
    }
    const dx = e.clientX - p.x;
    const dy = e.clientY - p.y;
    p.x = e.clientX;
    p.y = e.clientY;
    if (dx === 0 && dy === 0) return;
    const radians = Math.PI / height;
    const fly = isFly();
    if (p.button === 2 || p.button === 1 || p.shift) {
      cameraAction(() => viewer.pan(-dx / height, dy / height), e.timeStamp);
    } else if (fly) {
      cameraAction(() => viewer.look(dx * radians * 0.5, -dy * radians * 0.5), e.timeStamp);
    } else {
      cameraAction(() => viewer.orbit(dx * radians, -dy * radians), e.timeStamp);
    }
  });

  for (const type of ['pointerup', 'pointercancel']) {
    onView(type, (e) => pointers.delete(e.pointerId));
  }
  onView('contextmenu', (e) => e.preventDefault());

  onView('wheel', (e) => {
    e.preventDefault();
    const viewer = getViewer();
    if (viewer) cameraAction(() => viewer.dolly(Math.exp(Math.max(-100, Math.min(100, e.deltaY)) * 0.002)), e.timeStamp);
  }, { passive: false });

  onView('keydown', (e) => {
    const key = e.key.toLowerCase();
    if (key in FLY_KEYS) {
      heldKeys.add(key);
      e.preventDefault();
    }
  });
  onView('keyup', (e) => heldKeys.delete(e.key.toLowerCase()));
  onView('focusout', () => heldKeys.clear());

  // Fly keys move at a quarter of the scene's size per second while held.
  function applyHeldKeys(now) {
    const viewer = getViewer();
    if (heldKeys.size === 0 || !viewer) {
      lastKeysAt = null;
      return;
    }
    const dt = lastKeysAt === null ? 1 / 60 : Math.min(0.1, (now - lastKeysAt) / 1000);
    lastKeysAt = now;
    const step = [0, 0, 0];
    for (const key of heldKeys) FLY_KEYS[key].forEach((v, i) => { step[i] += v * dt * 0.25; });
    cameraAction(() => viewer.fly(step[0], step[1], step[2]), now);
  }

  return applyHeldKeys;
}
