// The page of `kdtrace serve` in real headless Chromium (Debian's package, driven by
// playwright-core; nothing is downloaded): it loads, the canvas shows the scene, dragging changes
// the view, clicking a pixel draws its path and lists its vertices, a scene that nothing lights
// says so. Run by tests/serve_browser.rs
// inside a network namespace of its own:  node browser.mjs URL [SCREENSHOT.png]
import { chromium } from "playwright-core";

const [url, screenshot] = process.argv.slice(2);
const executablePath = process.env.CHROMIUM || "/usr/lib/chromium/chromium";
const fail = (msg) => { console.error("FAIL: " + msg); process.exit(1); };
const step = (msg) => console.log(`[${(performance.now() / 1000).toFixed(2)} s] ${msg}`);

const browser = await chromium.launch({
  executablePath,
  headless: true,
  args: ["--no-sandbox", "--no-first-run", "--disable-background-networking", "--disable-component-update",
    "--disable-sync", "--disable-dev-shm-usage"],
});
try {
  const page = await browser.newPage({ viewport: { width: 1640, height: 860 } });
  const errors = [];
  page.on("pageerror", (e) => errors.push(String(e)));
  page.on("console", (m) => { if (m.type() === "error") errors.push(m.text()); });

  const t0 = Date.now();
  await page.goto(url);
  step("page loaded");
  const frames = () => page.$eval("#image", (c) => Number(c.dataset.frames || 0));
  // The canvas as numbers: its mean brightness and a coarse 16×16 thumbnail.
  const look = () => page.$eval("#image", (c) => {
    const g = c.getContext("2d");
    const d = g.getImageData(0, 0, c.width, c.height).data;
    let sum = 0;
    const thumb = new Array(256).fill(0);
    for (let y = 0; y < c.height; y++) for (let x = 0; x < c.width; x++) {
      const i = 4 * (y * c.width + x);
      const v = d[i] + d[i + 1] + d[i + 2];
      sum += v;
      thumb[Math.floor((16 * y) / c.height) * 16 + Math.floor((16 * x) / c.width)] += v;
    }
    const n = c.width * c.height;
    return { mean: sum / (3 * n), thumb: thumb.map((v) => (v * 256) / (3 * n)), width: c.width, height: c.height };
  });
  const distance = (a, b) => a.thumb.reduce((s, v, i) => s + Math.abs(v - b.thumb[i]), 0) / a.thumb.length;

  await page.waitForFunction(() => Number(document.getElementById("image").dataset.frames || 0) >= 1, null, { timeout: 15000 });
  const first = await look();
  step(`first frame after ${((Date.now() - t0) / 1000).toFixed(2)} s: ${first.width}x${first.height}, mean ${first.mean.toFixed(1)}`);
  if (Date.now() - t0 > 15000) fail("the first frame took more than 15 s");
  if (!(first.mean > 5)) fail(`the canvas is black (mean ${first.mean})`);
  // Let the render refine for a moment, then drag.
  await page.waitForTimeout(1500);
  const before = await look();
  const box = await page.locator("#image").boundingBox();
  const cx = box.x + box.width / 2, cy = box.y + box.height / 2;
  const n0 = await frames();
  await page.mouse.move(cx, cy);
  await page.mouse.down();
  for (let i = 1; i <= 10; i++) await page.mouse.move(cx + 15 * i, cy + 3 * i);
  await page.mouse.up();
  await page.waitForFunction((n) => Number(document.getElementById("image").dataset.frames || 0) >= n + 3, n0, { timeout: 20000 });
  await page.waitForTimeout(1000);
  const after = await look();
  const moved = distance(before, after);
  step(`drag: the image changed by ${moved.toFixed(2)} (mean abs over a 16x16 thumbnail, 0-255)`);
  if (!(moved > 4)) fail(`dragging did not change the view (difference ${moved})`);

  // Back to the scene's own camera, then click below the middle of the image (the scene's
  // floor and blocks are there) and wait for the pixel's path.
  const n1 = await frames();
  await page.click("#reset");
  await page.waitForFunction((n) => Number(document.getElementById("image").dataset.frames || 0) >= n + 3, n1, { timeout: 20000 });
  const reset = distance(await look(), before);
  step(`reset: the image is ${reset.toFixed(2)} from the one before the drag`);
  if (!(reset < moved / 2)) fail(`Reset camera did not bring the view back (difference ${reset})`);
  await page.mouse.click(cx - box.width * 0.1, cy + box.height * 0.2);
  await page.waitForFunction(() => document.querySelectorAll("#vertices tbody tr").length >= 1, null, { timeout: 20000 });
  const rows = await page.$$eval("#vertices tbody tr", (r) => r.length);
  const drawn = await page.$eval("#overlay", (c) => Number(c.dataset.vertices || 0));
  const info = await page.$eval("#pixel-info", (p) => p.textContent);
  const ink = await page.$eval("#overlay", (c) => {
    const d = c.getContext("2d").getImageData(0, 0, c.width, c.height).data;
    let n = 0;
    for (let i = 3; i < d.length; i += 4) if (d[i] > 0) n++;
    return n;
  });
  step(`click: ${rows} vertices listed, ${drawn} drawn (${ink} overlay pixels): ${info}`);
  if (!info.startsWith("Pixel (")) fail(`the pixel panel says ${JSON.stringify(info)}`);
  if (drawn !== rows) fail(`${rows} vertices listed but ${drawn} drawn`);
  if (!(ink > 20)) fail("the path is not drawn over the image");
  // The box's walls are Lambertian, so the path connects to light subpaths: the first vertex
  // lists its connection.
  const firstRow = await page.$eval("#vertices tbody tr", (r) => r.textContent);
  if (!/connection: (unblocked|blocked|invalid)/.test(firstRow)) fail(`no connection listed at the first vertex: ${JSON.stringify(firstRow)}`);
  // The lit scene has no warnings; choosing the second one, which nothing lights, shows why it
  // renders black.
  const quiet = await page.$eval("#warnings", (w) => w.textContent);
  if (quiet !== "") fail(`the lit scene shows warnings: ${JSON.stringify(quiet)}`);
  if (screenshot) {
    await page.waitForTimeout(2000);
    await page.screenshot({ path: screenshot });
    step(`screenshot ${screenshot}`);
  }
  await page.selectOption("#scene", "1");
  await page.waitForFunction(() => document.getElementById("warnings").textContent.includes("nothing emits light"), null, { timeout: 10000 });
  step(`unlit scene: ${await page.$eval("#warnings", (w) => w.textContent)}`);
  if (errors.length) fail("the page reported errors: " + errors.join("; "));
  console.log("PASS");
} finally {
  await browser.close();
}
