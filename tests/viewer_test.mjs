// The web viewer in a real browser (Debian's Chromium, headless, WebGL in
// software through SwiftShader, driven by playwright-core), three scenarios:
//
//  1. `mimic demo`: its viewer URL opened; the avatar streams and moves, the
//     int16 toggle works.
//  2. a foreign avatar (issue 13): a synth body of another seed, subdivided
//     twice and shuffled (make_foreign_avatar, tests/support/foreign_avatar.c),
//     served by `mimic serve --store <the demo's store> --avatar FOREIGN.ply`
//     on a simulated vest; the page draws the avatar with its own vertex and
//     face counts, and it moves.
//  3. a rigged avatar as authors ship it (issue 28): a textured GLB of several
//     primitives (make_rigged_avatar --all, tests/support/rigged_avatar.c),
//     served the same way with no landmark file (mimic places them from the
//     rig); the page draws it from GET /api/avatar.glb, one mesh per part
//     with its texture, and it moves.
//
//   node tests/viewer_test.mjs [MIMIC_BIN [MAKE_FOREIGN_AVATAR [MAKE_RIGGED_AVATAR]]]
//     (or MIMIC_BIN, MIMIC_FOREIGN_AVATAR and MIMIC_RIGGED_AVATAR in the
//      environment; the helpers default to tests/make_foreign_avatar and
//      tests/make_rigged_avatar of the build beside MIMIC_BIN)
//
// Exit status: 0 pass, 1 fail, 77 skip (no /usr/bin/chromium or no
// node_modules/playwright-core: npm ci). The screenshots are kept in a
// temporary folder whose path is printed (and, after a failure, the demo's
// files and the browser profile).
import { spawn, execFileSync } from 'node:child_process';
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
const makeForeign =
  process.env.MIMIC_FOREIGN_AVATAR || process.argv[3] || path.join(path.dirname(bin), '..', 'tests', 'make_foreign_avatar');
const makeRigged =
  process.env.MIMIC_RIGGED_AVATAR || process.argv[4] || path.join(path.dirname(bin), '..', 'tests', 'make_rigged_avatar');

const tmp = fs.mkdtempSync(path.join(os.tmpdir(), 'mimic-viewer-'));
const failures = [];
const check = (ok, what) => {
  console.log(`${ok ? 'ok  ' : 'FAIL'} ${what}`);
  if (!ok) failures.push(what);
};

// ---- child processes: every one is stopped in the end ----------------------
const children = [];
function start(name, args) {
  const p = spawn(bin, args, { stdio: ['ignore', 'pipe', 'pipe'], env: { ...process.env, MIMIC_PROGRESS: '0' } });
  const c = { name, p, out: '', err: '' };
  p.stdout.on('data', (d) => (c.out += d));
  p.stderr.on('data', (d) => (c.err += d));
  c.exited = new Promise((ok) => {
    p.on('exit', (code, signal) => ok({ code, signal }));
    p.on('error', (e) => ok({ code: `not started: ${e.message}`, signal: null })); // no such binary
  });
  children.push(c);
  return c;
}
const running = (c) => c.p.exitCode === null && c.p.signalCode === null;

// The first stdout line matching re, within timeoutMs.
function line(c, re, timeoutMs) {
  return new Promise((ok, fail) => {
    const timer = setTimeout(() => fail(new Error(`${c.name}: no line like ${re} on stdout within ${timeoutMs / 1000} s`)), timeoutMs);
    const look = () => {
      const hit = c.out.split('\n').slice(0, -1).find((l) => re.test(l));
      if (hit !== undefined) {
        clearTimeout(timer);
        ok(hit);
        return true;
      }
      return false;
    };
    if (look()) return;
    c.p.stdout.on('data', look);
    c.exited.then(({ code, signal }) => fail(new Error(`${c.name} exited (${signal || code}) first: ${c.err.trim()}`)));
  });
}
const viewerUrl = (c, timeoutMs) => line(c, /^http:\/\/127\.0\.0\.1:\d+\/$/, timeoutMs);
// Whether stderr holds a match of re within timeoutMs (stderr and stdout
// are two pipes: what was written first may come second).
async function inStderr(c, re, timeoutMs) {
  for (const end = Date.now() + timeoutMs; !re.test(c.err) && Date.now() < end; ) await new Promise((ok) => setTimeout(ok, 50));
  return re.test(c.err);
}

// SIGTERM, SIGKILL after graceMs; resolves to how it exited.
async function stop(c, graceMs = 15000) {
  if (running(c)) c.p.kill('SIGTERM');
  const t = setTimeout(() => c.p.kill('SIGKILL'), graceMs);
  const r = await c.exited;
  clearTimeout(t);
  console.log(`viewer_test: ${c.name} exited with ${r.signal || r.code}`);
  return r;
}
const cleanExit = (r) => r.code === 0 || r.signal === 'SIGTERM';

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

// Opens url in a new page and checks that the avatar streams and moves:
// two screenshots at least 1.5 s and 3 frames apart differ on the canvas,
// frames keep arriving, a template is recognised. Returns the page, its error list and the state at
// the second screenshot.
async function watch(context, url, tag) {
  const page = await context.newPage();
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
  // and a few new frames: a machine busy rendering in software may serve
  // and draw slowly, which is no failure (behaviour, not a rate)
  await page.waitForFunction((n) => window.mimicViewer.frames >= n + 3, v1.frames, { timeout: 30000 }).catch(() => {});
  const shot2 = await page.screenshot();
  const v2 = await v();
  const files = [path.join(tmp, `${tag}-1.png`), path.join(tmp, `${tag}-2.png`)];
  fs.writeFileSync(files[0], shot1);
  fs.writeFileSync(files[1], shot2);
  console.log(`viewer_test: ${tag}: screenshots ${files.join(' ')}`);
  console.log(`viewer_test: ${tag}: at the first: frame ${v1.lastFrameNumber}, ${v1.frames} received, template ${v1.templateId} (${v1.poseLabel}), ${v1.fps.toFixed(1)} frames/s`);
  console.log(`viewer_test: ${tag}: later: frame ${v2.lastFrameNumber}, ${v2.frames} received, template ${v2.templateId} (${v2.poseLabel}), ${v2.dropped} dropped`);

  const canvasBox = { x: Math.round(box.x), y: Math.round(box.y), width: Math.round(box.width), height: Math.round(box.height) };
  let moved = await pixelsDiffering(page, shot1, shot2, canvasBox);
  // both may fall in one held pose of the motion (the demo holds each pose):
  // then one more, 1.5 s later, against the first
  if (moved <= 200) {
    await page.waitForTimeout(1500);
    const shot3 = await page.screenshot();
    fs.writeFileSync(path.join(tmp, `${tag}-3.png`), shot3);
    const again = await pixelsDiffering(page, shot1, shot3, canvasBox);
    console.log(`viewer_test: ${tag}: ${moved} pixels differ, one held pose? a third screenshot differs in ${again}`);
    moved = again;
  }
  check(moved > 200, `${tag}: the canvas changed between the screenshots (${moved} pixels differ)`);
  check(v2.frames > v1.frames, `${tag}: frames kept arriving (${v1.frames} -> ${v2.frames})`);
  check(v2.templateId > 0, `${tag}: a template was recognised (id ${v2.templateId}, pose "${v2.poseLabel}")`);
  check(v2.glb, `${tag}: the avatar is drawn from its GLB (${v2.glb ? v2.parts + ' part meshes' : 'plain: ' + v2.glbError})`);
  return { page, errors, v, state: v2 };
}

function noErrors(tag, state, errors) {
  check(state.errors.length === 0, `${tag}: the viewer reported no errors${state.errors.length ? ': ' + state.errors.join('; ') : ''}`);
  check(errors.length === 0, `${tag}: no console or page errors${errors.length ? ': ' + errors.join('; ') : ''}`);
}

let context;
let code = 1;
try {
  // ---- 1. the demo ----------------------------------------------------------
  const demoDir = path.join(tmp, 'demo');
  const demo = start('mimic demo', ['demo', '--headless', '--duration', '90', '--listen', '127.0.0.1:0', '--dir', demoDir,
    '--vests', '2']);
  const url = await viewerUrl(demo, 120000);
  console.log(`viewer_test: demo at ${url}`);

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
  const d = await watch(context, url, 'demo');

  // The int16 encoding: the toggle asks for it, the server confirms, frames go on.
  const before = d.state.frames;
  await d.page.locator('#o-i16').check();
  await d.page.waitForFunction((n) => window.mimicViewer.format === 'i16' && window.mimicViewer.frames > n + 5, before, { timeout: 20000 });
  const file3 = path.join(tmp, 'demo-3-i16.png');
  await d.page.waitForTimeout(300);
  fs.writeFileSync(file3, await d.page.screenshot());
  check(true, `demo: int16 frames decoded after the toggle (screenshot ${file3})`);
  noErrors('demo', await d.v(), d.errors);

  // Two vests, two sessions: the picker lists both, and choosing the other
  // one loads the page for it, whose avatar then streams.
  await d.page.waitForFunction(() => window.mimicViewer.sessions.length === 2, null, { timeout: 20000 }).catch(() => {});
  const listed = await d.page.evaluate(() => [...document.querySelectorAll('#o-session option')].map((o) => o.value));
  check(listed.join(',') === 'default,vest2', `demo --vests 2: the picker lists the sessions (${listed.join(', ')})`);
  check((await d.v()).session === 'default', 'demo --vests 2: the page streams the first session by default');
  await Promise.all([d.page.waitForNavigation({ timeout: 20000 }), d.page.locator('#o-session').selectOption('vest2')]);
  await d.page.waitForFunction(() => window.mimicViewer.session === 'vest2' && window.mimicViewer.frames > 3, null, { timeout: 60000 });
  const file4 = path.join(tmp, 'demo-4-vest2.png');
  await d.page.waitForTimeout(300);
  fs.writeFileSync(file4, await d.page.screenshot());
  check(new URL(d.page.url()).searchParams.get('session') === 'vest2',
    `demo --vests 2: the viewer switched to session vest2 (screenshot ${file4})`);
  noErrors('demo vest2', await d.v(), d.errors);
  // the page first: a closing socket is no error of the page's
  await d.page.close();
  const de = await stop(demo);
  check(cleanExit(de), `mimic demo exited cleanly on SIGTERM${cleanExit(de) ? '' : ': ' + demo.err.trim()}`);

  // ---- 2. a foreign avatar on the demo's store --------------------------------
  // another seed than the demo's bodies (1): in no template of its store
  const avatar = path.join(tmp, 'foreign.ply');
  let made;
  try {
    made = JSON.parse(execFileSync(makeForeign, [avatar, '--vertices', '2000', '--seed', '7', '--subdivisions', '2', '--shuffle', '11'], { encoding: 'utf8' }));
  } catch (e) {
    throw new Error(`${makeForeign} (MIMIC_FOREIGN_AVATAR) could not make the foreign avatar: ${e.message}`);
  }
  console.log(`viewer_test: foreign avatar ${avatar}: ${made.vertices} vertices, ${made.faces} faces`);
  const link = path.join(tmp, 'vest');
  const vest = start('mimic vest simulate', ['vest', 'simulate', '--motion', 'demo', '--out', `pty:${link}`, '--loop']);
  await line(vest, /./, 30000); // it names its pty once it is there
  const serve = start('mimic serve', ['serve', '--store', path.join(demoDir, 'store'), '--avatar', avatar, '--vest', `serial:${link}`,
    '--vest-pose', 't', '--listen', '127.0.0.1:0']);
  const url2 = await viewerUrl(serve, 120000);
  console.log(`viewer_test: mimic serve with the foreign avatar at ${url2}`);
  check(await inStderr(serve, /foreign\.ply: registered onto the store's connectivity \(.*\) and bound, /, 5000),
    `foreign: the avatar was registered and bound at start (${serve.err.split('\n')[0]})`);
  const f = await watch(context, url2, 'foreign');
  check(f.state.vertices === made.vertices && f.state.faces === made.faces,
    `foreign: the page draws the avatar's own mesh (${f.state.vertices} vertices, ${f.state.faces} faces; the file has ${made.vertices} and ${made.faces})`);
  noErrors('foreign', await f.v(), f.errors); // a frame of another vertex count would be one
  await f.page.close();
  const se = await stop(serve);
  check(cleanExit(se), `mimic serve exited cleanly on SIGTERM${cleanExit(se) ? '' : ': ' + serve.err.trim()}`);
  await stop(vest, 5000);

  // ---- 3. a rigged, textured avatar of several primitives (issue 28) -----------
  const rigged = path.join(tmp, 'rigged.glb');
  let madeR;
  try {
    madeR = JSON.parse(execFileSync(makeRigged, [rigged, '--all', '--vertices', '3000'], { encoding: 'utf8' }));
  } catch (e) {
    throw new Error(`${makeRigged} (MIMIC_RIGGED_AVATAR) could not make the rigged avatar: ${e.message}`);
  }
  console.log(`viewer_test: rigged avatar ${rigged}: ${madeR.vertices} vertices, ${madeR.primitives} primitives`);
  const link3 = path.join(tmp, 'vest3');
  const vest3 = start('mimic vest simulate (rigged)', ['vest', 'simulate', '--motion', 'demo', '--out', `pty:${link3}`, '--loop']);
  await line(vest3, /./, 30000);
  const serve3 = start('mimic serve (rigged)', ['serve', '--store', path.join(demoDir, 'store'), '--avatar', rigged, '--vest',
    `serial:${link3}`, '--vest-pose', 't', '--listen', '127.0.0.1:0']);
  const url3 = await viewerUrl(serve3, 120000);
  console.log(`viewer_test: mimic serve with the rigged avatar at ${url3}`);
  const r = await watch(context, url3, 'rigged');
  check(r.state.parts === madeR.primitives,
    `rigged: the page draws one mesh per primitive (${r.state.parts} part meshes; the file has ${madeR.primitives} primitives)`);
  check(r.state.vertices === madeR.vertices,
    `rigged: the page draws the avatar's own vertices (${r.state.vertices}; the file has ${madeR.vertices})`);
  check(r.state.textured === 1, `rigged: a texture is loaded (textured ${r.state.textured})`);
  const file5 = path.join(tmp, 'rigged-textured.png');
  fs.writeFileSync(file5, await r.page.screenshot());
  console.log(`viewer_test: rigged: screenshot ${file5}`);
  noErrors('rigged', await r.v(), r.errors);
  await r.page.close();
  const se3 = await stop(serve3);
  check(cleanExit(se3), `mimic serve (rigged) exited cleanly on SIGTERM${cleanExit(se3) ? '' : ': ' + serve3.err.trim()}`);
  await stop(vest3, 5000);
  code = failures.length ? 1 : 0;
} catch (e) {
  console.log(`FAIL ${e.message}`);
  code = 1;
} finally {
  // the browser first: a closing socket is no error of the page's
  if (context) await context.close().catch(() => {});
  for (const c of children) if (running(c)) await stop(c, 5000);
  if (code === 0) {
    // keep only the screenshots of a pass (the demo's store is ~50 MB)
    for (const d of ['demo', 'profile', 'foreign.ply', 'foreign.landmarks.json', 'rigged.glb']) fs.rmSync(path.join(tmp, d), { recursive: true, force: true });
  }
  console.log(`viewer_test: ${code ? 'FAIL' : 'PASS'} (${code ? "screenshots, the demo's files and the browser profile" : 'screenshots'} in ${tmp})`);
  process.exit(code);
}
