// The browser runtimes of the equivalence harness (tracer/src/backend/harness/browser.rs): one
// headless Chromium (Debian's /usr/bin/chromium through playwright-core, the flags of DESIGN.md
// plus --enable-unsafe-webgpu) with the harness page (web/www/harness.html and harness.js, the
// wasm build in web/pkg/) served by this script on http://127.0.0.1 (a secure context: WebGPU
// needs one). It decides nothing: it relays requests to the page and its replies back.
//
//   node harness.mjs --root REPOSITORY
//
// Protocol: one JSON request per line on stdin, one reply per request on stdout, in order, as
// `@lp ` + JSON ({ ok: true, ... } or { ok: false, error }); the first line says the page is
// ready. Words travel as base64 of their little-endian bytes; to the page as a fetched blob.
// Requests: { op: 'create', runtime: 'webgl2'|'webgpu', modules } -> { id, info };
// { op: 'scene', id, words }; { op: 'layout', id, function, specialize } -> { inputWords,
// outputWords }; { op: 'run', id, function, invocations, specialize, words, corrupt } -> { words };
// { op: 'filter', id, words } -> { words, ms } (the denoiser's passes over an encoded FilterImage,
// and their time in the page);
// { op: 'drop', id }. `corrupt` (tests): { flip: K } (the page flips a bit of word K),
// 'truncate', 'garbage' or 'hang'.
//
// Exits (closing the browser) when stdin ends: the caller holds the pipe's other end, which the
// kernel closes however the caller ends, so neither this driver nor its browser outlives it.

import { chromium } from 'playwright-core';
import { createServer } from 'node:http';
import { mkdtempSync, rmSync, readFileSync, existsSync } from 'node:fs';
import { tmpdir } from 'node:os';
import { join, normalize } from 'node:path';
import { createInterface } from 'node:readline';

const CHROMIUM = process.env.CHROMIUM || '/usr/bin/chromium';
const ARGS = [
  '--headless=new', '--no-sandbox', '--use-angle=swiftshader', '--enable-unsafe-swiftshader', '--disable-gpu',
  '--disable-background-networking', '--disable-component-update', '--disable-sync', '--no-first-run',
  '--disable-quic', '--enable-unsafe-webgpu',
];
const TYPES = { '.html': 'text/html', '.js': 'text/javascript', '.wasm': 'application/wasm' };

const rootIndex = process.argv.indexOf('--root');
if (rootIndex < 0 || !process.argv[rootIndex + 1]) {
  console.error('usage: node harness.mjs --root REPOSITORY');
  process.exit(2);
}
const root = process.argv[rootIndex + 1];
const profile = mkdtempSync(join(tmpdir(), 'lightport-harness-'));

function reply(value) {
  process.stdout.write(`@lp ${JSON.stringify(value)}\n`);
}

function shutdown(code, why) {
  if (why) console.error(`harness.mjs: ${why}`);
  rmSync(profile, { recursive: true, force: true });
  // process.exit runs playwright's exit handler, which kills the browser it launched.
  process.exit(code);
}

// Blobs the page fetches once: the words of a request.
const blobs = new Map();
let nextBlob = 1;
function blob(bytes) {
  const id = nextBlob++;
  blobs.set(String(id), bytes);
  return `/blob/${id}`;
}

// The page, its wasm build and the blobs; nothing else.
function serve(request, response) {
  const path = new URL(request.url, 'http://127.0.0.1').pathname;
  let body = null;
  let type = 'application/octet-stream';
  if (path.startsWith('/blob/')) {
    const id = path.slice('/blob/'.length);
    body = blobs.get(id);
    blobs.delete(id);
  } else {
    const file = path === '/' ? '/harness.html' : path;
    const local = file.startsWith('/pkg/') ? join(root, 'web', normalize(file)) : join(root, 'web/www', normalize(file));
    if (!file.includes('..') && existsSync(local)) {
      body = readFileSync(local);
      type = TYPES[file.slice(file.lastIndexOf('.'))] || type;
    }
  }
  if (body === undefined || body === null) {
    response.writeHead(404).end();
    return;
  }
  response.writeHead(200, { 'content-type': type, 'cache-control': 'no-store' }).end(body);
}

const server = createServer(serve);
await new Promise((resolve) => server.listen(0, '127.0.0.1', resolve));
const url = `http://127.0.0.1:${server.address().port}/harness.html`;

const context = await chromium.launchPersistentContext(profile, {
  executablePath: CHROMIUM,
  headless: true,
  args: ARGS,
});
const page = context.pages()[0] || (await context.newPage());
page.on('console', (m) => { if (m.type() === 'error') console.error(`page: ${m.text()}`); });
page.on('pageerror', (e) => console.error(`page error: ${e}`));

const ops = {
  create: (r) => page.evaluate(([kind, modules]) => window.lightportHarness.create(kind, modules),
    [r.runtime, blob(Buffer.from(r.modules))]),
  scene: (r) => page.evaluate(([id, words]) => window.lightportHarness.scene(id, words),
    [r.id, blob(Buffer.from(r.words, 'base64'))]),
  layout: (r) => page.evaluate(([id, f, s]) => window.lightportHarness.layout(id, f, s),
    [r.id, r.function, JSON.stringify(r.specialize || {})]),
  run: async (r) => {
    if (r.corrupt === 'hang') return page.evaluate(() => new Promise(() => {}));
    const flip = r.corrupt && r.corrupt.flip !== undefined ? r.corrupt.flip : -1;
    const out = await page.evaluate(([id, f, n, s, words, k]) => window.lightportHarness.run(id, f, n, s, words, k),
      [r.id, r.function, r.invocations, JSON.stringify(r.specialize || {}), blob(Buffer.from(r.words, 'base64')), flip]);
    if (r.corrupt === 'truncate') {
      const bytes = Buffer.from(out.words, 'base64');
      out.words = bytes.subarray(0, Math.max(0, bytes.length - 4)).toString('base64');
    }
    return out;
  },
  filter: (r) => page.evaluate(([id, words]) => window.lightportHarness.filter(id, words),
    [r.id, blob(Buffer.from(r.words, 'base64'))]),
  drop: (r) => page.evaluate((id) => window.lightportHarness.drop(id), r.id),
};

async function handle(line) {
  let request;
  try {
    request = JSON.parse(line);
  } catch (e) {
    reply({ ok: false, error: `a request that is not JSON: ${e}` });
    return;
  }
  const op = ops[request.op];
  if (!op) {
    reply({ ok: false, error: `unknown op ${request.op}` });
    return;
  }
  try {
    const result = await op(request);
    if (request.corrupt === 'garbage') {
      process.stdout.write('@lp this is not JSON\n');
      return;
    }
    reply({ ok: true, ...result });
  } catch (e) {
    // page.evaluate's errors carry the page's message after a prefix of playwright's.
    reply({ ok: false, error: String(e && e.message ? e.message : e).replace(/^page\.evaluate: (Error: )?/, '') });
  }
}

// Requests are handled one at a time, in order; stdin's end ends everything at once (also a
// request still waiting on a hung page).
const input = createInterface({ input: process.stdin });
let chain = Promise.resolve();
input.on('line', (line) => { chain = chain.then(() => handle(line)); });
input.on('close', () => shutdown(0));
process.stdin.on('error', () => shutdown(4, 'stdin failed'));

try {
  await page.goto(url);
  await page.waitForFunction(() => window.lightportHarness && (window.lightportHarness.ready || window.lightportHarness.error),
    null, { timeout: 170000 });
  const state = await page.evaluate(() => ({ error: window.lightportHarness.error, userAgent: navigator.userAgent }));
  if (state.error) reply({ ok: false, error: state.error });
  else reply({ ok: true, ready: true, userAgent: state.userAgent });
} catch (e) {
  reply({ ok: false, error: `loading ${url}: ${e && e.message ? e.message : e}` });
}
