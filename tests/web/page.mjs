// The page in headless Chromium, as every browser scenario opens it: the flags per API, a
// fresh profile, and `open` (navigate, wait for the first scene, record requests and console
// errors). Shared by run.mjs and the scenarios kept in files of their own (animation.mjs, api.mjs).

import { chromium } from 'playwright-core';
import { mkdtempSync } from 'node:fs';
import { tmpdir } from 'node:os';
import { join } from 'node:path';

const CHROMIUM = process.env.CHROMIUM || '/usr/bin/chromium';
// The flags DESIGN.md lists for WebGL2 on SwiftShader, and WebGPU (on SwiftShader too: adapter
// "google / swiftshader"; the user data dir is given separately).
const BASE_ARGS = [
  '--headless=new', '--no-sandbox', '--use-angle=swiftshader', '--enable-unsafe-swiftshader',
  '--disable-background-networking', '--disable-component-update', '--disable-sync', '--no-first-run',
  '--disable-quic', '--enable-unsafe-webgpu',
];
// WebGL2 pages: the GPU process disabled (DESIGN.md). A WebGPU canvas needs a compositor that
// can take WebGPU's swap-chain images: with `--disable-gpu` (GL compositing over SwiftShader)
// Chromium finds no shared-image backing for them ("Could not find SharedImageBackingFactory
// ... WebgpuSwapChainTexture") and the GPU process dies at the first getCurrentTexture (every
// later promise rejects: "A valid external Instance reference no longer exists"); with Vulkan
// compositing on SwiftShader it works.
const WEBGL2_ARGS = [...BASE_ARGS, '--disable-gpu'];
const WEBGPU_ARGS = [...BASE_ARGS, '--use-vulkan=swiftshader', '--enable-features=Vulkan'];
// Extra Chromium flags for experiments (space-separated), e.g. LIGHTPORT_CHROMIUM_ARGS=
// --enable-dawn-features=disable_robustness to see what WebGPU's bounds checks cost.
const EXTRA_ARGS = (process.env.LIGHTPORT_CHROMIUM_ARGS || '').split(' ').filter(Boolean);
// `--api auto|webgpu|webgl2` (any scenario): the page's `api=`; default webgl2, which every
// scenario was written against.
export let pageApi = 'webgl2';

export function setPageApi(api) {
  pageApi = api;
}

// `--schedule auto|megakernel|wavefront` (any scenario): the page's `schedule=`; default none
// (the page's auto).
export let pageSchedule;

export function setPageSchedule(schedule) {
  pageSchedule = schedule;
}

// `--browser webgl2|webgpu` (any scenario): start Chromium with that API's flags whatever the
// page's `api=` (default: the page's API's): `webgl2` with `api=auto` is a browser whose
// WebGPU device dies at its first frame (see WEBGL2_ARGS).
export let browserFlags;

export function setBrowserFlags(flags) {
  browserFlags = flags;
}

export async function withBrowser(profile, action, extraArgs = []) {
  const flags = (browserFlags || pageApi) === 'webgl2' ? WEBGL2_ARGS : WEBGPU_ARGS;
  const context = await chromium.launchPersistentContext(profile, {
    executablePath: CHROMIUM,
    headless: true,
    args: [...flags, ...EXTRA_ARGS, ...extraArgs],
    viewport: { width: 900, height: 700 },
  });
  try {
    return await action(context);
  } finally {
    await context.close();
  }
}

export function freshProfile() {
  return mkdtempSync(join(tmpdir(), 'lightport-chromium-'));
}

// Opens the page and waits until the first scene is shown (or the page reports why not).
// Records every request the page makes and the console's errors.
export async function open(context, baseUrl, query, timeoutMs = 240000) {
  const page = context.pages()[0] || (await context.newPage());
  const requests = [];
  const consoleErrors = [];
  page.on('request', (r) => requests.push(new URL(r.url()).pathname));
  page.on('console', (m) => { if (m.type() === 'error') consoleErrors.push(m.text()); });
  page.on('pageerror', (e) => consoleErrors.push(String(e)));
  const url = new URL(baseUrl);
  for (const [k, v] of Object.entries({ api: pageApi, schedule: pageSchedule, ...query })) {
    if (v !== undefined) url.searchParams.set(k, v);
  }
  const navigationStart = Date.now();
  await page.goto(url.toString());
  await page.waitForFunction(() => window.lightport && window.lightport.ready, null, { timeout: timeoutMs });
  const state = await page.evaluate(() => ({ error: window.lightport.error, info: window.lightport.info() }));
  return { page, requests, consoleErrors, navigationStart, ...state };
}

// The median of `values` (the upper one of an even count).
export function median(values) {
  return [...values].sort((x, y) => x - y)[Math.floor(values.length / 2)];
}

// The frame loop's own pace (bands queued ahead): ms per whole frame it completes, between the
// first and the last completion seen in `ms` (null: fewer than two).
export async function loopPace(page, ms) {
  return page.evaluate(async (ms) => {
    const seen = [];
    let last = window.lightport.frames;
    const end = performance.now() + ms;
    while (performance.now() < end) {
      await new Promise((resolve) => setTimeout(resolve, 20));
      if (window.lightport.frames !== last) {
        last = window.lightport.frames;
        seen.push([last, performance.now()]);
      }
    }
    if (seen.length < 2) return null;
    return (seen.at(-1)[1] - seen[0][1]) / (seen.at(-1)[0] - seen[0][0]);
  }, ms);
}

// Records the page's long tasks (a main-thread task over 50 ms: on SwiftShader, a tick that
// waited for the GPU; docs/web.md "The first frame's rows"), those before the call included.
export async function watchLongTasks(page) {
  await page.evaluate(() => {
    window.longTasks = [];
    new PerformanceObserver((list) => {
      for (const e of list.getEntries()) window.longTasks.push([e.startTime, e.duration]);
    }).observe({ type: 'longtask', buffered: true });
  });
}

// The ms of the long tasks recorded by watchLongTasks that started in [from, to)
// (performance.now() times).
export async function longTaskMs(page, from, to) {
  return page.evaluate(([from, to]) => window.longTasks
    .filter(([t]) => t >= from && t < to)
    .reduce((sum, [, d]) => sum + d, 0), [from, to]);
}
