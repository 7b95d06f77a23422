// The client-side scene cache: bundle bytes kept with the Cache API, keyed by their
// content-addressed URL (/bundles/<sha256>.lpb never changes meaning, so a cached entry never
// needs revalidation), under a size budget with least-recently-used eviction. Last-use times
// and sizes live in localStorage (a few bytes per scene, read synchronously).
//
// Default budget: 1 GiB. Bundles store the packed arrays as 32-bit texels, uncompressed
// (gzip is only the transfer encoding), so they are large. Measured with `lightport serve`
// (docs/web.md; raw bytes, as cached): Cornell box 4.8 KB (8.4 MB with a 1024x512 HDR sky, which
// every scene served with --sky carries), Avocado 25 MB, DamagedHelmet 45 MB, LittlestTokyo
// 100 MB (all with that sky). The four benchmark scenes take 178 MB: 1 GiB keeps a session's
// worth of such scenes several times over while staying well under the storage quota browsers
// grant an origin (Chrome: a share of free disk, usually many GiB). LRU fits how the page is
// used: the scenes a visitor comes back to are the ones viewed last; a scene larger than the
// whole budget is rendered but not stored.

const CACHE_NAME = 'lightport-bundles-v1';
const INDEX_KEY = 'lightport-bundle-index-v1';
export const DEFAULT_BUDGET_BYTES = 1024 * 1024 * 1024;

function readIndex() {
  try {
    const index = JSON.parse(localStorage.getItem(INDEX_KEY) || '{}');
    return index && typeof index === 'object' ? index : {};
  } catch {
    return {};
  }
}

function writeIndex(index) {
  localStorage.setItem(INDEX_KEY, JSON.stringify(index));
}

export class BundleCache {
  constructor(budgetBytes = DEFAULT_BUDGET_BYTES) {
    this.budget = budgetBytes;
    // Bytes of scene data downloaded by this page (cache misses), for the read-out and tests.
    this.bytesFetched = 0;
    this.available = typeof caches !== 'undefined';
  }

  // Drops index entries whose cached response is gone (storage cleared by the browser) and
  // cached responses the index does not know (an interrupted write).
  async reconcile() {
    if (!this.available) return;
    const cache = await caches.open(CACHE_NAME);
    const index = readIndex();
    const cachedUrls = new Set((await cache.keys()).map((r) => new URL(r.url).pathname));
    for (const url of Object.keys(index)) {
      if (!cachedUrls.has(url)) delete index[url];
    }
    for (const url of cachedUrls) {
      if (!(url in index)) await cache.delete(url);
    }
    writeIndex(index);
  }

  // The bundle's bytes (ArrayBuffer): from the cache when present, else downloaded and stored.
  // `onProgress(received, total)` reports downloads.
  async fetch(url, onProgress = () => {}) {
    if (this.available) {
      const cache = await caches.open(CACHE_NAME);
      const hit = await cache.match(url);
      if (hit) {
        const bytes = await hit.arrayBuffer();
        const index = readIndex();
        index[url] = { bytes: bytes.byteLength, lastUsed: Date.now() };
        writeIndex(index);
        return { bytes, fromCache: true };
      }
    }
    const response = await fetch(url);
    if (!response.ok) throw new Error(`downloading ${url}: HTTP ${response.status}`);
    const bytes = await readWithProgress(response, onProgress);
    this.bytesFetched += bytes.byteLength;
    if (this.available) {
      try {
        await this.store(url, bytes);
      } catch (e) {
        // Storage can be full or disabled (private mode): render anyway, uncached.
        console.warn(`not caching ${url}: ${e}`);
      }
    }
    return { bytes, fromCache: false };
  }

  async store(url, bytes) {
    const size = bytes.byteLength;
    if (size > this.budget) return;
    const cache = await caches.open(CACHE_NAME);
    const index = readIndex();
    delete index[url];
    let used = Object.values(index).reduce((sum, e) => sum + e.bytes, 0);
    const byAge = Object.entries(index).sort((a, b) => a[1].lastUsed - b[1].lastUsed);
    for (const [oldUrl, entry] of byAge) {
      if (used + size <= this.budget) break;
      await cache.delete(oldUrl);
      delete index[oldUrl];
      used -= entry.bytes;
    }
    // Stored as plain bytes: the transfer's Content-Encoding does not follow them.
    await cache.put(url, new Response(bytes, { headers: { 'Content-Type': 'application/octet-stream' } }));
    index[url] = { bytes: size, lastUsed: Date.now() };
    writeIndex(index);
  }

  usage() {
    const entries = Object.values(readIndex());
    return { bytes: entries.reduce((sum, e) => sum + e.bytes, 0), scenes: entries.length, budget: this.budget };
  }

  async clear() {
    if (this.available) await caches.delete(CACHE_NAME);
    writeIndex({});
  }
}

async function readWithProgress(response, onProgress) {
  const total = Number(response.headers.get('Content-Length')) || 0;
  if (!response.body) return response.arrayBuffer();
  const reader = response.body.getReader();
  const chunks = [];
  let received = 0;
  for (;;) {
    const { done, value } = await reader.read();
    if (done) break;
    chunks.push(value);
    received += value.byteLength;
    onProgress(received, total);
  }
  const bytes = new Uint8Array(received);
  let offset = 0;
  for (const chunk of chunks) {
    bytes.set(chunk, offset);
    offset += chunk.byteLength;
  }
  return bytes.buffer;
}
