// Shared pieces of the browser tests: command-line arguments, a
// fesbench-server on loopback (temporary database, simulated bench in
// accelerated time), API calls with a token, Debian's chromium through
// Playwright, screenshots and timed steps. Waits are on page state
// (selectors, texts, data attributes), never fixed sleeps.
import { spawn } from 'node:child_process';
import { mkdirSync, mkdtempSync, readFileSync, rmSync, writeFileSync } from 'node:fs';
import { createRequire } from 'node:module';
import { tmpdir } from 'node:os';
import { join, resolve } from 'node:path';
import assert from 'node:assert/strict';

export const arg = (name) => {
  const i = process.argv.indexOf(name);
  if (i < 0) throw new Error(`missing ${name}`);
  return process.argv[i + 1];
};

export function playwright() {
  return createRequire(join(resolve(arg('--node-modules')), 'index.js'))('playwright-core');
}

/// @axe-core/playwright's AxeBuilder (the accessibility checks of axe-core).
export function axeBuilder() {
  return createRequire(join(resolve(arg('--node-modules')), 'index.js'))('@axe-core/playwright').default;
}

/// Runs axe-core on the page as it is now (WCAG 2.1 A and AA rules); the
/// serious and critical violations as [{id, impact, help, targets}].
export async function axeCheck(page) {
  const AxeBuilder = axeBuilder();
  const result = await new AxeBuilder({ page }).withTags(['wcag2a', 'wcag2aa', 'wcag21a', 'wcag21aa']).analyze();
  return result.violations.filter((v) => v.impact === 'serious' || v.impact === 'critical')
    .map((v) => ({ id: v.id, impact: v.impact, help: v.help, targets: v.nodes.map((n) => n.target.join(' ')).slice(0, 5) }));
}

/// Starts fesbench-server; resolves {child, url, token (admin), work}.
export function startServer({ timeScale, seed = 3 }) {
  const work = mkdtempSync(join(tmpdir(), 'fesbench-browser-'));
  const child = spawn(arg('--server'), ['--port', '0', '--db', join(work, 'fesbench.db'), '--time-scale', String(timeScale),
    '--web-root', arg('--web-root'), '--seed', String(seed), '--dds-transport', 'off'], { stdio: ['ignore', 'pipe', 'pipe'] });
  let out = '';
  child.stderr.on('data', (d) => process.stderr.write(`[server] ${d}`));
  return new Promise((resolve, reject) => {
    const timer = setTimeout(() => reject(new Error(`server did not start: ${out}`)), 20000);
    child.on('exit', (code) => reject(new Error(`server exited ${code}: ${out}`)));
    child.stdout.on('data', (d) => {
      out += d;
      const m = out.match(/listening on (http:\/\/127\.0\.0\.1:\d+)\//);
      if (m) {
        clearTimeout(timer);
        const token = readFileSync(join(work, 'admin.token'), 'utf8').trim();
        resolve({ child, url: m[1], token, work });
      }
    });
  });
}

export function stopServer(server) {
  if (server.child.exitCode === null) server.child.kill('SIGTERM');
  rmSync(server.work, { recursive: true, force: true });
}

export async function call(server, method, path, body, token = server.token) {
  const res = await fetch(`${server.url}/api/v1${path}`, {
    method, headers: { Authorization: `Bearer ${token}`, ...(body ? { 'Content-Type': 'application/json' } : {}) },
    body: body ? JSON.stringify(body) : undefined });
  const text = await res.text();
  return { status: res.status, body: text ? JSON.parse(text) : null };
}

/// A user with a role and their token (through the admin API).
export async function makeUser(server, name, role) {
  const user = await call(server, 'POST', '/users', { name, role });
  assert.equal(user.status, 201, JSON.stringify(user.body));
  const token = await call(server, 'POST', '/tokens', { user_id: user.body.id });
  return { ...user.body, token: token.body.token };
}

/// Headless Debian chromium in a persistent profile (so session storage
/// survives a reload), 1280×800.
export async function launch(server) {
  const { chromium } = playwright();
  const context = await chromium.launchPersistentContext(join(server.work, 'profile'), {
    executablePath: arg('--chromium'),
    headless: true,
    args: ['--no-sandbox', '--disable-gpu', '--disable-quic', '--no-first-run', '--disable-background-networking',
      '--disable-component-update', '--disable-sync'],
    viewport: { width: 1280, height: 800 },
    acceptDownloads: true,
  });
  context.setDefaultTimeout(20000);
  const page = context.pages()[0] || (await context.newPage());
  const external = [];
  page.on('request', (r) => { if (!r.url().startsWith(server.url)) external.push(r.url()); });
  // Every click the user makes (trusted events only), across reloads: the
  // walk's clicks per step.
  await context.exposeBinding('__fesbenchClick', () => { clicks.count += 1; });
  await context.addInitScript(() => {
    document.addEventListener('click', (e) => { if (e.isTrusted) window.__fesbenchClick(); }, true);
  });
  const consoleErrors = [];
  page.on('pageerror', (e) => consoleErrors.push(String(e)));
  page.on('console', (m) => { if (m.type() === 'error' && !/Failed to load resource/.test(m.text())) consoleErrors.push(m.text()); });
  return { context, page, external, consoleErrors };
}

/// Numbered screenshots under `dir`.
export function shooter(dir) {
  mkdirSync(dir, { recursive: true });
  let shots = 0;
  return {
    /// A full-page capture with the sticky header at the top (not mid-page).
    async full(page, name) {
      shots += 1;
      await page.evaluate(() => { document.querySelector('.chrome').style.position = 'static'; });
      await page.screenshot({ path: join(dir, `${String(shots).padStart(2, '0')}-${name}.png`), fullPage: true });
      await page.evaluate(() => { document.querySelector('.chrome').style.position = ''; });
    },
    /// What the user sees now (the viewport), at the current width.
    async view(page, name) {
      shots += 1;
      const w = page.viewportSize().width;
      await page.screenshot({ path: join(dir, `${String(shots).padStart(2, '0')}-${name}-${w}.png`) });
    },
    /// The viewport at 1280 and at 820 px width (back to 1280 after).
    async both(page, name) {
      await this.view(page, name);
      await page.setViewportSize({ width: 820, height: 1000 });
      await this.view(page, name);
      await page.setViewportSize({ width: 1280, height: 800 });
    },
  };
}

/// Clicks counted since launch (launch() installs the counter).
export const clicks = { count: 0 };
/// Each step's name, wall time and clicks, in order.
export const walk = [];

export async function step(name, fn) {
  const t0 = Date.now();
  const c0 = clicks.count;
  await fn();
  const entry = { name, ms: Date.now() - t0, clicks: clicks.count - c0 };
  walk.push(entry);
  console.log(`ok  ${name} (${entry.ms} ms, ${entry.clicks} clicks)`);
}

/// The walk (steps, clicks, times) and anything else as JSON under `dir`.
export function saveWalk(dir, extra = {}) {
  writeFileSync(join(dir, 'walk.json'), `${JSON.stringify({ steps: walk, ...extra }, null, 2)}\n`);
}

/// The e-stop button is inside the viewport on this page.
export async function expectEstopVisible(page) {
  const box = await page.locator('#estop').boundingBox();
  const vp = page.viewportSize();
  assert.ok(box && box.y >= 0 && box.y + box.height <= vp.height && box.x + box.width <= vp.width,
    `e-stop not in the viewport: ${JSON.stringify(box)}`);
}

/// Fills a protocol parameter, unfolding the advanced parameters if it is one of them.
export async function fillParameter(page, name, value) {
  const input = page.locator(`#f-${name}`);
  if (!(await input.isVisible())) await page.locator('#advanced-parameters > summary').click();
  await input.fill(value);
}

// The end of every browser test: on an error its message and a screenshot
// of the page, then the browser context and the server closed, the notes
// and the verdict printed, and the process ends with the verdict.
export async function finish({ error, page, context, server, artefacts, started, notes = [] }) {
  if (error) {
    console.error('FAILED:', error);
    try {
      const shown = page || (context && context.pages()[0]);
      if (shown) await shown.screenshot({ path: join(artefacts, 'failure.png'), fullPage: true });
    } catch { /* best effort */ }
  }
  if (context) await context.close();
  stopServer(server);
  for (const n of notes) console.log(`    ${n}`);
  console.log(`${error ? 'FAILED' : 'passed'} in ${((Date.now() - started) / 1000).toFixed(1)} s; screenshots in ${artefacts}`);
  process.exit(error ? 1 : 0);
}
