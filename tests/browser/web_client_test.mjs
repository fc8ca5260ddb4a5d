// Browser test of the fesbench web client (README, "Web client"): starts fesbench-server on
// loopback (temporary database, simulated bench in accelerated time), drives
// Debian's chromium headless with Playwright through the clinician's whole
// flow, and saves a screenshot of each page. Waits are on page state
// (selectors, texts, data attributes), never fixed sleeps.
//
//   node web_client_test.mjs --server BIN --web-root DIR --node-modules DIR
//                            --chromium BIN --artefacts DIR
import net from 'node:net';
import assert from 'node:assert/strict';
import { arg, call, expectEstopVisible, fillParameter, finish, launch, shooter, startServer, step } from './harness.mjs';

const TIME_SCALE = 8;
const artefacts = arg('--artefacts');
const shots = shooter(artefacts);
const shot = (page, name) => shots.full(page, name);

// The status of a GET with exactly this request target (no URL normalisation).
function rawStatus(url, target) {
  const { port } = new URL(url);
  return new Promise((resolve, reject) => {
    const socket = net.connect(Number(port), '127.0.0.1', () =>
      socket.write(`GET ${target} HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n\r\n`));
    let data = '';
    socket.on('data', (d) => { data += d; });
    socket.on('end', () => resolve(Number((data.match(/^HTTP\/1\.1 (\d+)/) || [])[1])));
    socket.on('error', reject);
  });
}

const started = Date.now();
const server = await startServer({ timeScale: TIME_SCALE });
let context;
let error;
try {
  await step('static files: index, hashed assets, content types, caching, no traversal', async () => {
    const index = await fetch(`${server.url}/`);
    assert.equal(index.status, 200);
    assert.match(index.headers.get('content-type'), /^text\/html/);
    assert.equal(index.headers.get('cache-control'), 'no-cache');
    assert.match(index.headers.get('content-security-policy'), /default-src 'self'/);
    const html = await index.text();
    const js = html.match(/src="\/(app-[A-Z0-9]+\.js)"/)[1];
    const css = html.match(/href="\/(app-[A-Z0-9]+\.css)"/)[1];
    const jsRes = await fetch(`${server.url}/${js}`);
    assert.equal(jsRes.status, 200);
    assert.match(jsRes.headers.get('content-type'), /^text\/javascript/);
    assert.match(jsRes.headers.get('cache-control'), /immutable/);
    const cssRes = await fetch(`${server.url}/${css}`);
    assert.match(cssRes.headers.get('content-type'), /^text\/css/);
    // Nothing from elsewhere: no absolute URLs to other hosts in the page or bundle.
    for (const text of [html, await cssRes.text()]) assert.doesNotMatch(text, /(src|href)=["']?(https?:)?\/\//);
    // Raw request lines: a browser's URL parser would remove the dot segments.
    for (const p of ['/../fesbench.db', '/..%2ffesbench.db', '/%2e%2e/fesbench.db', '/%2E%2E/%2E%2E/etc/passwd',
      '/../../../../etc/passwd', '/.hidden', '/index.html/..', '/nonexistent.js', '/api/v1/nothing']) {
      const status = await rawStatus(server.url, p);
      assert.equal(status, 404, `${p} answered ${status}`);
    }
    const post = await fetch(`${server.url}/`, { method: 'POST' });
    assert.ok(post.status === 404 || post.status === 405, `POST / answered ${post.status}`);
    const me = await call(server, 'GET', '/me');
    assert.deepEqual([me.status, me.body.name, me.body.role], [200, 'admin', 'admin']);
  });

  let page;
  let external;
  let consoleErrors;
  ({ context, page, external, consoleErrors } = await launch(server));

  await step('signed out, E-STOP says at once and plainly that it cannot stop the bench (docs/SAFETY.md)', async () => {
    await page.goto(`${server.url}/`);
    await page.waitForURL(/#\/signin$/);
    await expectEstopVisible(page);
    // The page does not look signed in.
    assert.equal(await page.locator('#who').textContent(), 'Not signed in');
    assert.equal(await page.locator('#estop-state').textContent(), 'Bench: unknown');
    const sent = [];
    const listen = (r) => { if (r.url().includes('/bench/estop')) sent.push(r.url()); };
    page.on('request', listen);
    await page.locator('#estop').click();
    await page.locator('#latch').filter({ hasText: 'E-STOP NOT CONFIRMED' }).waitFor({ timeout: 1000 });
    assert.match(await page.locator('#latch').textContent(), /Sign in to send the e-stop\. Use the bench's hardware stop\./);
    page.off('request', listen);
    assert.deepEqual(sent, [], 'a signed-out e-stop sent a request');
    await shot(page, 'estop-signed-out');
    // The bench is polled every second; the failure stays until dismissed.
    await page.waitForTimeout(2500);
    assert.match(await page.locator('#latch').textContent(), /E-STOP NOT CONFIRMED/);
    await page.locator('#estop-failed-dismiss').click();
    assert.equal(await page.locator('#latch').isHidden(), true);
  });

  await step('sign in: a wrong token is refused plainly, the right one shows name and role', async () => {
    await page.goto(`${server.url}/`);
    await page.waitForURL(/#\/signin$/);
    await expectEstopVisible(page);
    await page.getByLabel('Access token').fill('fsb_not_a_real_token');
    await page.keyboard.press('Enter');
    await page.locator('#signin-status .msg-error').filter({ hasText: 'Sign-in failed' }).waitFor();
    await shot(page, 'signin-refused');
    await page.getByLabel('Access token').fill(server.token);
    await page.keyboard.press('Enter');
    await page.waitForURL(/#\/subjects$/);
    assert.equal(await page.locator('#who-name').textContent(), 'Signed in as admin');
    assert.equal(await page.locator('#who-role').textContent(), 'admin');
  });

  await step('subjects: bad input shows the server\'s field message; create; search', async () => {
    await page.getByLabel('Pseudonymous code').fill('bad code!');
    await page.getByRole('button', { name: 'Create subject' }).click();
    const codeError = page.locator('#f-code-error');
    await codeError.filter({ hasText: /letters, digits/ }).waitFor();
    assert.equal(await page.locator('#f-code').getAttribute('aria-invalid'), 'true');
    await shot(page, 'subject-bad-input');
    await page.getByLabel('Pseudonymous code').fill('S01');
    await page.getByLabel('Age (years)').fill('34');
    await page.getByLabel('Height (cm)').fill('178');
    await page.getByLabel('Body mass (kg)').fill('72');
    await page.getByLabel('Shank length (cm)').fill('43');
    await page.getByRole('button', { name: 'Create subject' }).click();
    await page.locator('#subject-form-status').filter({ hasText: 'Subject S01 created.' }).waitFor();
    assert.equal(await codeError.textContent(), '');
    await page.locator('#subjects-table').getByRole('link', { name: 'S01' }).waitFor();
    await call(server, 'POST', '/subjects', { code: 'S02', legs: ['left'] });
    await page.getByLabel('Find by code').fill('S02');
    await page.getByRole('button', { name: 'Search' }).click();
    await page.locator('#subjects-table').getByRole('link', { name: 'S02' }).waitFor();
    assert.equal(await page.locator('#subjects-table tbody tr').count(), 1);
    await page.getByRole('button', { name: 'Show all' }).click();
    await page.locator('#subjects-table').getByRole('link', { name: 'S01' }).waitFor();
    await shot(page, 'subjects');
  });

  let sessionUrl;
  await step('sessions: bad date refused on its field, then a session is opened', async () => {
    await page.locator('#subjects-table').getByRole('link', { name: 'S01' }).click();
    await page.getByRole('heading', { name: 'Subject S01' }).waitFor();
    await page.getByLabel('Date (YYYY-MM-DD)').fill('2026-13-45');
    await page.getByLabel('Stimulation threshold (mA)').fill('20');
    await page.getByLabel('Max tolerated (mA)').fill('45');
    await page.getByLabel('Accelerometer placement').fill('shank, 20 cm below the knee');
    await page.getByRole('button', { name: 'Open session' }).click();
    await page.locator('#f-date-error').filter({ hasText: 'YYYY-MM-DD' }).waitFor();
    await page.getByLabel('Date (YYYY-MM-DD)').fill('2026-11-20');
    await shot(page, 'subject');
    await page.getByRole('button', { name: 'Open session' }).click();
    // Opening a session opens its page.
    await page.locator('#run-form').waitFor();
    assert.match(page.url(), /#\/sessions\/\d+$/);
    sessionUrl = page.url();
    // Back on the subject's page the new session is listed, the form empty of it.
    await page.goBack();
    await page.locator('#sessions-table a').first().waitFor();
    assert.equal(await page.locator('#sessions-table a').count(), 1);
    await page.goto(sessionUrl);
    await page.locator('#run-form').waitFor();
  });

  let setUrl;
  await step('run: parameters prefilled; bad parameter refused; rapid run with progress, ETA and live plots', async () => {
    assert.equal(await page.locator('#protocol').inputValue(), 'rapid_parameterisation');
    // Prefilled from the protocol description and the session's threshold / max tolerated.
    assert.equal(await page.locator('#f-threshold_ma').inputValue(), '20');
    assert.equal(await page.locator('#f-max_ma').inputValue(), '45');
    assert.equal(await page.locator('#f-duration_s').inputValue(), '10');
    // A range-scaled amplitude shows mA: threshold + 0.6·(max − threshold).
    assert.equal(await page.locator('#f-amplitude_ma').inputValue(), '35');
    await fillParameter(page, 'max_ma', '500');
    await page.getByRole('button', { name: 'Start protocol' }).click();
    await page.locator('#f-max_ma-error').filter({ hasText: /must be [0-9.]+–[0-9.]+ mA, got 500/ }).waitFor();
    await fillParameter(page, 'max_ma', '45');
    await page.getByRole('button', { name: 'Start protocol' }).click();
    await page.locator('#live[data-state="running"]').waitFor();
    await page.waitForFunction(() => Number(document.querySelector('#live').dataset.samples || 0) > 600 &&
      Number(document.querySelector('#run-progress').value) > 0.2);
    assert.match(await page.locator('#run-eta').textContent(), /^ETA \d+ s/);
    assert.equal(await page.locator('#live figure.plot').count(), 3);
    await expectEstopVisible(page);
    await shot(page, 'run-live');
    await page.locator('#live[data-state="done"]').waitFor({ timeout: 60000 });
    await page.locator('#run-parameter-set').waitFor();
    assert.equal(await page.locator('#run-progress').evaluate((e) => e.value), 1);
    await shot(page, 'run-done');
    await page.locator('#run-parameter-set').click();
    await page.locator('#set-plots figure.plot').nth(5).waitFor();
    setUrl = page.url();
  });

  await step('parameter set: six plots and the values table', async () => {
    assert.equal(await page.locator('#set-plots figure.plot').count(), 6);
    for (const id of ['irc', 'twitch', 'passive-angle', 'passive-velocity', 'active-angle', 'active-velocity']) {
      await page.locator(`figure[data-plot="${id}"] canvas`).waitFor();
    }
    const table = await page.locator('#values-table').textContent();
    for (const label of ['τ_scale', 'inertia', 'pole', 'Recruitment threshold']) assert.ok(table.includes(label), label);
    await shot(page, 'parameter-set');
  });

  await step('cancel a run', async () => {
    await page.goto(sessionUrl);
    await page.locator('#protocol').selectOption('active_random_binary');
    await fillParameter(page, 'duration_s', '120');
    await page.getByRole('button', { name: 'Start protocol' }).click();
    await page.locator('#live[data-state="running"]').waitFor();
    await page.waitForFunction(() => Number(document.querySelector('#live').dataset.samples) > 100);
    await page.locator('#cancel-run').click();
    await page.locator('#live[data-state="aborted"]').waitFor();
    await page.locator('#run-end .msg').filter({ hasText: /ended: aborted/ }).waitFor();
    console.log(`    ${await page.locator('#run-end .msg').textContent()}`);
  });

  await step('e-stop during a run: the run ends, the latch shows, start disabled, cleared after confirming', async () => {
    await page.locator('#protocol').selectOption('active_random_binary');
    await fillParameter(page, 'duration_s', '120');
    await page.getByRole('button', { name: 'Start protocol' }).click();
    await page.locator('#live[data-state="running"]').waitFor();
    await page.waitForFunction(() => Number(document.querySelector('#live').dataset.samples) > 100);
    await page.locator('#estop').click();
    await page.locator('#latch').filter({ hasText: 'E-STOP LATCHED' }).waitFor();
    assert.equal(await page.locator('#estop-state').textContent(), 'Bench: LATCHED');
    await page.locator('#live[data-state="aborted"]').waitFor();
    const bench = await call(server, 'GET', '/bench');
    assert.equal(bench.body.state.estopped, true);
    await shot(page, 'estop');
    // While latched nothing can start, and the page says why.
    assert.equal(await page.getByRole('button', { name: 'Start protocol' }).isDisabled(), true);
    await page.locator('#start-hint').filter({ hasText: 'e-stop is latched' }).waitFor();
    // Clearing takes a dialog and a second, explicit confirmation.
    await page.locator('#estop-clear').click();
    await page.locator('#estop-dialog').waitFor();
    assert.equal(await page.locator('#estop-confirm').isDisabled(), true);
    await page.locator('#estop-keep').click();
    assert.equal((await call(server, 'GET', '/bench')).body.state.estopped, true);
    await page.locator('#estop-clear').click();
    await page.locator('#estop-confirm-check').check();
    await page.locator('#estop-confirm').click();
    await page.locator('#estop-state').filter({ hasText: 'Bench: idle' }).waitFor();
    assert.equal(await page.locator('#latch').isHidden(), true);
  });

  await step('second parameter set (another rapid run) for history and comparison', async () => {
    await page.locator('#protocol').selectOption('rapid_parameterisation');
    await page.getByRole('button', { name: 'Start protocol' }).click();
    await page.locator('#live[data-state="done"]').waitFor({ timeout: 60000 });
  });

  await step('history and comparison of two parameter sets', async () => {
    await page.locator('.crumbs a').nth(1).click();
    await page.locator('#compare-form').waitFor();
    await page.locator('#history-link').click();
    await page.locator('#history-plots figure.plot').nth(3).waitFor();
    assert.equal(await page.locator('#history-table tbody tr').count(), 2);
    await shot(page, 'history');
    await page.goBack();
    await page.locator('#compare-form').waitFor();
    await page.getByRole('button', { name: 'Compare' }).click();
    await page.locator('#compare-table').waitFor();
    await page.locator('#set-plots figure.plot').nth(5).waitFor();
    await shot(page, 'compare');
  });

  await step('prediction: predicted vs measured knee angle with the error figures', async () => {
    await page.goto(setUrl);
    await page.locator('#predict-link').click();
    await page.locator('#predict-trial option').filter({ hasText: 'random_binary' }).first().waitFor({ state: 'attached' });
    await page.getByRole('button', { name: 'Run prediction' }).click();
    await page.locator('#error-table').waitFor({ timeout: 30000 });
    const rms = Number((await page.locator('#error-table tbody tr').first().locator('td').textContent()).trim());
    assert.ok(rms > 0 && rms < 10, `E_RMS ${rms} deg`);
    await page.locator('figure[data-plot="prediction"] canvas').waitFor();
    await shot(page, 'prediction');
  });

  await step('tablet width: the e-stop stays visible, plots stack', async () => {
    await page.setViewportSize({ width: 820, height: 1180 });
    await page.goto(setUrl);
    await page.locator('#set-plots figure.plot').nth(5).waitFor();
    await expectEstopVisible(page);
    const widths = await page.locator('#set-plots figure.plot').evaluateAll((fs) => fs.map((f) => f.getBoundingClientRect().width));
    assert.ok(widths.every((w) => w <= 820), `plot wider than the page: ${widths}`);
    await shot(page, 'tablet-parameter-set');
    await page.setViewportSize({ width: 1280, height: 800 });
  });

  await step('keyboard: the e-stop is reachable with Tab', async () => {
    await page.goto(`${server.url}/#/subjects`);
    await page.reload(); // a fresh document: focus starts at its top
    await page.locator('#subjects-table').waitFor();
    let focused = '';
    for (let i = 0; i < 12 && focused !== 'estop'; i++) {
      await page.keyboard.press('Tab');
      focused = await page.evaluate(() => document.activeElement && document.activeElement.id);
    }
    assert.equal(focused, 'estop');
  });

  await step('a clinician sees their role and may run the model check (a prediction)', async () => {
    const user = await call(server, 'POST', '/users', { name: 'dr_lee', role: 'clinician' });
    const token = await call(server, 'POST', '/tokens', { user_id: user.body.id });
    await page.getByRole('button', { name: 'Sign out' }).click();
    await page.getByLabel('Access token').fill(token.body.token);
    await page.getByRole('button', { name: 'Sign in' }).click();
    await page.waitForURL(/#\/subjects$/);
    assert.equal(await page.locator('#who-name').textContent(), 'Signed in as dr_lee');
    assert.equal(await page.locator('#who-role').textContent(), 'clinician');
    await page.goto(`${server.url}/#/predict`);
    await page.getByRole('button', { name: 'Run prediction' }).waitFor();
    assert.equal(await page.getByRole('button', { name: 'Run prediction' }).isDisabled(), false);
  });

  await step('server unreachable: the page says so', async () => {
    await page.goto(`${server.url}/#/subjects`);
    await page.locator('#subjects-table').waitFor();
    server.child.kill('SIGTERM');
    await new Promise((r) => server.child.once('exit', r));
    await page.getByRole('button', { name: 'Search' }).click();
    await page.locator('#banner').filter({ hasText: 'cannot be reached' }).waitFor();
    await page.locator('#main .msg-error').filter({ hasText: 'cannot be reached' }).waitFor();
    await page.locator('#estop-state').filter({ hasText: 'Bench: unknown' }).waitFor();
    await shot(page, 'unreachable');
  });

  assert.deepEqual(external, [], 'the page requested something from elsewhere');
  assert.deepEqual(consoleErrors, [], 'uncaught errors in the page');
} catch (e) {
  error = e;
}
await finish({ error, context, server, artefacts, started });
