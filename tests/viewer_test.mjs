// The web viewer in a real browser: starts `mimic demo`, opens its viewer
// URL in Debian's Chromium (headless, WebGL in software through SwiftShader)
// with playwright-core, and checks that the avatar streams and moves.
//
//   node tests/viewer_test.mjs [MIMIC_BIN]     (or MIMIC_BIN in the environment)
//
// Exit status: 0 pass, 1 fail, 77 skip (no /usr/bin/chromium or no
// node_modules/playwright-core: npm ci). The screenshots are kept in a
// temporary folder whose path is printed (and, after a failure, the demo's
// files and the browser profile).
import { spawn } from 'node:child_process';
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import { createRequire } from 'node:module';
import { fileURLToPath } from 'node:url';

const CHROMIUM = '/usr/bin/chromium';
const root = path.resolve(path.dirname(fileURLToPath(import.meta.url)), '..');

function skip(why) {
  console.log(`viewer_test: SKIP: ${why}`);
  process.exit(77);
}
if (!fs.existsSync(CHROMIUM)) skip(`${CHROMIUM} is missing (apt-get install chromium)`);
let chromium;
try {
  ({ chromium } = createRequire(path.join(root, 'package.json'))('playwright-core'));
} catch {
  skip(`${root}/node_modules/playwright-core is missing (npm ci)`);
}
const bin = process.env.MIMIC_BIN || process.argv[2];
if (!bin) {
  console.error('viewer_test: give the mimic binary as MIMIC_BIN or the first argument');
  process.exit(1);
}

const tmp = fs.mkdtempSync(path.join(os.tmpdir(), 'mimic-viewer-'));
const failures = [];
const check = (ok, what) => {
  console.log(`${ok ? 'ok  ' : 'FAIL'} ${what}`);
  if (!ok) failures.push(what);
};

// ---- the demo: wait for its viewer URL on stdout --------------------------
const demo = spawn(bin, ['demo', '--headless', '--duration', '60', '--listen', '127.0.0.1:0', '--dir', path.join(tmp, 'demo')], {
  stdio: ['ignore', 'pipe', 'pipe'],
  env: { ...process.env, MIMIC_PROGRESS: '0' },
});
let demoErr = '';
demo.stderr.on('data', (d) => (demoErr += d));
const exited = new Promise((ok) => {
  demo.on('exit', (code, signal) => ok({ code, signal }));
  demo.on('error', (e) => ok({ code: `not started: ${e.message}`, signal: null })); // no such binary
});

function viewerUrl(timeoutMs) {
  return new Promise((ok, fail) => {
    let buf = '';
    const timer = setTimeout(() => fail(new Error(`no viewer URL on stdout within ${timeoutMs / 1000} s`)), timeoutMs);
    demo.stdout.on('data', (d) => {
      buf += d;
      const lines = buf.split('\n');
      buf = lines.pop();
      for (const line of lines) {
        if (/^http:\/\/127\.0\.0\.1:\d+\/$/.test(line)) {
          clearTimeout(timer);
          ok(line);
        }
      }
    });
    exited.then(({ code, signal }) => fail(new Error(`mimic demo exited (${signal || code}) before printing its URL: ${demoErr.trim()}`)));
  });
}

// Differing pixels of two same-sized PNG screenshots inside a box, compared
// in the browser (no PNG decoder in node without packages).
async function pixelsDiffering(page, a, b, box) {
  return page.evaluate(
    async ({ a, b, box }) => {
      const load = async (b64) => createImageBitmap(await (await fetch(`data:image/png;base64,${b64}`)).blob());
      const pixels = (img) => {
        const c = new OffscreenCanvas(box.width, box.height), g = c.getContext('2d');
        g.drawImage(img, box.x, box.y, box.width, box.height, 0, 0, box.width, box.height);
        return g.getImageData(0, 0, box.width, box.height).data;
      };
      const pa = pixels(await load(a)), pb = pixels(await load(b));
      let n = 0;
      for (let i = 0; i < pa.length; i += 4)
        if (Math.abs(pa[i] - pb[i]) + Math.abs(pa[i + 1] - pb[i + 1]) + Math.abs(pa[i + 2] - pb[i + 2]) > 24) n++;
      return n;
    },
    { a: a.toString('base64'), b: b.toString('base64'), box },
  );
}

let context;
let code = 1;
try {
  const url = await viewerUrl(120000);
  console.log(`viewer_test: demo at ${url}`);

  // ---- the browser ----------------------------------------------------------
  // A persistent context on a fresh profile folder is how playwright takes
  // --user-data-dir. WebGL without a GPU: ANGLE on SwiftShader.
  context = await chromium.launchPersistentContext(path.join(tmp, 'profile'), {
    executablePath: CHROMIUM,
    headless: true,
    viewport: { width: 1280, height: 720 },
    args: [
      '--headless', '--no-sandbox', '--disable-gpu', '--disable-quic', '--no-first-run',
      '--disable-background-networking', '--disable-component-update', '--disable-sync',
      '--use-angle=swiftshader', '--enable-unsafe-swiftshader',
    ],
  });
  const page = context.pages()[0] || (await context.newPage());
  const errors = [];
  page.on('console', (m) => m.type() === 'error' && errors.push(`console: ${m.text()}`));
  page.on('pageerror', (e) => errors.push(`page error: ${e.message}`));

  await page.goto(url);
  await page.waitForFunction(() => window.mimicViewer && window.mimicViewer.connected && window.mimicViewer.frames > 0, null, { timeout: 60000 });
  const v = () => page.evaluate(() => ({ ...window.mimicViewer, errors: [...window.mimicViewer.errors] }));
  // the first key frame (template id) may come a little after the first frame
  await page.waitForFunction(() => window.mimicViewer.templateId > 0, null, { timeout: 30000 }).catch(() => {});
  await page.waitForTimeout(300); // let the overlay show the latest frame
  const box = await page.locator('#view').boundingBox();
  const shot1 = await page.screenshot();
  const v1 = await v();
  await page.waitForTimeout(1500);
  const shot2 = await page.screenshot();
  const v2 = await v();
  const files = [path.join(tmp, 'viewer-1.png'), path.join(tmp, 'viewer-2.png')];
  fs.writeFileSync(files[0], shot1);
  fs.writeFileSync(files[1], shot2);
  console.log(`viewer_test: screenshots ${files.join(' ')}`);
  console.log(`viewer_test: at the first: frame ${v1.lastFrameNumber}, ${v1.frames} received, template ${v1.templateId} (${v1.poseLabel}), ${v1.fps.toFixed(1)} frames/s`);
  console.log(`viewer_test: 1.5 s later: frame ${v2.lastFrameNumber}, ${v2.frames} received, template ${v2.templateId} (${v2.poseLabel}), ${v2.dropped} dropped`);

  const canvasBox = { x: Math.round(box.x), y: Math.round(box.y), width: Math.round(box.width), height: Math.round(box.height) };
  const moved = await pixelsDiffering(page, shot1, shot2, canvasBox);
  check(moved > 200, `the canvas changed between the screenshots (${moved} pixels differ)`);
  check(v2.frames > v1.frames, `frames kept arriving (${v1.frames} -> ${v2.frames})`);
  check(v2.templateId > 0, `a template was recognised (id ${v2.templateId}, pose "${v2.poseLabel}")`);

  // The int16 encoding: the toggle asks for it, the server confirms, frames go on.
  const before = v2.frames;
  await page.locator('#o-i16').check();
  await page.waitForFunction((n) => window.mimicViewer.format === 'i16' && window.mimicViewer.frames > n + 5, before, { timeout: 20000 });
  const file3 = path.join(tmp, 'viewer-3-i16.png');
  await page.waitForTimeout(300);
  fs.writeFileSync(file3, await page.screenshot());
  check(true, `int16 frames decoded after the toggle (screenshot ${file3})`);

  const v3 = await v();
  check(v3.errors.length === 0, `the viewer reported no errors${v3.errors.length ? ': ' + v3.errors.join('; ') : ''}`);
  check(errors.length === 0, `no console or page errors${errors.length ? ': ' + errors.join('; ') : ''}`);
  code = failures.length ? 1 : 0;
} catch (e) {
  console.log(`FAIL ${e.message}`);
  code = 1;
} finally {
  // the browser first: a closing socket is no error of the page's
  if (context) await context.close().catch(() => {});
  if (demo.exitCode === null && demo.signalCode === null) demo.kill('SIGTERM');
  const t = setTimeout(() => demo.kill('SIGKILL'), 15000);
  const { code: dc, signal } = await exited;
  clearTimeout(t);
  console.log(`viewer_test: mimic demo exited with ${signal || dc}`);
  if (code === 0 && !(dc === 0 || signal === 'SIGTERM')) {
    console.log(`FAIL mimic demo did not exit cleanly on SIGTERM: ${demoErr.trim()}`);
    code = 1;
  }
  if (code === 0) {
    // keep only the screenshots of a pass (the demo's store is ~50 MB)
    for (const d of ['demo', 'profile']) fs.rmSync(path.join(tmp, d), { recursive: true, force: true });
  }
  console.log(`viewer_test: ${code ? 'FAIL' : 'PASS'} (${code ? "screenshots, the demo's files and the browser profile" : 'screenshots'} in ${tmp})`);
  process.exit(code);
}
