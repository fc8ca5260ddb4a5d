// Browser test of README's "First session with a new subject": a clinician's first session with a
// new subject, the whole chain in the web client on a fresh server — sign in → new
// subject without body mass / shank length → add them by correction (with a
// reason) → session without threshold / max tolerated → tolerance test,
// "the subject says stop" → the session shows the recorded values → rapid
// parameterisation while switching views (the run survives, the run bar
// shows throughout) → prediction_random_binary and prediction_step runs →
// the prediction page (an analyst colleague) on those fresh trials with the
// error figures → e-stop during a run, confirmed clear. Viewport
// screenshots of each step at 1280 and 820 px.
//
//   node clinician_chain_test.mjs --server BIN --web-root DIR --node-modules DIR
//                                 --chromium BIN --artefacts DIR
import assert from 'node:assert/strict';
import { arg, axeCheck, call, expectEstopVisible, fillParameter, finish, launch, makeUser, saveWalk, shooter, startServer, step } from './harness.mjs';

// Runs last seconds of wall time (rapid ≈ 14 s), so switching views really
// happens while the run goes on, also when the machine is busy with other
// tests (at 5×, a loaded machine finished the rapid run before the page
// came back to its run bar).
const TIME_SCALE = 2;
const artefacts = arg('--artefacts');
const shots = shooter(artefacts);
const started = Date.now();

const server = await startServer({ timeScale: TIME_SCALE });
let context;
let page;
let error;
const notes = [];
// axe-core on every page of the walk: its serious and critical violations.
const axe = [];
async function snap(name) {
  await shots.both(page, name);
  const violations = await axeCheck(page);
  axe.push({ page: name, url: page.url().replace(/^.*#/, '#'), serious_or_critical: violations.length, violations });
  if (violations.length) console.log(`axe ${name}: ${JSON.stringify(violations)}`);
}

async function signIn(token) {
  if (await page.locator('#who-name').count()) {
    await page.getByRole('button', { name: 'Sign out' }).click();
  }
  await page.waitForURL(/#\/signin$/);
  await page.getByLabel('Access token').fill(token);
  await page.getByRole('button', { name: 'Sign in' }).click();
  await page.waitForURL(/#\/subjects$/);
}

// Starts the selected protocol; resolves the run id, or null with the
// refusal the page shows.
async function startProtocol(name) {
  if ((await page.locator('#protocol').inputValue()) !== name) await page.locator('#protocol').selectOption(name);
  await page.locator('#start-run:not([disabled])').waitFor();
  await page.locator('#start-run').click();
  const status = page.locator('#run-form-status .msg');
  await status.filter({ hasText: /started|Cannot start|correct/ }).waitFor();
  const text = await status.textContent();
  const m = text.match(/Run (\d+) started/);
  return m ? { runId: Number(m[1]) } : { refusal: text };
}

try {
  const { context: c, page: p, external, consoleErrors } = await launch(server);
  context = c;
  page = p;
  const clinician = await makeUser(server, 'dr_chain', 'clinician');
  const analyst = await makeUser(server, 'an_chain', 'analyst');
  let subjectId;
  let sessionId;
  let setId;
  let set0;
  const freshRuns = [];

  await step('sign in as a clinician', async () => {
    await page.goto(`${server.url}/`);
    await page.waitForURL(/#\/signin$/);
    await page.getByLabel('Access token').fill(clinician.token);
    await page.keyboard.press('Enter');
    await page.waitForURL(/#\/subjects$/);
    assert.equal(await page.locator('#who-role').textContent(), 'clinician');
    await page.locator('#estop-state').filter({ hasText: 'Bench: idle' }).waitFor();
    await snap('signed-in');
  });

  await step('a new subject without body mass or shank length', async () => {
    await page.getByLabel('Pseudonymous code').fill('N01');
    await page.getByLabel('Age (years)').fill('41');
    await page.getByRole('button', { name: 'Create subject' }).click();
    await page.locator('#subject-form-status').filter({ hasText: 'Subject N01 created.' }).waitFor();
    await page.locator('#subjects-table').getByRole('link', { name: 'N01' }).click();
    await page.getByRole('heading', { name: 'Subject N01' }).waitFor();
    subjectId = Number(page.url().match(/subjects\/(\d+)/)[1]);
    const details = await page.locator('#subject-details').textContent();
    assert.match(details, /Body mass \(kg\)—/);
    assert.match(details, /Shank length \(cm\)—/);
    await snap('subject-new');
  });

  await step('correction: every invalid field at once, then body mass and shank length with a reason', async () => {
    await page.locator('#subject-edit-box summary').click();
    await page.locator('#subject-edit-weight_kg').fill('-72');
    await page.locator('#subject-edit-shank_length_cm').fill('43');
    await page.getByRole('button', { name: 'Save correction' }).click();
    // Both problems of one submit are shown together, before any request.
    await page.locator('#subject-edit-weight_kg-error').filter({ hasText: /must be 1–400 kg, got -72/ }).waitFor();
    await page.locator('#subject-edit-reason-error').filter({ hasText: /why/ }).waitFor();
    assert.equal(await page.locator('#subject-edit [aria-invalid=true]').count(), 2);
    await snap('subject-correction-invalid');
    await page.locator('#subject-edit-weight_kg').fill('72');
    await page.locator('#subject-edit-reason').fill('body mass and shank length measured at the first visit');
    await page.getByRole('button', { name: 'Save correction' }).click();
    await page.locator('#subject-edit-status').filter({ hasText: /Saved as revision 2/ }).waitFor();
    await page.locator('#subject-details').filter({ hasText: /Body mass \(kg\)72/ }).waitFor();
    assert.match(await page.locator('#subject-details').textContent(), /Shank length \(cm\)43/);
    const history = page.locator('#subject-revisions-table tbody tr');
    assert.equal(await history.count(), 2);
    assert.match(await history.nth(1).textContent(), /measured at the first visit/);
    assert.match(await history.nth(1).textContent(), /dr_chain/);
    const subject = await call(server, 'GET', `/subjects/${subjectId}`);
    assert.deepEqual([subject.body.revision, subject.body.details.weight_kg, subject.body.details.shank_length_cm], [2, 72, 43]);
    await page.locator('#subject-revisions').scrollIntoViewIfNeeded();
    await snap('subject-corrected');
  });

  await step('a session without threshold or max tolerated (nothing prefilled)', async () => {
    assert.equal(await page.locator('#f-threshold_ma').inputValue(), '');
    assert.equal(await page.locator('#f-max_tolerated_ma').inputValue(), '');
    await page.getByLabel('Accelerometer placement').fill('shank, 20 cm below the knee');
    await page.getByRole('button', { name: 'Open session' }).click();
    await page.locator('#run-form').waitFor();  // opening a session opens its page
    sessionId = Number(page.url().match(/sessions\/(\d+)/)[1]);
    assert.equal(await page.locator('#session-threshold').textContent(), '—');
    assert.equal(await page.locator('#session-max-tolerated').textContent(), '—');
    // Without recorded limits the tolerance test is what can run.
    assert.equal(await page.locator('#protocol').inputValue(), 'tolerance_test');
    // Labels in the clinician's words, the thesis section behind a help link.
    assert.doesNotMatch(await page.locator('#protocol-parameters').textContent(), /§/);
    assert.match(await page.locator('#protocol-help').getAttribute('title'), /§/);
    await snap('session-new');
  });

  await step('tolerance test, "the subject says stop": the current and torque live, the session shows the recorded values at once', async () => {
    const { runId } = await startProtocol('tolerance_test');
    assert.ok(runId, 'tolerance test refused');
    await page.locator('#live[data-state="running"]').waitFor();
    await page.locator('#runbar[data-state="running"]').waitFor();
    // The clinician stops when the subject has had enough: a clear torque
    // response, above this virtual subject's threshold.
    await page.waitForFunction(() => Number(document.querySelector('#live').dataset.torqueSwing || 0) >= 3, null, { timeout: 60000 });
    await snap('tolerance-running');
    // The live numbers: the current and the torque, to 0.1, large.
    assert.match(await page.locator('#live-ma').textContent(), /^\d+\.\d$/);
    assert.match(await page.locator('#live-nm').textContent(), /^-?\d+\.\d$/);
    // The subject's stop is the primary action, first; cancelling says it records nothing.
    const actions = await page.locator('#live .actions button').allTextContents();
    assert.deepEqual(actions, ['The subject says stop (record max tolerated)', 'Cancel (records nothing)']);
    assert.equal(await page.locator('#stop-run').getAttribute('class'), 'primary');
    assert.equal(await page.locator('#runbar-stop').textContent(), 'Subject says stop');
    assert.equal(await page.locator('#runbar-cancel').textContent(), 'Cancel (records nothing)');
    // The stimulation plot is drawn first, with the max tolerated line (none recorded yet here).
    assert.equal(await page.locator('#live figure').first().getAttribute('data-plot'), 'stimulation');
    await page.getByRole('button', { name: 'The subject says stop (record max tolerated)' }).click();
    await page.locator('#live[data-state="done"]').waitFor();
    await page.locator('#run-recorded').waitFor();
    const session = (await call(server, 'GET', `/sessions/${sessionId}`)).body;
    const { threshold_ma: thr, max_tolerated_ma: max } = session.details;
    assert.ok(Number.isFinite(thr) && Number.isFinite(max) && max > thr, JSON.stringify(session.details));
    const shown = (sel) => page.locator(sel).textContent().then(Number);
    assert.ok(Math.abs((await shown('#session-threshold')) - thr) < 0.01 * thr, 'threshold shown');
    assert.ok(Math.abs((await shown('#session-max-tolerated')) - max) < 0.01 * max, 'max tolerated shown');
    assert.match(await page.locator('#session-revisions-table').textContent(), new RegExp(`tolerance_test run ${runId}`));
    notes.push(`tolerance test: threshold ${thr} mA, max tolerated ${max} mA`);
    await snap('tolerance-recorded');
  });

  await step('rapid parameterisation while switching views: the run survives, the run bar shows throughout', async () => {
    const { runId, refusal } = await startProtocol('rapid_parameterisation');
    assert.ok(runId, `rapid refused: ${refusal}`);
    await page.locator('#live[data-state="running"]').waitFor();
    await page.getByRole('navigation').getByRole('link', { name: 'Subjects' }).click();
    await page.locator('#subjects-table').waitFor();
    await page.locator(`#runbar[data-run-id="${runId}"][data-state="running"]`).waitFor();
    const p0 = await page.locator('#runbar-progress').evaluate((e) => e.value);
    await page.waitForFunction((v) => document.querySelector('#runbar-progress').value > v, p0);
    await expectEstopVisible(page);
    await snap('rapid-on-subjects');
    await page.locator('#subjects-table').getByRole('link', { name: 'N01' }).click();
    await page.getByRole('heading', { name: 'Subject N01' }).waitFor();
    await page.locator(`#runbar[data-run-id="${runId}"]`).waitFor();
    await page.getByRole('navigation').getByRole('link', { name: 'Prediction' }).click();
    await page.locator(`#runbar[data-run-id="${runId}"]`).waitFor();
    await snap('rapid-on-prediction');
    // Back through the bar's link: the session follows the same run live.
    await page.locator('#runbar-session').click();
    await page.locator(`#live[data-run-id="${runId}"]`).waitFor();
    await page.locator('#live[data-state="done"]').waitFor({ timeout: 90000 });
    const run = (await call(server, 'GET', `/runs/${runId}`)).body;
    assert.equal(run.state, 'done', `rapid ended ${run.state}: ${run.reason}`);
    setId = run.parameter_set_id;
    assert.ok(setId, 'no parameter set from rapid');
    set0 = (await call(server, 'GET', `/parameter-sets/${setId}`)).body;
    // From the run's end to its set and its model check.
    await page.locator('#run-model-check').waitFor();
    await page.locator('#run-parameter-set').waitFor();
    await snap('rapid-done');
  });

  let gateRefusal = null;
  await step('prediction_random_binary and prediction_step runs (fresh trials)', async () => {
    for (const protocol of ['prediction_random_binary', 'prediction_step']) {
      const { runId, refusal } = await startProtocol(protocol);
      if (!runId) {
        // The model gate refused: the page must say so plainly.
        assert.match(refusal, /Cannot start: .{20,}/);
        gateRefusal = refusal;
        notes.push(`${protocol} refused by the model gate: ${refusal}`);
        await snap(`${protocol}-refused`);
        continue;
      }
      await page.locator(`#live[data-run-id="${runId}"][data-state="done"]`).waitFor({ timeout: 60000 });
      freshRuns.push(runId);
      await snap(`${protocol}-done`);
    }
    // The session lists its trials: plot one and download it as CSV.
    await page.locator('#trials-table').waitFor();
    await page.locator('#trials-table button[data-trial]').last().click();
    await page.locator('#trial-plot figure[data-plot="trial-angle"] canvas').waitFor();
    const [csv] = await Promise.all([page.waitForEvent('download'), page.locator('#trials-table button[data-csv]').last().click()]);
    assert.match(csv.suggestedFilename(), /\.csv$/);
    const [sto] = await Promise.all([page.waitForEvent('download'), page.locator('#trials-table button[data-sto]').last().click()]);
    assert.match(sto.suggestedFilename(), /\.sto$/);
    await page.locator('#trial-plot').scrollIntoViewIfNeeded();
    await snap('session-trials');
    // At 820 px the page never scrolls sideways and the trials table's last
    // column can be reached (the table scrolls inside the page).
    await page.setViewportSize({ width: 820, height: 1000 });
    // (plots follow the width once their resize observers ran)
    await page.waitForFunction(() => document.documentElement.scrollWidth <= window.innerWidth, null, { timeout: 5000 })
      .catch(async () => {
        const widest = await page.evaluate(() => [...document.querySelectorAll('main *')]
          .filter((e) => e.getBoundingClientRect().right > window.innerWidth + 1)
          .slice(-3).map((e) => `${e.tagName}#${e.id}.${e.className} right ${Math.round(e.getBoundingClientRect().right)}`));
        assert.fail(`the page scrolls sideways at 820 px: ${widest.join('; ')}`);
      });
    const lastCell = page.locator('#trials-table tbody tr').first().locator('td').last();
    await lastCell.scrollIntoViewIfNeeded();
    const box = await lastCell.boundingBox();
    assert.ok(box && box.x >= 0 && box.x + box.width <= 820 + 1, `last trials column out of reach at 820 px: ${JSON.stringify(box)}`);
    await page.setViewportSize({ width: 1280, height: 800 });
  });

  await step('tracking (adaptive): target and knee angle live, the error and τ_scale drawn, the figures at the end', async () => {
    await page.locator('#protocol').selectOption('tracking');
    await page.locator('#f-controller').selectOption({ label: 'adaptive' });
    await page.locator('#f-duration_s').fill('10');
    // This leg is weak (full recruitment holds it near 60°): the extended
    // end is left to its default, which the server fits to what the set
    // says the leg reaches (an explicit end past it is refused).
    const { runId, refusal } = await startProtocol('tracking');
    assert.ok(runId, `tracking refused: ${refusal}`);
    await page.locator(`#live[data-run-id="${runId}"]`).waitFor();
    await page.locator('figure[data-plot="tau_scale"] canvas').waitFor();
    await page.locator('figure[data-plot="error"] canvas').waitFor();
    await page.locator(`#live[data-run-id="${runId}"][data-state="done"]`).waitFor({ timeout: 60000 });
    const text = await page.locator('#run-tracking').textContent();
    const rms = Number(text.match(/Tracking error ([0-9.]+)° RMS/)[1]);
    assert.ok(rms > 0 && rms < 10, text);
    assert.ok(Number.isFinite(Number(await page.locator('#live').getAttribute('data-last-error'))));
    const run = (await call(server, 'GET', `/runs/${runId}`)).body;
    assert.equal(run.parameters.controller, 2);
    assert.ok(run.parameters.lo_deg > 30, `the default target fitted to the weak leg: lo_deg ${run.parameters.lo_deg}`);
    // The form keeps what the clinician chose when the run ends (it used to
    // return to the defaults: Start again would run another experiment).
    assert.equal((await page.locator('#f-controller option:checked').textContent()).trim(), 'adaptive');
    assert.equal(await page.locator('#f-duration_s').inputValue(), '10');
    notes.push(`tracking (adaptive, 10 s sine ${run.parameters.lo_deg}–80°): ${text}`);
    await page.locator('#live').scrollIntoViewIfNeeded();
    await snap('tracking-done');
  });

  await step('tracking an uploaded trajectory (CSV t_s, angle_deg)', async () => {
    await page.locator('#protocol').selectOption('tracking');
    await page.locator('#f-controller').selectOption({ label: 'inverse model' });
    await page.locator('#f-target').selectOption({ label: 'uploaded' });
    const rows = ['t_s,angle_deg'];
    for (let i = 0; i <= 60; i++) rows.push(`${(i * 0.1).toFixed(1)},${(72 + 6 * Math.sin(2 * Math.PI * 0.2 * i * 0.1)).toFixed(2)}`);
    await page.locator('#f-target_file').setInputFiles({ name: 'target.csv', mimeType: 'text/csv', buffer: Buffer.from(rows.join('\n')) });
    const { runId, refusal } = await startProtocol('tracking');
    assert.ok(runId, `uploaded tracking refused: ${refusal}`);
    await page.locator(`#live[data-run-id="${runId}"][data-state="done"]`).waitFor({ timeout: 60000 });
    const run = (await call(server, 'GET', `/runs/${runId}`)).body;
    assert.equal(run.parameters.target, 3);
    assert.ok(run.values.tracking_rms_deg < 10, JSON.stringify(run.values));
    notes.push(`tracking an uploaded 6 s trajectory: RMS ${run.values.tracking_rms_deg.toFixed(2)}°`);
  });

  await step('runs are records: each with its outcome and parameters, and "run again" fills the form', async () => {
    const runs = (await call(server, 'GET', `/sessions/${sessionId}/runs`)).body.items;
    const tolerance = runs.find((r) => r.protocol === 'tolerance_test' && r.state === 'done');
    const rapid = runs.find((r) => r.protocol === 'rapid_parameterisation' && r.parameter_set_id);
    const row = (run) => page.locator('#runs-table tbody tr', { hasText: `Run ${run.run_id}` }).first();
    assert.match(await row(tolerance).textContent(), /threshold \d+\.\d mA, max tolerated \d+\.\d mA/);
    assert.match(await row(rapid).textContent(), new RegExp(`Parameter set ${rapid.parameter_set_id}`));
    assert.match(await row(rapid).textContent(), /\d+ parameters/);
    await row(tolerance).getByRole('button', { name: 'Run again with these' }).click();
    assert.equal(await page.locator('#protocol').inputValue(), 'tolerance_test');
    for (const [name, value] of Object.entries(tolerance.parameters)) {
      const input = page.locator(`#run-form [name="${name}"]`);
      if (await input.count()) assert.equal(Number(await input.inputValue()), value, name);
    }
    await page.locator('#run-form-status').filter({ hasText: `run ${tolerance.run_id}'s parameters` }).waitFor();
    // A run opens as a page of its own: its parameters in words and units,
    // its outcome, its trials, and the way back to run it again.
    await row(rapid).getByRole('link', { name: `Run ${rapid.run_id}` }).click();
    await page.locator('#run-summary').waitFor();
    assert.match(await page.locator('h1').textContent(), new RegExp(`Run ${rapid.run_id}: `));
    assert.match(await page.locator('#run-summary').textContent(), new RegExp(`Parameter set ${rapid.parameter_set_id}`));
    const paramText = await page.locator('#run-parameters-table').textContent();
    assert.doesNotMatch(paramText, /_ma|_deg|_s\b/, 'internal parameter names on the run page');
    assert.match(paramText, /\(mA\)/);
    const runTrials = page.locator('#run-trials-table tbody tr');
    assert.equal(await runTrials.count(), rapid.trial_ids.length);
    await snap('run-page');
    await runTrials.first().getByRole('link', { name: /^Plot trial/ }).click();
    await page.locator(`#trial-plot[data-trial-id="${rapid.trial_ids[0]}"]`).waitFor();
    await page.goto(`${server.url}/#/runs/${tolerance.run_id}`);
    await page.locator('#run-again-link').click();
    await page.locator('#run-form-status').filter({ hasText: `run ${tolerance.run_id}'s parameters` }).waitFor();
    assert.equal(await page.locator('#protocol').inputValue(), 'tolerance_test');
  });

  await step('daily check: today\'s leg against its set, what moved shown', async () => {
    const { runId, refusal } = await startProtocol('daily_check');
    assert.ok(runId, `daily check refused: ${refusal}`);
    await page.locator(`#live[data-run-id="${runId}"][data-state="done"]`).waitFor({ timeout: 60000 });
    const text = await page.locator('#run-daily-check').textContent();
    assert.match(text, /Daily check: (no change, the approved set stands|the recruitment moved, the set was re-fitted|a full rapid parameterisation is due)/);
    // In words and units: no internal names in the table.
    assert.doesNotMatch(await page.locator('#daily-check-table').textContent(), /irc_threshold_ma|full_scale|irc_slope/);
    assert.match(await page.locator('#daily-check-table').textContent(), /\d\.\d mA/);
    const run = (await call(server, 'GET', `/runs/${runId}`)).body;
    assert.equal(run.result.drifts.length, 4);
    notes.push(`daily check on the same leg: ${run.result.verdict} (${run.result.summary})`);
    await page.locator('#run-daily-check').scrollIntoViewIfNeeded();
    await snap('daily-check-done');
  });

  await step('prediction page (analyst): the new set on trials it was not fitted on, with error figures', async () => {
    await signIn(analyst.token);
    await page.goto(`${server.url}/#/predict/${setId}`);
    await page.locator('#predict-set').waitFor();
    assert.equal(await page.locator('#predict-set').inputValue(), String(setId));
    const set = (await call(server, 'GET', `/parameter-sets/${setId}`)).body;
    // The options are there once the set's trials are loaded (not the "Loading…" placeholder).
    await page.locator('#predict-trial option[data-training]').first().waitFor({ state: 'attached' });
    const chosen = Number(await page.locator('#predict-trial').inputValue());
    // Training trials are marked; the default is not one of them.
    const trainingOptions = await page.locator('#predict-trial option[data-training="1"]').allTextContents();
    assert.ok(trainingOptions.length >= 1 && trainingOptions.every((t) => t.includes('(training)')), String(trainingOptions));
    if (freshRuns.length) {
      assert.ok(!set.trial_ids.includes(chosen), `default trial ${chosen} is a training trial`);
      const trial = (await call(server, 'GET', `/sessions/${sessionId}/trials`)).body.items.find((t) => t.id === chosen);
      assert.ok(trial && freshRuns.includes(trial.run_id), `default trial ${chosen} is not from the prediction runs`);
      assert.equal(await page.locator('#predict-training-note').isHidden(), true);
    } else {
      // Nothing fresh was recorded (gate refusal): choosing a training trial says so.
      await page.locator('#predict-trial').selectOption(String(set.trial_ids[set.trial_ids.length - 1]));
      await page.locator('#predict-training-note').waitFor();
    }
    await page.getByRole('button', { name: 'Run prediction' }).click();
    await page.locator('#error-table').waitFor({ timeout: 60000 });
    const rms = Number((await page.locator('#error-table tbody tr').first().locator('td').textContent()).trim());
    assert.ok(rms > 0 && Number.isFinite(rms), `E_RMS ${rms}`);
    notes.push(`prediction of set ${setId} on trial ${chosen}: E_RMS ${rms} deg`);
    // The rapid set records where its curves were identified; the page says how much is extrapolated.
    assert.match(await page.locator('#predict-extrapolated').textContent(), /% of the predicted samples lie outside/);
    await page.locator('figure[data-plot="prediction"] canvas').waitFor();
    assert.match(await page.locator('#predict-title').textContent(), /Predicted vs measured knee angle/);
    await snap('prediction');
    // An isometric trial is torque against torque, in N·m (it was plotted on
    // a knee-angle chart).
    const iso = page.locator('#predict-trial option', { hasText: /isometric/ }).first();
    await iso.waitFor({ state: 'attached' });
    await page.locator('#predict-trial').selectOption(await iso.getAttribute('value'));
    await page.getByRole('button', { name: 'Run prediction' }).click();
    await page.locator('#predict-title', { hasText: 'torque' }).waitFor({ timeout: 60000 });
    assert.match(await page.locator('#error-table thead').textContent(), /Value \(N[.·]m\)/);
    await snap('prediction-isometric');
    await signIn(clinician.token);
    // The clinician's model check: the Prediction page runs for a clinician too.
    await page.goto(`${server.url}/#/predict/${setId}`);
    await page.locator('#predict-trial option[data-training]').first().waitFor({ state: 'attached' });
    await page.getByRole('button', { name: 'Run prediction' }).click();
    await page.locator('#error-table').waitFor({ timeout: 60000 });
  });

  await step('the model check: the new set on the leg\'s fresh trials, a verdict in words, errors in each trial\'s unit', async () => {
    await page.goto(`${server.url}/#/sessions/${sessionId}`);
    await page.locator('#runs-table').waitFor();
    // From the run that made the set to its model check (it runs at once).
    await page.locator('#runs-table a', { hasText: 'model check' }).first().click();
    await page.locator('#model-check-result').waitFor({ timeout: 60000 });
    const verdict = await page.locator('#model-check-result').getAttribute('data-verdict');
    const text = await page.locator('#model-check-verdict').textContent();
    assert.match(text, /^(Good for control|Use with care|Do not use to drive stimulation|Not checked yet)/);
    // The same check through the API: the same trials, verdict and errors.
    const job = await call(server, 'POST', `/parameter-sets/${setId}/model-check`, undefined, clinician.token);
    assert.equal(job.status, 202, JSON.stringify(job.body));
    let done = job.body;
    while (done.state !== 'done' && done.state !== 'failed') done = (await call(server, 'GET', `/jobs/${done.id}`, undefined, clinician.token)).body;
    assert.equal(done.state, 'done', JSON.stringify(done.error));
    const check = done.result;
    assert.equal(check.verdict, verdict);
    const rows = page.locator('#model-check-table tbody tr');
    assert.equal(await rows.count(), check.trials.length);
    for (let i = 0; i < check.trials.length; i++) {
      const t = check.trials[i];
      const cells = await rows.nth(i).locator('th, td').allTextContents();
      assert.match(cells[0], new RegExp(`^${t.trial_id}:`));
      const shown = t.unit === 'deg' ? `${t.e_rms.toFixed(1)}°` : `${t.e_rms.toFixed(1)} N·m`;
      assert.ok(cells[2].startsWith(shown), `${cells[2]} vs ${shown}`);
      assert.ok(!set0.trial_ids.includes(t.trial_id), `training trial ${t.trial_id} in the check`);
    }
    if (freshRuns.length) assert.ok(check.trials.length >= 2, 'the fresh prediction trials are checked');
    notes.push(`model check of set ${setId}: ${check.verdict}; ` +
      check.trials.map((t) => `trial ${t.trial_id} ${t.quantity} ${t.e_rms?.toFixed(2)} ${t.unit} → ${t.verdict}`).join('; '));
    // The fit's warnings in a clinician's words on the set's page.
    if (set0.parameters.provenance.warnings.length) {
      assert.doesNotMatch(await page.locator('#fit-notes > ul').textContent(), /non-positive|rank \d+ of/);
    }
    await page.locator('#model-check').scrollIntoViewIfNeeded();
    await snap('model-check');

    // An analyst's re-identification is a candidate: the clinician checks it
    // and approves it with the check's verdict beside the approval.
    const fit = await call(server, 'POST', '/identifications', { session_id: sessionId, method: 'rapid' }, analyst.token);
    assert.equal(fit.status, 202, JSON.stringify(fit.body));
    let fitJob = fit.body;
    while (fitJob.state !== 'done' && fitJob.state !== 'failed') fitJob = (await call(server, 'GET', `/jobs/${fitJob.id}`, undefined, analyst.token)).body;
    assert.equal(fitJob.state, 'done', JSON.stringify(fitJob.error));
    const candidate = fitJob.result.parameter_sets[0].id;
    assert.equal((await call(server, 'GET', `/parameter-sets/${candidate}`)).body.approved, false);
    await page.goto(`${server.url}/#/parameter-sets/${candidate}/check`);
    await page.locator('#model-check-result').waitFor({ timeout: 60000 });
    assert.match(await page.locator('#approval-status').textContent(), /A candidate, never approved/);
    assert.match(await page.locator('#approve-note').inputValue(), /^Model check: /);
    await page.getByRole('button', { name: 'Approve for this leg' }).click();
    await page.locator('#approval-status').filter({ hasText: "The leg's approved set" }).waitFor();
    const approved = (await call(server, 'GET', `/parameter-sets/${candidate}`)).body;
    assert.equal(approved.approved, true);
    assert.match(approved.approval.note, /^Model check: /);
    assert.equal(approved.approval.approved_by, 'dr_chain');
    notes.push(`candidate set ${candidate} approved with: ${approved.approval.note}`);
  });

  await step('closing the tab during a run asks first; a reload re-attaches to the run', async () => {
    await page.goto(`${server.url}/#/sessions/${sessionId}`);
    await page.locator('#run-form').waitFor();
    await page.locator('#protocol').selectOption('active_random_binary');
    await fillParameter(page, 'duration_s', '120'); // long enough for the reload and the e-stop below
    const { runId } = await startProtocol('active_random_binary');
    assert.ok(runId);
    await page.locator('#live[data-state="running"]').waitFor();
    // A reload asks (beforeunload); accepting it reloads, and the page takes
    // the heartbeat over again because the server says this user controls it.
    const asked = page.waitForEvent('dialog').then(async (dialog) => {
      assert.equal(dialog.type(), 'beforeunload');
      await dialog.accept();
    });
    await page.evaluate(() => location.reload()).catch(() => {});
    await asked;
    await page.locator(`#runbar[data-run-id="${runId}"][data-state="running"]`).waitFor();
    await page.locator(`#live[data-run-id="${runId}"]`).waitFor();
    const p0 = await page.locator('#runbar-progress').evaluate((e) => e.value);
    await page.waitForFunction((v) => document.querySelector('#runbar-progress').value > v + 0.02, p0);
    assert.equal((await call(server, 'GET', `/runs/${runId}`)).body.state, 'running');
    await snap('reattached');
  });

  await step('e-stop during a run: latch banner, every start disabled, confirmed clear', async () => {
    await page.locator('#estop').click();
    await page.locator('#latch').filter({ hasText: 'E-STOP LATCHED' }).waitFor();
    await page.locator('#live[data-state="aborted"]').waitFor();
    await page.locator('#start-hint').filter({ hasText: 'e-stop is latched' }).waitFor();
    assert.equal(await page.locator('#start-run').isDisabled(), true);
    // The latch is the most visible thing: full width, right under the header.
    const latch = await page.locator('#latch').boundingBox();
    assert.ok(latch.width >= page.viewportSize().width - 20, `latch ${latch.width} px wide`);
    await snap('estop-latched');
    await page.locator('#estop-clear').click();
    await page.locator('#estop-dialog').waitFor();
    assert.equal(await page.locator('#estop-confirm').isDisabled(), true);
    await snap('estop-clear-dialog');
    await page.locator('#estop-confirm-check').check();
    await page.locator('#estop-confirm').click();
    await page.locator('#estop-state').filter({ hasText: 'Bench: idle' }).waitFor();
    assert.equal((await call(server, 'GET', '/bench')).body.state.estopped, false);
    await page.locator('#start-run:not([disabled])').waitFor();
    await snap('estop-cleared');
  });

  await step('the header never shifts: the E-STOP button keeps its place at 1280 and 820 px', async () => {
    for (const width of [1280, 820]) {
      await page.setViewportSize({ width, height: 900 });
      const idle = await page.locator('#estop').boundingBox();
      const header = await page.locator('.top').boundingBox();
      await page.locator('#protocol').selectOption('active_random_binary');
      const { runId } = await startProtocol('active_random_binary');
      await page.locator(`#runbar[data-run-id="${runId}"][data-state="running"]`).waitFor();
      const busy = await page.locator('#estop').boundingBox();
      assert.deepEqual([busy.x, busy.y, busy.width], [idle.x, idle.y, idle.width], `E-STOP moved at ${width} px`);
      assert.equal((await page.locator('.top').boundingBox()).height, header.height, `header grew at ${width} px`);
      // The run's progress stays in view.
      const bar = await page.locator('#runbar-progress').boundingBox();
      assert.ok(bar && bar.y >= header.height - 1 && bar.y + bar.height <= 900, `run progress hidden at ${width} px`);
      await page.locator('#runbar-cancel').click();
      await page.locator('#live[data-state="aborted"]').waitFor();
      await page.locator('#start-run:not([disabled])').waitFor();
    }
    await page.setViewportSize({ width: 1280, height: 800 });
  });

  await step('admin: a user and a token issued from the page (shown once), then revoked', async () => {
    await signIn(server.token);
    await page.getByRole('navigation').getByRole('link', { name: 'Users and tokens' }).click();
    await page.locator('#users-table').waitFor();
    await page.locator('#user-name').fill('dr_new');
    await page.locator('#user-role').selectOption('clinician');
    await page.getByRole('button', { name: 'Add user' }).click();
    await page.locator('#admin-status').filter({ hasText: 'User dr_new (clinician) added' }).waitFor();
    await page.locator('#token-label').fill('ward PC');
    await page.getByRole('button', { name: 'Issue token' }).click();
    const secret = await page.locator('#token-secret-value').inputValue();
    assert.ok(secret.length >= 20, 'no token shown');
    const me = await call(server, 'GET', '/me', undefined, secret);
    assert.deepEqual([me.status, me.body.name, me.body.role], [200, 'dr_new', 'clinician']);
    await snap('admin-token-issued');
    // Shown once: the list has its metadata, never the secret.
    assert.doesNotMatch(await page.locator('#tokens-table').textContent(), new RegExp(secret));
    const row = page.locator('#tokens-table tbody tr', { hasText: 'ward PC' });
    await row.getByRole('button', { name: /^Revoke token/ }).click();
    await page.locator('#admin-status').filter({ hasText: /Token \d+ of dr_new is revoked/ }).waitFor();
    assert.equal((await call(server, 'GET', '/me', undefined, secret)).status, 401);
  });

  assert.deepEqual(external, [], 'the page requested something from elsewhere');
  const seriousOrCritical = axe.reduce((n, a) => n + a.serious_or_critical, 0);
  notes.push(`axe-core on ${axe.length} pages: ${seriousOrCritical} serious or critical violations`);
  saveWalk(artefacts, { axe });
  assert.equal(seriousOrCritical, 0, `axe: ${JSON.stringify(axe.filter((a) => a.serious_or_critical))}`);
  assert.deepEqual(consoleErrors, [], 'uncaught errors in the page');
  if (gateRefusal) console.log('NOTE: the model gate refused a prediction protocol after a default rapid run');
} catch (e) {
  error = e;
}
await finish({ error, page, context, server, artefacts, started, notes });
