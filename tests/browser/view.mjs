// Opens `ipfn view` in headless Debian chromium and records what the page did, for
// tests/view.rs to check against `ipfn synth`:
//
//   node view.mjs plane URL OUT_DIR   the plane: tiles fetched (saved as PNG), their places,
//                                     then a drag and the places after it
//   node view.mjs run URL OUT_DIR     a run: plots and previews drawn (then report.html, when
//                                     REPORT=file:///…/report.html is set)
//
// SCREENSHOT=FILE saves a screenshot of the page at the end.
import { chromium } from "playwright-core";
import { writeFileSync } from "node:fs";
import { join } from "node:path";

const [mode, url, out] = process.argv.slice(2);
const browser = await chromium.launch({
  executablePath: process.env.CHROMIUM || "/usr/bin/chromium",
  args: ["--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
    "--disable-background-networking", "--disable-component-update", "--disable-sync"],
});
const page = await browser.newPage({ viewport: { width: 1200, height: 960 } });
const record = { console: [] };
page.on("console", (m) => record.console.push(m.type() + ": " + m.text()));
page.on("pageerror", (e) => record.console.push("pageerror: " + e.message));
page.on("requestfailed", (r) => record.console.push("failed: " + r.url() + " " + r.failure()?.errorText));

// Every tile the page fetched, saved with its URL: tile requests pass through here, so their
// bodies are read as the server sent them.
const tiles = [];
await page.route(/\/tile\?/, async (route) => {
  try {
    const response = await route.fetch();
    const body = await response.body();
    if (response.status() === 200 && body.length >= 8 && body.readUInt32BE(0) === 0x89504e47) {
      const file = join(out, `tile-${tiles.length}.png`);
      tiles.push({ url: route.request().url(), file });
      writeFileSync(file, body);
    }
    await route.fulfill({ response, body });
  } catch (e) {
    // A tile that left the screen was cancelled by the page.
    await route.abort().catch(() => {});
  }
});

// Waits until every placed tile has loaded, then returns their places.
async function placed() {
  await page.waitForFunction(() => {
    const imgs = [...document.querySelectorAll("#tiles img")];
    return imgs.length > 0 && imgs.every((i) => i.complete && i.naturalWidth > 0);
  }, null, { timeout: Number(process.env.WAIT_MS || 120000) });
  return page.evaluate(() => ({
    hash: location.hash,
    plane: (() => { const p = document.getElementById("plane"); return [p.clientWidth, p.clientHeight]; })(),
    tiles: [...document.querySelectorAll("#tiles img")].sort((a, b) =>
      Number(a.dataset.y) - Number(b.dataset.y) || Number(a.dataset.x) - Number(b.dataset.x)).map((i) => ({
      src: i.dataset.url, x: Number(i.dataset.x), y: Number(i.dataset.y),
      left: parseFloat(i.style.left), top: parseFloat(i.style.top),
      width: i.naturalWidth, height: i.naturalHeight,
    })),
  }));
}

try {
if (mode === "plane") {
  await page.goto(url);
  record.before = await placed();
  const box = await page.locator("#plane").boundingBox();
  const [sx, sy] = [box.x + box.width / 2, box.y + box.height / 2];
  await page.mouse.move(sx, sy);
  await page.mouse.down();
  await page.mouse.move(sx - 100, sy - 50, { steps: 5 });
  await page.mouse.up();
  record.after = await placed();
  // The URL holds the view: reopened, it shows the same tiles in the same places.
  await page.goto("about:blank");
  await page.goto(url.split("#")[0] + record.after.hash);
  record.reopened = await placed();
  // The wheel zooms about the pointer (here the plane's centre): one notch is x1.25.
  const plane = await page.locator("#plane").boundingBox();
  await page.mouse.move(plane.x + plane.width / 2, plane.y + plane.height / 2);
  await page.mouse.wheel(0, -100);
  await page.waitForFunction(() => location.hash.includes("zoom=1.875"), null, { timeout: 10000 });
  record.zoomed = await placed();
} else if (mode === "run") {
  await page.goto(url);
  await page.waitForFunction(() => document.querySelectorAll("#plots polyline").length >= 3
    // Every preview settled (loaded or failed), not just the first: the strip is counted next.
    && [...document.querySelectorAll("#previews img")].some((i) => i.complete && i.naturalWidth > 0)
    && [...document.querySelectorAll("#previews img")].every((i) => i.complete),
  null, { timeout: Number(process.env.WAIT_MS || 120000) });
  record.run = await page.evaluate(() => ({
    series: [...document.querySelectorAll("#plots polyline")].map((p) => p.dataset.series),
    previews: [...document.querySelectorAll("#previews img")].filter((i) => i.naturalWidth > 0).length,
    state: document.getElementById("run-state").textContent,
    config: document.getElementById("config").textContent.length,
  }));
  await placed();
  if (process.env.REPORT) {
    const report = await browser.newPage();
    await report.goto(process.env.REPORT);
    await report.waitForFunction(() => document.querySelectorAll("#plots polyline").length >= 3,
      null, { timeout: 30000 });
    record.report = await report.evaluate(() => ({
      series: [...document.querySelectorAll("#plots polyline")].map((p) => p.dataset.series),
      previews: [...document.querySelectorAll("#previews img")].length,
      state: document.getElementById("run-state").textContent,
    }));
  }
}
} catch (e) {
  record.error = String(e).split("\n")[0];
  record.pending = await page.evaluate(() => [...document.querySelectorAll("#tiles img")]
    .filter((i) => !(i.complete && i.naturalWidth > 0))
    .map((i) => i.getAttribute("src") + (i.complete ? " (failed)" : " (loading)"))).catch(() => []);
}
record.tiles = tiles;
if (process.env.SCREENSHOT) await page.screenshot({ path: process.env.SCREENSHOT });
writeFileSync(join(out, "record.json"), JSON.stringify(record, null, 1));
await browser.close();
