// The harness page: the wasm module's HarnessRuntime (web/src/harness.rs: the native GlHarness on
// WebGL2 and WgpuHarness on WebGPU) behind `window.lightportHarness`, which tests/web/harness.mjs
// calls. Words arrive as blobs fetched from the driver and leave as base64.

import init, { HarnessRuntime } from './pkg/lightport_web.js';

const runtimes = new Map();
let nextId = 1;

async function fetchBytes(url) {
  const response = await fetch(url);
  if (!response.ok) throw new Error(`fetching ${url}: ${response.status}`);
  return new Uint8Array(await response.arrayBuffer());
}

function wordsOf(bytes) {
  if (bytes.byteLength % 4 !== 0) throw new Error(`${bytes.byteLength} bytes of words`);
  return new Uint32Array(bytes.buffer, bytes.byteOffset, bytes.byteLength / 4);
}

function base64(words) {
  const bytes = new Uint8Array(words.buffer, words.byteOffset, words.byteLength);
  if (bytes.toBase64) return bytes.toBase64();
  let text = '';
  for (let i = 0; i < bytes.length; i += 0x8000) text += String.fromCharCode(...bytes.subarray(i, i + 0x8000));
  return btoa(text);
}

function runtime(id) {
  const r = runtimes.get(id);
  if (!r) throw new Error(`no harness runtime ${id}`);
  return r;
}

window.lightportHarness = {
  ready: false,
  error: null,
  async create(kind, modulesUrl) {
    const modules = new TextDecoder().decode(await fetchBytes(modulesUrl));
    let r;
    if (kind === 'webgl2') r = HarnessRuntime.webgl2(modules);
    else if (kind === 'webgpu') r = await HarnessRuntime.webgpu(modules);
    else throw new Error(`unknown runtime ${kind}`);
    const id = nextId++;
    runtimes.set(id, r);
    return { id, info: r.info() };
  },
  async scene(id, wordsUrl) {
    runtime(id).setScene(wordsOf(await fetchBytes(wordsUrl)));
    return {};
  },
  async layout(id, fn, specialize) {
    const r = runtime(id);
    r.setSpecialization(specialize);
    const [inputWords, outputWords] = await r.layout(fn);
    return { inputWords, outputWords };
  },
  // `flip` >= 0 (tests): flip the lowest bit of that output word.
  async run(id, fn, invocations, specialize, wordsUrl, flip) {
    const r = runtime(id);
    r.setSpecialization(specialize);
    const out = await r.runWords(fn, invocations, wordsOf(await fetchBytes(wordsUrl)));
    if (flip >= 0 && flip < out.length) out[flip] ^= 1;
    return { words: base64(out) };
  },
  async filter(id, wordsUrl) {
    const out = await runtime(id).runFilter(wordsOf(await fetchBytes(wordsUrl)));
    return { words: base64(out.words), ms: out.ms };
  },
  drop(id) {
    const r = runtimes.get(id);
    if (r) {
      runtimes.delete(id);
      r.free();
    }
    return {};
  },
};

try {
  await init();
  window.lightportHarness.ready = true;
} catch (e) {
  window.lightportHarness.error = `the wasm module did not load: ${e}`;
}
