// Browser test of form errors: a form submitted with three invalid fields shows
// all three messages at once — each beside its field, with the unit and the
// allowed range the server applies ("must be 1–400 kg, got -5") — and sends
// nothing to the server; the same for the new-session form. The server's own
// 400 names the field, its unit and range in the same words.
//
//   node form_errors_test.mjs --server BIN --web-root DIR --node-modules DIR
//                             --chromium BIN --artefacts DIR
import assert from 'node:assert/strict';
import { arg, call, finish, launch, shooter, startServer, step } from './harness.mjs';

const artefacts = arg('--artefacts');
const shots = shooter(artefacts);
const started = Date.now();
const server = await startServer({ timeScale: 0 });
let context;
let page;
let error;

// The messages of every field of `form` that has one, by input name.
async function fieldMessages(form) {
  return page.locator(`${form} [aria-invalid=true]`).evaluateAll((inputs) => Object.fromEntries(
    inputs.map((i) => [i.name, document.getElementById(`${i.id}-error`).textContent])));
}

try {
  const launched = await launch(server);
  context = launched.context;
  page = launched.page;
  const writes = [];
  page.on('request', (r) => { if (r.method() !== 'GET') writes.push(`${r.method()} ${new URL(r.url()).pathname}`); });

  await step('sign in', async () => {
    await page.goto(`${server.url}/`);
    await page.waitForURL(/#\/signin$/);
    await page.getByLabel('Access token').fill(server.token);
    await page.keyboard.press('Enter');
    await page.waitForURL(/#\/subjects$/);
  });

  await step('new subject with three invalid fields: all three messages at once, nothing sent', async () => {
    await page.getByLabel('Pseudonymous code').fill('S 01');
    await page.getByLabel('Body mass (kg)').fill('-5');
    await page.getByLabel('Shank length (cm)').fill('500');
    await page.getByLabel('Age (years)').fill('34');
    writes.length = 0;
    await page.getByRole('button', { name: 'Create subject' }).click();
    await page.locator('#subject-form-status').filter({ hasText: 'Please correct the 3 marked fields.' }).waitFor();
    const messages = await fieldMessages('#subject-form');
    assert.deepEqual(Object.keys(messages).sort(), ['code', 'shank_length_cm', 'weight_kg']);
    assert.match(messages.code, /letters, digits, _ and -/);
    assert.equal(messages.weight_kg, 'must be 1–400 kg, got -5');
    assert.equal(messages.shank_length_cm, 'must be 10–80 cm, got 500');
    for (const name of ['code', 'weight_kg', 'shank_length_cm']) {
      assert.ok(await page.locator(`#f-${name}-error`).isVisible(), `${name}'s message is not visible`);
    }
    assert.equal(await page.locator('#f-age_years').getAttribute('aria-invalid'), null, 'a valid field is marked');
    assert.deepEqual(writes, [], 'an invalid form reached the server');
    assert.deepEqual((await call(server, 'GET', '/subjects')).body.items, []);
    await shots.view(page, 'subject-three-invalid');
    // Corrected: the messages go and the subject is created.
    await page.getByLabel('Pseudonymous code').fill('S01');
    await page.getByLabel('Body mass (kg)').fill('72');
    await page.getByLabel('Shank length (cm)').fill('43');
    await page.getByRole('button', { name: 'Create subject' }).click();
    await page.locator('#subject-form-status').filter({ hasText: 'Subject S01 created.' }).waitFor();
    assert.equal(await page.locator('#subject-form [aria-invalid=true]').count(), 0);
  });

  await step('new session with three invalid fields: all three messages at once, nothing sent', async () => {
    const subject = (await call(server, 'GET', '/subjects?code=S01')).body.items[0];
    await page.goto(`${server.url}/#/subjects/${subject.id}`);
    await page.locator('#session-form').waitFor();
    await page.locator('#f-date').fill('2026-13-40');
    await page.locator('#f-threshold_ma').fill('150');
    await page.locator('#f-max_tolerated_ma').fill('-1');
    writes.length = 0;
    await page.getByRole('button', { name: 'Open session' }).click();
    await page.locator('#session-form-status').filter({ hasText: 'Please correct the 3 marked fields.' }).waitFor();
    const messages = await fieldMessages('#session-form');
    assert.deepEqual(messages, {
      date: 'must be a calendar date YYYY-MM-DD, got 2026-13-40',
      threshold_ma: 'must be 0–100 mA, got 150',
      max_tolerated_ma: 'must be 0–100 mA, got -1',
    });
    assert.deepEqual(writes, [], 'an invalid form reached the server');
    await shots.view(page, 'session-three-invalid');
  });

  await step('a tolerance test above the recorded max needs a reason, which is sent and audited', async () => {
    const subject = (await call(server, 'GET', '/subjects?code=S01')).body.items[0];
    const side = (await call(server, 'GET', `/subjects/${subject.id}`)).body.legs[0].side;
    const session = await call(server, 'POST', `/subjects/${subject.id}/sessions`,
      { leg: side, date: '2026-11-24', threshold_ma: 5, max_tolerated_ma: 12 });
    assert.equal(session.status, 201, JSON.stringify(session.body));
    await page.goto(`${server.url}/#/sessions/${session.body.id}`);
    await page.locator('#protocol').selectOption('tolerance_test');
    await page.locator('#advanced-parameters').evaluate((d) => { d.open = true; });
    await page.locator('#f-ceiling_ma').fill('14');
    await page.locator('#start-run:not([disabled])').waitFor();
    await page.locator('#start-run').click();
    const status = page.locator('#run-form-status .msg');
    await status.filter({ hasText: /correct|Cannot start/ }).waitFor();
    assert.match(await page.locator('#f-ceiling_ma-error').textContent(), /needs an explicit ceiling_reason/);
    await page.getByLabel('Reason for a ceiling above the recorded max').fill('re-test after four weeks of training');
    await page.locator('#start-run').click();
    await status.filter({ hasText: /Run \d+ started/ }).waitFor();
    const runId = Number((await status.textContent()).match(/Run (\d+) started/)[1]);
    const audit = (await call(server, 'GET', '/audit?limit=20')).body.items
      .find((e) => e.action === 'run.ceiling_above_max' && e.target === `runs/${runId}`);
    assert.ok(audit, 'the decision is not audited');
    assert.match(audit.request_summary, /ceiling 14 mA above the session's recorded max tolerated 12 mA; reason: re-test after four weeks/);
    await page.locator('#run-end').filter({ hasText: /done|aborted|failed/ }).waitFor({ timeout: 60000 });
  });

  await step("the server's 400 names the field, its unit and its range", async () => {
    const bad = await call(server, 'POST', '/subjects', { code: 'S02', details: { weight_kg: -5 } });
    assert.equal(bad.status, 400);
    assert.deepEqual(bad.body.error, { code: 'invalid_argument', message: 'weight_kg must be 1–400 kg, got -5',
      field: 'details.weight_kg' });
    const age = await call(server, 'POST', '/subjects', { code: 'S02', details: { age_years: 200 } });
    assert.equal(age.body.error.message, 'age_years must be 0–130 years, got 200');
  });

  assert.deepEqual(launched.external, [], 'the page requested something from elsewhere');
  assert.deepEqual(launched.consoleErrors, [], 'uncaught errors in the page');
} catch (e) {
  error = e;
}
await finish({ error, page, context, server, artefacts, started });
