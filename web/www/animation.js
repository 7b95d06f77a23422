// The animation controls of a scene that moves (a dropped glTF whose animation moves
// something; see web/src/playback.rs): play/pause, a time slider and the speed. Hidden for a
// static scene. The viewer plays by default; paused, samples accumulate on the pose shown.

import { setIfChanged } from './readouts.js';

// Wires the controls to the viewer `getViewer()` returns; `guarded` shows a thrown error.
export function setUpAnimationControls($, getViewer, guarded) {
  $('anim-play').addEventListener('click', () => guarded(() => {
    const info = getViewer().sceneInfo().animation;
    if (info) getViewer().setPlaying(!info.playing);
  }));
  $('anim-time').addEventListener('input', (e) => guarded(() => {
    getViewer().setPlaying(false);
    getViewer().setAnimationTime(Number(e.target.value));
  }));
  $('anim-speed').addEventListener('change', (e) => guarded(() => getViewer().setAnimationSpeed(Number(e.target.value))));
}

// Shows the controls for `info.animation` (sceneInfo()), or hides them (what is unchanged is not
// written again: setIfChanged).
export function showAnimation($, info) {
  const a = info.animation;
  setIfChanged($('animation'), 'hidden', !a);
  if (!a) return;
  setIfChanged($('anim-play'), 'textContent', a.playing ? 'Pause' : 'Play');
  const slider = $('anim-time');
  setIfChanged(slider, 'max', String(a.duration));
  if (document.activeElement !== slider) setIfChanged(slider, 'value', String(a.time));
  setIfChanged($('anim-time-value'), 'textContent', `${a.time.toFixed(2)} / ${a.duration.toFixed(2)} s`);
}

// What moves, for the scene read-out ('' for a static scene).
export function movingText(info) {
  return info.animation ? `; animated: ${info.animation.moving}` : '';
}
