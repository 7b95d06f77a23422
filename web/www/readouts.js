// The read-outs' words and numbers (the API line, byte counts and rates), and writing them.

// The API and, on WebGPU, the schedule that runs: "WebGPU, wavefront".
function apiName(info) {
  return info.api === 'WebGPU' ? `${info.api}, ${info.schedule}` : info.api;
}

// The API read-out: "WebGPU, wavefront (auto: 0.62x the megakernel's frame time, measured;
// google / swiftshader)"; without a schedule measurement, the API, schedule and adapter.
export function apiReadout(info) {
  const choice = info.scheduleChoice;
  const details = [choice && choice.reason, info.adapter].filter(Boolean).join('; ');
  return `${apiName(info)} (${details})`;
}

export function formatBytes(n) {
  const units = ['B', 'KB', 'MB', 'GB'];
  let i = 0;
  while (n >= 1000 && i < units.length - 1) { n /= 1000; i++; }
  return `${n.toFixed(i === 0 ? 0 : 1)} ${units[i]}`;
}

export function formatRate(n) {
  if (!Number.isFinite(n) || n <= 0) return '–';
  const units = ['', 'k', 'M', 'G'];
  let i = 0;
  while (n >= 1000 && i < units.length - 1) { n /= 1000; i++; }
  return `${n.toFixed(1)}${units[i]}`;
}

// Sets `element[key]` unless it holds `value` already: a read-out rewritten with what it shows
// still makes the browser lay out and paint the page again, at every animation frame (CPU time
// a software-rendered page takes from its renderer).
export function setIfChanged(element, key, value) {
  if (element[key] !== value) element[key] = value;
}

// The element `id` shows `text` (setIfChanged).
export function setText(id, text) {
  setIfChanged(document.getElementById(id), 'textContent', String(text));
}
