// Browser test of data in and out (docs/API.md) on the session page: a recording made on another
// rig (ms, radians, amperes) uploaded with its kind and column mapping; a
// bad file refused with the line and column named and nothing stored; the
// session report opened in a new tab and captured (screenshot and, where
// the browser can, an A4 PDF); the session exported as a zip and that zip
// imported into another session.
//
//   node data_exchange_test.mjs --server BIN --web-root DIR --node-modules DIR
//                               --chromium BIN --artefacts DIR
import assert from 'node:assert/strict';
import { statSync } from 'node:fs';
import { arg, call, finish, launch, shooter, startServer, step } from './harness.mjs';

const artefacts = arg('--artefacts');
const shots = shooter(artefacts);
const started = Date.now();
const server = await startServer({ timeScale: 0 });
let context;
let page;
let error;

// 2 s of a knee swinging under a stimulation step, as another rig writes it.
function rigCsv() {
  let csv = 'Time (ms),Knee angle (rad),Stim (A)\n';
  for (let i = 0; i < 400; i += 1) {
    const t = i * 5;
    const angle = (70 + 10 * Math.sin(i / 40)) * Math.PI / 180;
    csv += `${t},${angle},${i >= 100 && i < 300 ? 0.03 : 0}\n`;
  }
  return csv;
}

async function newSession(code) {
  const subject = await call(server, 'POST', '/subjects',
    { code, legs: ['right'], details: { weight_kg: 72, shank_length_cm: 43 } });
  const session = await call(server, 'POST', `/subjects/${subject.body.id}/sessions`,
    { leg: 'right', date: '2026-11-25', threshold_ma: 15, max_tolerated_ma: 40 });
  assert.equal(session.status, 201);
  return session.body.id;
}

try {
  const launched = await launch(server);
  context = launched.context;
  page = launched.page;
  const first = await newSession('RIG01');
  const second = await newSession('RIG02');

  await step('sign in and open the session', async () => {
    await page.goto(`${server.url}/`);
    await page.waitForURL(/#\/signin$/);
    await page.getByLabel('Access token').fill(server.token);
    await page.keyboard.press('Enter');
    await page.waitForURL(/#\/subjects$/);
    await page.goto(`${server.url}/#/sessions/${first}`);
    await page.locator('#exchange').waitFor();
  });

  await step('a bad recording: the line and column named, nothing stored', async () => {
    await page.locator('#exchange summary').click();
    await page.locator('#f-import_file').setInputFiles({ name: 'bad.csv', mimeType: 'text/csv',
      buffer: Buffer.from('Time (ms),Knee angle (rad),Stim (A)\n0,1.2,0\n5,1.2,0\n5,1.3,0\n') });
    await page.locator('#f-import_kind').selectOption('prediction_step');
    await page.locator('#f-import_time_column').fill('Time (ms)');
    await page.locator('#f-import_time_unit').selectOption('ms');
    await page.locator('#f-import_columns').fill('Knee angle (rad)=angle_deg:rad\nStim (A)=stim_ma:A');
    await page.locator('#import-submit').click();
    await page.locator('#exchange-status').filter({ hasText: 'line 4, column 1 (Time (ms))' }).waitFor();
    await shots.view(page, 'import-refused');
    assert.equal((await call(server, 'GET', `/sessions/${first}/trials`)).body.items.length, 0);
  });

  await step('a recording from another rig: imported, listed, plotted', async () => {
    await page.locator('#f-import_file').setInputFiles({ name: 'rig-b.csv', mimeType: 'text/csv',
      buffer: Buffer.from(rigCsv()) });
    await page.locator('#f-import_source').fill('rig B');
    await page.locator('#import-submit').click();
    await page.locator('#exchange-status').filter({ hasText: 'Imported 1 trial(s) from rig-b.csv.' }).waitFor();
    await page.locator('#import-table').waitFor();
    await page.locator('#trials-table').filter({ hasText: 'prediction_step' }).waitFor();
    const trials = (await call(server, 'GET', `/sessions/${first}/trials`)).body.items;
    assert.equal(trials.length, 1);
    const trial = (await call(server, 'GET', `/trials/${trials[0].id}`)).body;
    assert.equal(trial.import.source, 'rig B');
    const angle = trial.channels.find((c) => c.name === 'angle_deg').values;
    assert.ok(Math.abs(angle[0] - 70) < 1e-9, `angle converted from rad: ${angle[0]}`);
    const stim = trial.channels.find((c) => c.name === 'stim_ma').values;
    assert.ok(Math.abs(stim[150] - 30) < 1e-9, `stimulation converted from A: ${stim[150]}`);
    await page.locator(`[data-trial="${trials[0].id}"]`).click();
    await page.locator('[data-plot="trial-angle"]').waitFor();
    await shots.view(page, 'imported');
  });

  let reported;
  await step('a rapid run and a prediction of the imported recording (for the report)', async () => {
    const run = await call(server, 'POST', `/sessions/${first}/runs`, { protocol: 'rapid_parameterisation' });
    assert.equal(run.status, 201, JSON.stringify(run.body));
    let view;
    for (let i = 0; i < 600; i += 1) {
      await call(server, 'POST', `/runs/${run.body.run_id}/heartbeat`);
      view = (await call(server, 'GET', `/runs/${run.body.run_id}`)).body;
      if (['done', 'aborted', 'failed'].includes(view.state)) break;
      await new Promise((r) => setTimeout(r, 100));
    }
    assert.equal(view.state, 'done', JSON.stringify(view));
    const trial = (await call(server, 'GET', `/sessions/${first}/trials`)).body.items.find((t) => t.name === 'prediction_step');
    const job = await call(server, 'POST', '/predictions', { parameter_set_id: view.parameter_set_id, trial_id: trial.id });
    assert.equal(job.status, 202, JSON.stringify(job.body));
    let state = job.body;
    while (state.state !== 'done' && state.state !== 'failed') {
      await new Promise((r) => setTimeout(r, 100));
      state = (await call(server, 'GET', `/jobs/${job.body.id}`)).body;
    }
    assert.equal(state.state, 'done', JSON.stringify(state));
    // The same trial predicted twice: the report lists it once (the newest).
    const again = await call(server, 'POST', '/predictions', { parameter_set_id: view.parameter_set_id, trial_id: trial.id });
    state = again.body;
    while (state.state !== 'done' && state.state !== 'failed') {
      await new Promise((r) => setTimeout(r, 100));
      state = (await call(server, 'GET', `/jobs/${again.body.id}`)).body;
    }
    assert.equal(state.state, 'done', JSON.stringify(state));
    reported = { run: view, prediction: state.result };
  });

  await step('the session report in a new tab, printable', async () => {
    await page.reload();
    await page.locator('#open-report').waitFor();
    const [report] = await Promise.all([context.waitForEvent('page'), page.locator('#open-report').click()]);
    await report.waitForLoadState();
    await report.locator('#runs-section').waitFor();
    for (const id of ['#session', '#trials-section', '#warnings']) {
      assert.ok(await report.locator(id).isVisible(), `${id} is not visible`);
    }
    assert.match(await report.locator('h1').textContent(), /RIG01, right leg/);
    assert.match(await report.locator('#trials').textContent(), /prediction_step/);
    assert.ok(await report.locator('figure.plot svg').count() >= 7, 'curves and a prediction figure');
    assert.match(await report.locator('table.predictions').textContent(), /prediction_step/);
    // The numbers are the API's: the run's outcome, each prediction once, in its unit.
    const runRow = report.locator('#runs tbody tr', { hasText: 'rapid_parameterisation' });
    assert.match(await runRow.textContent(), new RegExp(`parameter set ${reported.run.parameter_set_id}`));
    const predRows = report.locator('table.predictions tbody tr');
    assert.equal(await predRows.count(), 1, 'a trial predicted twice is listed once');
    const cells = await predRows.first().locator('td').allTextContents();
    const e = reported.prediction.errors;
    assert.equal(Number(cells[0]), reported.prediction.prediction_id, 'the newest prediction');
    const unit = e.unit === 'deg' ? 'deg' : 'N.m';
    assert.equal(cells[3], `${e.e_rms.toFixed(2)} ${unit}`);
    assert.equal(cells[4], `${e.e_abs.toFixed(2)} ${unit}`);
    await report.setViewportSize({ width: 1000, height: 1400 });
    await report.screenshot({ path: `${artefacts}/session-report.png`, fullPage: true });
    await report.emulateMedia({ media: 'print' });
    await report.pdf?.({ path: `${artefacts}/session-report.pdf`, format: 'A4' }).catch(() => {});
    console.log(`    report screenshot: ${artefacts}/session-report.png`);
    await report.close();
  });

  let zipPath;
  await step('export the session as a zip', async () => {
    const [download] = await Promise.all([page.waitForEvent('download'), page.locator('#export-zip').click()]);
    assert.equal(download.suggestedFilename(), `fesbench-session-${first}.zip`);
    zipPath = `${artefacts}/fesbench-session-${first}.zip`;
    await download.saveAs(zipPath);
    assert.ok(statSync(zipPath).size > 1000);
    await page.locator('#exchange-status').filter({ hasText: 'Downloaded' }).waitFor();
  });

  await step('the zip imported into another session', async () => {
    await page.goto(`${server.url}/#/sessions/${second}`);
    await page.locator('#exchange').waitFor();
    await page.locator('#exchange summary').click();
    await page.locator('#f-import_file').setInputFiles(zipPath);
    await page.locator('#import-submit').click();
    await page.locator('#exchange-status').filter({ hasText: /Imported \d+ trial/ }).waitFor();
    const trials = (await call(server, 'GET', `/sessions/${second}/trials`)).body.items;
    const original = (await call(server, 'GET', `/sessions/${first}/trials`)).body.items;
    assert.equal(trials.length, original.length);
    assert.match(await page.locator('#import-table').textContent(), /parameter set/);
    await shots.view(page, 'archive-imported');
  });
} catch (e) {
  error = e;
}
await finish({ error, page, context, server, artefacts, started });
