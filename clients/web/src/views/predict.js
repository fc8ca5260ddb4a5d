// Prediction: simulate a parameter set on a stored trial's stimulation and
// show predicted vs measured knee angle with the error figures
// (E_RMS, E_ABS, E_AVE, normalised RMS; §6.2).
import { api, listAll, waitForJob } from '../api.js';
import { fmt, h, say, table } from '../dom.js';
import { makePlot } from '../plot.js';
import { legSide } from './subjects.js';

export async function predictionView(ctx, presetId) {
  const mayPredict = ['clinician', 'analyst', 'admin'].includes(ctx.user.role);
  const sets = await listAll('/parameter-sets');
  const subjects = new Map();
  await Promise.all([...new Set(sets.map((s) => s.subject_id))].map(async (id) => {
    subjects.set(id, await api('GET', `/subjects/${id}`));
  }));
  const status = h('div', { id: 'predict-status' });
  const result = h('div', { id: 'predict-result' });
  const trainingNote = h('p', { id: 'predict-training-note', class: 'msg msg-info', hidden: true },
    'This trial was used to fit the parameter set (training): its errors measure the fit, not how well the model predicts.');
  // Newest first, so the set just made is the default.
  sets.sort((a, b) => b.id - a.id);
  const setSelect = h('select', { id: 'predict-set', name: 'parameter_set_id' },
    sets.map((s) => {
      const subject = subjects.get(s.subject_id);
      return h('option', { value: s.id, selected: s.id === presetId },
        `Parameter set ${s.id} — ${subject ? subject.code : `subject ${s.subject_id}`}, ${legSide(subject, s.leg_id)} leg, ` +
        `${s.created_at_utc.slice(0, 10)}`);
    }));
  const trialSelect = h('select', { id: 'predict-trial', name: 'trial_id' });
  let training = new Set();
  // How each trial kind ranks as a default (fetched once per page): trials
  // recorded to validate a model first, then the other free-swing trials.
  let kindRank = null;
  const showTrainingNote = () => { trainingNote.hidden = !training.has(Number(trialSelect.value)); };
  trialSelect.addEventListener('change', showTrainingNote);

  async function loadTrials() {
    const summary = sets.find((s) => String(s.id) === setSelect.value);
    if (!summary) return;
    trialSelect.replaceChildren(h('option', {}, 'Loading…'));
    try {
      // Honest validation by default: the trials the set was NOT fitted on
      // come first; its training trials are marked as such.
      kindRank ??= api('GET', '/trial-kinds').then((kinds) =>
        new Map(kinds.items.map((k) => [k.name, 2 * Number(k.validation) + Number(k.free_swing)])))
        .catch((e) => { kindRank = null; throw e; });  // asked again next time
      const [set, sessions, rank] = await Promise.all([api('GET', `/parameter-sets/${summary.id}`),
        listAll(`/subjects/${summary.subject_id}/sessions`), kindRank]);
      training = new Set(set.trial_ids || []);
      const legSessions = sessions.filter((s) => s.leg_id === undefined || s.leg_id === summary.leg_id);
      const trials = (await Promise.all(legSessions.map((s) => listAll(`/sessions/${s.id}/trials`)))).flat();
      const score = (t) => rank.get(t.kind) || 0;
      trials.sort((a, b) => score(b) - score(a) || b.id - a.id);
      const option = (t) => h('option', { value: t.id, dataset: { training: training.has(t.id) ? '1' : '0' } },
        `Trial ${t.id}: ${t.name || t.kind || '—'} (session ${t.session_id})${training.has(t.id) ? ' (training)' : ''}`);
      const fresh = trials.filter((t) => !training.has(t.id));
      const used = trials.filter((t) => training.has(t.id));
      trialSelect.replaceChildren(
        fresh.length ? h('optgroup', { label: 'Not used for fitting (validation)' }, fresh.map(option)) : '',
        used.length ? h('optgroup', { label: 'Used to fit this set (training)' }, used.map(option)) : '');
      if (!trials.length) trialSelect.replaceChildren(h('option', { value: '' }, 'No stored trials for this leg'));
      else if (!fresh.length) say(status, 'info', 'Every stored trial of this leg was used to fit the set: record a prediction protocol for an honest check.');
      else say(status, '', '');
      showTrainingNote();
    } catch (e) {
      say(status, 'error', e.message);
    }
  }
  setSelect.addEventListener('change', loadTrials);

  const form = h('form', { id: 'predict-form', novalidate: true, onsubmit: async (event) => {
    event.preventDefault();
    if (!trialSelect.value) {
      say(status, 'error', 'Choose a stored trial.');
      return;
    }
    const button = form.querySelector('button[type=submit]');
    button.disabled = true;
    say(status, 'info', 'Running the prediction…');
    result.replaceChildren();
    try {
      const job = await api('POST', '/predictions', { parameter_set_id: Number(setSelect.value), trial_id: Number(trialSelect.value) });
      const r = await waitForJob(job);
      const trial = await api('GET', `/trials/${r.trial_id}`);
      showResult(r, trial);
      say(status, 'ok', `Prediction ${r.prediction_id} done.`);
    } catch (e) {
      say(status, 'error', `Prediction failed: ${e.message}`);
    } finally {
      button.disabled = false;
    }
  } },
  h('div', { class: 'grid-form' },
    h('div', { class: 'field' }, h('label', { for: 'predict-set' }, 'Parameter set'), setSelect),
    h('div', { class: 'field' }, h('label', { for: 'predict-trial' }, 'Measured trial (its stimulation is replayed)'), trialSelect)),
  trainingNote,
  h('div', { class: 'actions' }, h('button', { type: 'submit', class: 'primary', disabled: !mayPredict }, 'Run prediction'),
    mayPredict ? '' : h('small', {}, ' Predictions need the clinician, analyst or admin role.')));

  function showResult(r, trial) {
    const channel = (name) => (trial.channels.find((c) => c.name === name) || { values: [] }).values;
    // The quantity the errors are about, in its own unit: the knee angle of
    // a free-swing trial, the torque of an isometric one.
    const compared = r.errors.channel || 'angle_deg';
    const torque = compared === 'torque_nm';
    const what = torque ? 'torque' : 'knee angle';
    const unit = r.errors.unit || (torque ? 'N·m' : 'deg');
    const measured = channel(compared);
    const measuredT = channel('t_s');
    const predicted = r.columns[compared] || r.columns.angle_deg;
    const t = r.columns.t_s;
    // Align on the prediction's time base (same sample rate, same start).
    const m = t.map((_, i) => (i < measured.length ? measured[i] : null));
    const e = r.errors;
    const plotBox = h('div', { class: 'plot-cell', id: 'predict-plot' });
    const errorBox = h('div', { class: 'plot-cell' });
    result.replaceChildren(
      h('h2', { id: 'predict-title' }, `Predicted vs measured ${what} — trial ${r.trial_id}${training.has(r.trial_id) ? ' (training)' : ''}`),
      table(['Error figure', `Value (${e.unit})`], [
        ['E_RMS', fmt(e.e_rms, 4)], ['E_ABS (mean absolute)', fmt(e.e_abs, 4)], ['E_AVE (mean)', fmt(e.e_ave, 4)],
        ['largest absolute', fmt(e.max_abs, 4)], ['normalised RMS', fmt(e.normalised_rms, 4)], ['samples', fmt(e.samples)]],
      { id: 'error-table', class: 'kv' }),
      r.share_outside_identified_ranges == null ? ''
        : h('p', { id: 'predict-extrapolated', class: 'msg msg-info' },
          `${fmt(100 * r.share_outside_identified_ranges, 3)} % of the predicted samples lie outside the ranges the set's curves were identified over (there the model extrapolates).`),
      plotBox, errorBox);
    const c1 = makePlot(plotBox, [{ label: 'measured' }, { label: 'predicted', dash: [6, 3] }], [t, m, predicted],
      { title: what[0].toUpperCase() + what.slice(1), xLabel: 'time (s)', yLabel: unit, height: 260, id: 'prediction' });
    const c2 = makePlot(errorBox, [{ label: 'predicted − measured' }], [t, t.map((_, i) => (m[i] === null ? null : predicted[i] - m[i]))],
      { title: 'Prediction error', xLabel: 'time (s)', yLabel: unit, height: 160, id: 'prediction-error' });
    ctx.onLeave(() => { c1.disconnect(); c2.disconnect(); });
    result.dataset.samples = String(measuredT.length);
  }

  ctx.main.replaceChildren(h('h1', {}, 'Prediction'),
    h('p', {}, 'Simulate the model of a parameter set on a stored trial\'s stimulation and compare with what was measured: the knee angle of a free-swing trial, the torque of an isometric one.'),
    sets.length ? form : h('p', {}, 'No parameter sets yet.'), status, result);
  if (sets.length) await loadTrials();
}
