// A session: its details (correctable, with the revision history), start a
// protocol (parameters labelled and prefilled by the server for this
// session, advanced ones collapsed), follow a run live (progress with ETA,
// knee angle, torque and stimulation from the event stream), the session's
// runs and its recorded trials (plot, CSV / .sto download).
// The run's heartbeat belongs to the app (ctx.runs), not to this view.
import { api, download, listAll } from '../api.js';
import { clearErrors, field, fmt, fmtDeg, fmtDuration, fmtFixed, fmtMa, fmtNm, h, message, say, showFieldError, showFieldErrors, table } from '../dom.js';
import { makePlot } from '../plot.js';
import { isFinal, progressOf } from '../runs.js';
import { streamEvents } from '../sse.js';
import { numberProblem, SESSION_LIMITS } from '../checks.js';
import { correctionForm, revisionHistory } from './corrections.js';
import { exchangeSection } from './exchange.js';
import { DAILY_DRIFT, DAILY_VERDICT, parameterRows, runOutcome } from './outcome.js';

// A live number to 0.1 of its unit (mA, N·m), or a dash.
const fmt1 = (x) => fmtFixed(x, 1);

const WINDOW_S = 30; // bench seconds shown in the live plots

export const SESSION_FIELDS = [
  { name: 'date', label: 'Date (YYYY-MM-DD)', type: 'text' },
  { name: 'threshold_ma', label: 'Stimulation threshold (mA)', type: 'number', ...SESSION_LIMITS.threshold_ma },
  { name: 'max_tolerated_ma', label: 'Max tolerated (mA)', type: 'number', ...SESSION_LIMITS.max_tolerated_ma },
  { name: 'accelerometer_placement', label: 'Accelerometer placement', type: 'text' },
  { name: 'notes', label: 'Notes', type: 'textarea' },
];
const SESSION_LABELS = Object.fromEntries(SESSION_FIELDS.map((f) => [f.name, f.label]));

const utc = (iso) => (iso || '').slice(0, 19).replace('T', ' ');
const unitText = (unit) => (unit === '1' ? '' : ` (${unit})`);

/// Client-side checks of a protocol form from the parameter metadata: every
/// problem at once ([{field, message}]); the server checks again.
export function checkParameters(protocol, valueOf) {
  const problems = [];
  for (const p of protocol.parameters) {
    const message = numberProblem(p, String(valueOf(p.name)).trim());
    if (message) problems.push({ field: p.name, message });
  }
  return problems;
}

export async function sessionView(ctx, sessionId, { trialId = null, againRunId = null } = {}) {
  let [session, catalog, bench] = await Promise.all([
    api('GET', `/sessions/${sessionId}`), api('GET', `/protocols?session_id=${sessionId}`), api('GET', '/bench')]);
  const subject = await api('GET', `/subjects/${session.subject_id}`);
  let protocols = catalog.protocols;
  // A protocol's description (GET /protocols), {} for a name the catalogue lacks.
  const describedAs = (name) => protocols.find((p) => p.name === name) || {};
  const rate_hz = bench.limits.sample_rate_hz;
  const mayRun = ctx.user.role === 'clinician' || ctx.user.role === 'admin';
  const sessionPath = `/sessions/${sessionId}`;

  // --- details, correction, revisions ---------------------------------------------
  const detailsSlot = h('div', { id: 'session-details-box' });
  const editForm = correctionForm({ id: 'session-edit', path: sessionPath, fields: SESSION_FIELDS, mayEdit: mayRun,
    current: () => ({ ...session.details, date: session.date }), onSaved: async () => refreshSession() });
  async function renderDetails() {
    const d = session.details;
    detailsSlot.replaceChildren(
      table(['Field', 'Value'], [['Threshold, tolerance test (mA)', h('span', { id: 'session-threshold' }, fmtFixed(d.threshold_ma, 1))],
        ['Max tolerated (mA)', h('span', { id: 'session-max-tolerated' }, fmtFixed(d.max_tolerated_ma, 1))],
        ['Accelerometer placement', d.accelerometer_placement || '—'], ['Notes', d.notes || '—'],
        ['Revision', String(session.revision ?? 1)]],
      { class: 'kv', id: 'session-details' }),
      h('p', { class: 'help', id: 'threshold-explained' }, 'Two thresholds describe one leg: the tolerance test\'s is the current at which the ' +
        'first clear torque response was seen in this session; a parameter set\'s recruitment threshold is where its fitted ' +
        'recruitment curve reaches 2 % of full recruitment. They measure different things and usually differ by a few mA; ' +
        'stimulation defaults use this session\'s values.'),
      editForm,
      await revisionHistory(sessionPath, SESSION_LABELS, 'session-revisions').catch((e) => message('error', `Revision history unavailable: ${e.message}`)));
  }
  async function refreshSession() {
    [session, catalog] = await Promise.all([api('GET', sessionPath), api('GET', `/protocols?session_id=${sessionId}`)]);
    protocols = catalog.protocols;
    editForm.refresh();
    await renderDetails();
    // The form is drawn again with the session's new defaults (a tolerance
    // test changes them), but what the clinician typed or chose stays: a
    // form never changes it behind their back.
    const typed = {};
    const before = {};
    for (const el of paramSlot.querySelectorAll('input[data-prefilled], select[data-prefilled]')) {
      before[el.name] = el.dataset.prefilled;
      if (el.value !== el.dataset.prefilled) typed[el.name] = el.value;
    }
    renderParameters();
    const updated = [];
    for (const el of paramSlot.querySelectorAll('input[data-prefilled], select[data-prefilled]')) {
      if (el.name in typed) {
        el.value = typed[el.name];
      } else if (el.name in before && before[el.name] !== el.dataset.prefilled) {
        updated.push(el.labels && el.labels[0] ? el.labels[0].textContent : el.name);
      }
    }
    if (updated.length) {
      say(formStatus, 'info', `Defaults updated from the session: ${updated.join(', ')}.`);
    }
  }

  // --- runs and trials -----------------------------------------------------------------
  const runsSlot = h('div', { id: 'run-list' });
  async function loadRuns() {
    const runs = await listAll(`/sessions/${sessionId}/runs`);
    // Runs are records: what each ran with and what it gave; running one
    // again with its parameters is an explicit choice.
    const parametersOf = (r) => {
      const rows = parameterRows(protocols.find((p) => p.name === r.protocol), r.parameters);
      if (!rows.length) return '—';
      return h('details', { class: 'run-parameters' }, h('summary', {}, `${rows.length} parameters`),
        rows.map(([label, v]) => `${label}: ${v}`).join('; '));
    };
    const again = (r) => (mayRun && protocols.some((p) => p.name === r.protocol)
      ? h('button', { type: 'button', class: 'small', 'data-run-again': String(r.run_id), onclick: () => runAgain(r) }, 'Run again with these')
      : '');
    runsSlot.replaceChildren(runs.length
      ? table(['Run', 'Protocol', 'State', 'Created (UTC)', 'Outcome', 'Parameters', 'Reason', ''], runs.map((r) => [
        h('a', { href: `#/runs/${r.run_id}` }, `Run ${r.run_id}`), r.protocol, r.state, utc(r.created_at_utc), runOutcome(r), parametersOf(r), r.reason || '—', again(r)]),
      { id: 'runs-table' })
      : h('p', {}, 'No runs yet.'));
  }
  // The form filled with a past run's parameters, for the clinician to check
  // and start (nothing starts by itself).
  function runAgain(r) {
    select.value = r.protocol;
    renderParameters();
    for (const [name, value] of Object.entries(r.parameters || {})) {
      const el = form.elements[name];
      if (el && typeof value !== 'object') el.value = String(value);
    }
    say(formStatus, 'info', `The form holds run ${r.run_id}'s parameters: check them, then start.`);
    form.scrollIntoView({ block: 'start' });
  }

  const trialsSlot = h('div', { id: 'trial-list' });
  const trialPlot = h('div', { id: 'trial-plot', class: 'plots' });
  const trialStatus = h('div', { id: 'trial-status' });
  let trialCharts = [];
  const dropTrialCharts = () => {
    for (const c of trialCharts) c.disconnect();
    trialCharts = [];
  };
  ctx.onLeave(dropTrialCharts);
  async function plotTrial(t) {
    say(trialStatus, 'info', `Loading trial ${t.id}…`);
    try {
      const trial = await api('GET', `/trials/${t.id}`);
      const channel = (name) => (trial.channels.find((c) => c.name === name) || { values: [] }).values;
      const time = channel('t_s');
      dropTrialCharts();
      trialPlot.replaceChildren(h('h3', { id: 'trial-plot-h' }, `Trial ${t.id}: ${t.name || t.kind || ''}`));
      trialPlot.dataset.trialId = String(t.id);
      const x = time.length ? time : channel('angle_deg').map((_, i) => i / trial.sample_rate_hz);
      trialCharts.push(makePlot(trialPlot, [{ label: 'knee angle', color: '#1f5fbf' }], [x, channel('angle_deg')],
        { title: 'Knee angle', xLabel: 'time (s)', yLabel: 'deg', height: 200, id: 'trial-angle' }));
      trialCharts.push(makePlot(trialPlot, [{ label: 'stimulation', color: '#1e8449' }], [x, channel('stim_ma')],
        { title: 'Stimulation', xLabel: 'time (s)', yLabel: 'mA', height: 150, id: 'trial-stim' }));
      say(trialStatus, '', '');
    } catch (e) {
      say(trialStatus, 'error', `Cannot plot trial ${t.id}: ${e.message}`);
    }
  }
  const fetchFile = async (t, format) => {
    try {
      const name = await download(`/trials/${t.id}?format=${format}`, `trial-${t.id}.${format}`);
      say(trialStatus, 'ok', `Downloaded ${name}.`);
    } catch (e) {
      say(trialStatus, 'error', e.message);
    }
  };
  async function loadTrials() {
    const trials = await listAll(`/sessions/${sessionId}/trials`);
    const duration = (t) => (Number.isFinite(t.duration_s) ? t.duration_s : t.num_samples / t.sample_rate_hz);
    trialsSlot.replaceChildren(trials.length
      ? table(['Trial', 'Run', 'Duration (s)', 'Samples', 'Recorded (UTC)', 'Plot / download'], trials.map((t) => [
        `${t.id}: ${t.name || t.kind || '—'}`, t.run_id ? h('a', { href: `#/runs/${t.run_id}` }, `Run ${t.run_id}`) : '—', fmt(duration(t), 4), String(t.num_samples),
        utc(t.created_at_utc),
        h('span', { class: 'trial-actions' },
          h('button', { type: 'button', class: 'small', 'data-trial': t.id, onclick: () => plotTrial(t) }, 'Plot'),
          h('button', { type: 'button', class: 'small', 'data-csv': t.id, onclick: () => fetchFile(t, 'csv') }, 'CSV'),
          h('button', { type: 'button', class: 'small', 'data-sto': t.id, onclick: () => fetchFile(t, 'sto') }, '.sto'))]),
      { id: 'trials-table' })
      : h('p', {}, 'No trials recorded yet.'));
    return trials;
  }

  // --- protocol form --------------------------------------------------------------------
  const select = h('select', { id: 'protocol', name: 'protocol' },
    protocols.map((p) => h('option', { value: p.name }, p.title)));
  const description = h('p', { class: 'help', id: 'protocol-description' });
  const paramSlot = h('div', { id: 'protocol-parameters' });
  const formStatus = h('div', { id: 'run-form-status' });
  const current = () => protocols.find((x) => x.name === select.value);
  // A target trajectory CSV: a header naming t_s and angle_deg, then numbers.
  function parseTargetCsv(text) {
    const lines = text.split(/\r?\n/).filter((l) => l.trim() !== '');
    if (lines.length < 4) throw new Error('the target file needs a header and at least 3 rows');
    const header = lines[0].split(',').map((x) => x.trim());
    const ti = header.indexOf('t_s');
    const ai = header.indexOf('angle_deg');
    if (ti < 0 || ai < 0) throw new Error('the target file\'s header must name t_s and angle_deg');
    const out = { t_s: [], angle_deg: [] };
    lines.slice(1).forEach((line, i) => {
      const cells = line.split(',');
      const t = Number(cells[ti]);
      const a = Number(cells[ai]);
      if (!Number.isFinite(t) || !Number.isFinite(a)) throw new Error(`target file line ${i + 2}: not two numbers`);
      out.t_s.push(t);
      out.angle_deg.push(a);
    });
    return out;
  }
  function parameterField(param) {
    const value = param.default === null || param.default === undefined ? '' : param.default;
    if (param.choices && param.choices.length) {
      // A choice (e.g. tracking's controller): the value sent is its index.
      const el = field(param.name, param.label || param.name, {
        options: param.choices.map((c, i) => ({ value: String(i), label: c.replace(/_/g, ' ') })),
        value: String(value), help: param.description });
      el.querySelector('select').dataset.prefilled = String(value);
      return el;
    }
    const range = `${param.min}–${param.max}${param.unit === '1' ? '' : ` ${param.unit}`}`;
    const help = [param.description, value === '' && param.default_rule ? `default: ${param.default_rule}` : '', range]
      .filter(Boolean).join('; ');
    const el = field(param.name, `${param.label || param.name}${unitText(param.unit)}`,
      { type: 'number', value, step: param.integer ? 1 : 'any', help });
    const input = el.querySelector('input');
    input.dataset.prefilled = String(value);
    if (value === '' && param.default_rule) input.placeholder = param.default_rule;
    return el;
  }
  function renderParameters() {
    const p = current();
    if (!p) return;
    const tip = [p.description, p.thesis_section ? `Thesis ${p.thesis_section}.` : ''].filter(Boolean).join(' ');
    const stim = p.stimulates === undefined ? '' : p.stimulates ? 'Stimulates; bench' : 'No stimulation; bench';
    description.replaceChildren(`${stim || 'Bench'} mode ${p.bench_mode}.`,
      h('a', { href: '#', class: 'help-tip', id: 'protocol-help', title: tip, 'aria-label': `About this protocol: ${tip}`,
        onclick: (e) => { e.preventDefault(); helpText.hidden = !helpText.hidden; } }, '?'));
    helpText.textContent = tip;
    helpText.hidden = true;
    const basic = p.parameters.filter((x) => !x.advanced);
    const advanced = p.parameters.filter((x) => x.advanced);
    // A tolerance test above the session's recorded max is the clinician's
    // explicit decision, with its reason audited (docs/SAFETY.md).
    const reason = p.measures_max_tolerated
      ? field('ceiling_reason', 'Reason for a ceiling above the recorded max', {
        help: 'Only when the ceiling goes above the session\'s max tolerated amplitude (e.g. a re-test after training); audited.',
      })
      : '';
    // tracking's uploaded target: a CSV file with the columns t_s and angle_deg.
    const targetFile = p.follows_target
      ? field('target_file', 'Target trajectory file (CSV: t_s, angle_deg)', {
        type: 'file', help: 'For the target "uploaded": seconds and degrees, time strictly increasing.' })
      : '';
    paramSlot.replaceChildren(
      h('div', { class: 'grid-form', id: 'basic-parameters' }, basic.map(parameterField)), targetFile,
      advanced.length ? h('details', { id: 'advanced-parameters' }, h('summary', {}, `Advanced parameters (${advanced.length})`),
        h('div', { class: 'grid-form' }, advanced.map(parameterField))) : '',
      reason);
  }
  const helpText = h('p', { class: 'msg msg-info', id: 'protocol-help-text', hidden: true });
  select.addEventListener('change', renderParameters);

  const startButton = h('button', { type: 'submit', class: 'primary', id: 'start-run' }, 'Start protocol');
  const startHint = h('span', { class: 'start-hint', id: 'start-hint', 'aria-live': 'polite' });
  ctx.startControl(startButton, startHint, mayRun ? '' : 'Only a clinician or an admin may start protocols.');
  const form = h('form', { id: 'run-form', novalidate: true, onsubmit: async (event) => {
    event.preventDefault();
    clearErrors(form);
    const p = current();
    const valueOf = (name) => form.elements[name].value.trim();
    const problems = checkParameters(p, valueOf);
    if (problems.length) {
      const adv = form.querySelector('#advanced-parameters');
      if (adv && problems.some((x) => adv.querySelector(`[name="${x.field}"]`))) adv.open = true;
      showFieldErrors(form, problems);
      say(formStatus, 'error', `Please correct the ${problems.length === 1 ? 'marked parameter' : `${problems.length} marked parameters`}.`);
      return;
    }
    // Only what the clinician changed: the server derives the rest from the
    // protocol's defaults and the session (some defaults depend on others).
    const parameters = {};
    for (const param of p.parameters) {
      const input = form.elements[param.name];
      const raw = input.value.trim();
      if (raw === '' || raw === input.dataset.prefilled) continue;
      parameters[param.name] = Number(raw);
    }
    say(formStatus, 'info', 'Starting…');
    try {
      const body = { protocol: p.name, parameters };
      const file = form.elements.target_file && form.elements.target_file.files[0];
      if (p.follows_target && form.elements.target && form.elements.target.value === '3') {
        if (!file) throw new Error('choose the target trajectory file (CSV with t_s and angle_deg)');
        body.target_samples = parseTargetCsv(await file.text());
      }
      const reason = form.elements.ceiling_reason ? form.elements.ceiling_reason.value.trim() : '';
      if (reason) body.ceiling_reason = reason;
      const run = await api('POST', `/sessions/${sessionId}/runs`, body);
      ctx.runs.control(run);
      say(formStatus, 'ok', `Run ${run.run_id} started.`);
      follow(run);
    } catch (e) {
      const input = e.field && form.querySelector(`[name="${CSS.escape(e.field.split('.').pop())}"]`);
      const adv = form.querySelector('#advanced-parameters');
      if (input && adv && adv.contains(input)) adv.open = true;
      const onField = showFieldError(form, e);
      say(formStatus, 'error', onField ? `Please correct the marked parameter: ${e.message}` : `Cannot start: ${e.message}`);
    }
    ctx.refreshBench();
  } },
  h('div', { class: 'field' }, h('label', { for: 'protocol' }, 'Protocol'), select), description, helpText, paramSlot,
  h('div', { class: 'actions' }, startButton, startHint));

  // --- live run ------------------------------------------------------------------
  const live = h('section', { id: 'live', 'aria-labelledby': 'live-h', hidden: true });
  let stopLive = () => {};
  ctx.onLeave(() => stopLive());

  function follow(run) {
    stopLive();
    const runId = run.run_id;
    const abort = new AbortController();
    const progress = h('progress', { id: 'run-progress', max: 1, value: 0, 'aria-label': 'Run progress' });
    const progressText = h('span', { id: 'run-progress-text' }, '0 %');
    const eta = h('span', { id: 'run-eta' }, 'ETA —');
    const stateText = h('strong', { id: 'run-state', 'aria-live': 'polite' }, run.state);
    const phase = h('span', { id: 'run-phase' }, '');
    const endSlot = h('div', { id: 'run-end', 'aria-live': 'polite' });
    const trialsText = h('span', { id: 'run-trials' }, '');
    const tolerance = Boolean(describedAs(run.protocol).measures_max_tolerated);
    // In a tolerance test the primary action is the subject's "stop" (the
    // amplitude reached is recorded as the max tolerated); cancelling
    // records nothing, and says so.
    const cancel = h('button', { type: 'button', class: tolerance ? '' : 'danger', id: 'cancel-run', disabled: !mayRun,
      onclick: async () => {
        try {
          await api('POST', `/runs/${runId}/cancel`);
        } catch (e) {
          say(endSlot, 'error', `Cancel failed: ${e.message}`);
        }
      } }, tolerance ? 'Cancel (records nothing)' : 'Cancel run');
    const stop = tolerance
      ? h('button', { type: 'button', class: 'primary', id: 'stop-run', disabled: !mayRun, onclick: async () => {
        try {
          await api('POST', `/runs/${runId}/stop`);
        } catch (e) {
          say(endSlot, 'error', `Stop failed: ${e.message}`);
        }
      } }, 'The subject says stop (record max tolerated)')
      : '';
    // The numbers that matter while stimulating, large, beside the plots.
    const liveMa = h('span', { class: 'live-number', id: 'live-ma' }, '—');
    const liveNm = h('span', { class: 'live-number', id: 'live-nm' }, '—');
    const maxTolerated = session.details.max_tolerated_ma;
    const liveNumbers = h('div', { class: 'live-numbers', id: 'live-numbers', 'aria-live': 'off' },
      h('div', {}, h('span', { class: 'live-label' }, 'Current'), liveMa, h('span', { class: 'live-unit' }, 'mA')),
      h('div', {}, h('span', { class: 'live-label' }, 'Torque'), liveNm, h('span', { class: 'live-unit' }, 'N·m')),
      Number.isFinite(maxTolerated)
        ? h('div', {}, h('span', { class: 'live-label' }, 'Max tolerated'),
          h('span', { class: 'live-number', id: 'live-max' }, fmt1(maxTolerated)), h('span', { class: 'live-unit' }, 'mA'))
        : '');
    const plotsBox = h('div', { class: 'plots' });
    live.hidden = false;
    live.dataset.state = run.state;
    live.dataset.samples = '0';
    live.dataset.runId = String(runId);
    live.replaceChildren(h('h2', { id: 'live-h' }, `Run ${runId}: ${run.protocol}`),
      h('div', { class: 'progress-row' }, progress, progressText, eta),
      h('p', {}, 'State: ', stateText, ' ', phase, ' ', trialsText),
      h('div', { class: 'actions' }, stop, cancel), endSlot, liveNumbers, plotsBox);

    // A tracking run (docs/PROTOCOLS.md, `tracking`) draws the target with the knee angle, the
    // tracking error and, for the adaptive controller, its τ_scale estimate.
    const tracking = Boolean(describedAs(run.protocol).follows_target);
    const adaptive = tracking && run.parameters && run.parameters.controller === 2;
    const data = { t: [], angle: [], torque: [], stim: [], target: [], error: [], tau: [] };
    const mk = (title, label, unit, color) => makePlot(plotsBox, [{ label, color }], [[], []],
      { title, xLabel: 'bench time (s)', yLabel: unit, height: 180, id: label });
    // The stimulation with the session's max tolerated as a dashed line.
    const withMax = Number.isFinite(maxTolerated);
    const stimPlot = () => (withMax
      ? makePlot(plotsBox, [{ label: 'stimulation', color: '#1e8449' }, { label: 'max tolerated', color: '#c0392b', dash: [6, 4] }],
        [[], [], []], { title: 'Stimulation', xLabel: 'bench time (s)', yLabel: 'mA', height: 180, id: 'stimulation' })
      : mk('Stimulation', 'stimulation', 'mA', '#1e8449'));
    const anglePlot = () => (tracking
      ? makePlot(plotsBox, [{ label: 'target', color: '#7f8c8d', dash: [6, 4] }, { label: 'angle', color: '#1f5fbf' }],
        [[], [], []], { title: 'Knee angle and target', xLabel: 'bench time (s)', yLabel: 'deg', height: 200, id: 'angle' })
      : mk('Knee angle', 'angle', 'deg', '#1f5fbf'));
    // A tolerance test holds the knee locked: the current and the torque it
    // makes come first, the (still) angle last.
    const plots = tolerance
      ? { stim: stimPlot(), torque: mk('Torque', 'torque', 'N·m', '#c0392b'), angle: anglePlot() }
      : {
        angle: anglePlot(),
        ...(tracking ? { error: mk('Tracking error (knee − target)', 'error', 'deg', '#8e44ad') } : {}),
        torque: mk('Torque', 'torque', 'N·m', '#c0392b'),
        stim: stimPlot(),
        ...(adaptive ? { tau: mk('τ_scale estimate (adaptive)', 'tau_scale', 'N·m', '#d35400') } : {}),
      };
    let drawPending = false;
    let samplesSeen = 0;
    const redraw = () => {
      drawPending = false;
      for (const key of ['torque', 'error', 'tau']) if (plots[key]) plots[key].setData([data.t, data[key]]);
      plots.stim.setData(withMax ? [data.t, data.stim, data.t.map(() => maxTolerated)] : [data.t, data.stim]);
      if (data.stim.length) liveMa.textContent = fmt1(data.stim[data.stim.length - 1]);
      if (data.torque.length) liveNm.textContent = fmt1(data.torque[data.torque.length - 1]);
      plots.angle.setData(tracking ? [data.t, data.target, data.angle] : [data.t, data.angle]);
      if (tracking && data.error.length) live.dataset.lastError = String(data.error[data.error.length - 1]);
      live.dataset.samples = String(samplesSeen);
      if (data.stim.length) live.dataset.lastStim = String(data.stim[data.stim.length - 1]);
      let lo = Infinity;
      let hi = -Infinity;
      for (const v of data.torque) {
        if (v < lo) lo = v;
        if (v > hi) hi = v;
      }
      // The torque response seen in the window (a tolerance test stops on it).
      if (data.torque.length) live.dataset.torqueSwing = String(hi - lo);
    };
    const showProgress = (x) => {
      if (!x || x.progress === undefined) return;
      const { fraction, eta_s } = progressOf(x);
      progress.value = fraction;
      progressText.textContent = `${Math.round(fraction * 100)} %`;
      const p = typeof x.progress === 'object' ? x.progress : null;
      eta.textContent = `ETA ${fmtDuration(eta_s)}` +
        (p && Number.isFinite(p.bench_total_s) ? ` (bench ${fmt(p.bench_elapsed_s, 3)} of ${fmt(p.bench_total_s, 3)} s)` : '');
      phase.textContent = p && p.phase ? `phase ${p.phase}, step ${p.step}` : '';
      ctx.runs.update({ progress: x.progress, eta_s });
    };
    showProgress(run);

    let finished = false;
    stopLive = () => {
      abort.abort();
      for (const p of Object.values(plots)) p.disconnect();
      stopLive = () => {};
    };
    const finish = async (end) => {
      if (finished) return;
      finished = true;
      ctx.runs.update({ state: end.state });
      cancel.disabled = true;
      if (stop) stop.disabled = true;
      stateText.textContent = end.state;
      const parts = [`Run ${runId} ended: ${end.state}.`];
      if (end.reason) parts.push(`Reason: ${end.reason}.`);
      const r = end.result;
      let recorded = '';
      if (r && r.session_revision) {
        recorded = h('p', { class: 'msg msg-ok', id: 'run-recorded' }, `Recorded in this session: tolerance-test threshold ${fmtMa(r.threshold_ma)}, ` +
          `max tolerated ${fmtMa(r.max_tolerated_ma)} (revision ${r.session_revision})` +
          (r.subject_signalled_limit ? ', where the subject signalled the limit.' : '.'));
      } else if (r && r.ended_at_ceiling) {
        recorded = h('p', { class: 'msg msg-error', id: 'run-not-recorded' },
          `No max tolerated amplitude was recorded: ${r.message}.`);
      } else if (r && 'max_tolerated_ma' in r) {
        recorded = h('p', { class: 'msg msg-error', id: 'run-not-recorded' }, Number.isFinite(r.threshold_ma)
          ? `Measured threshold ${fmtMa(r.threshold_ma)} and max tolerated ${fmtMa(r.max_tolerated_ma)}, but they were not ` +
            'stored in the session: correct the session by hand or repeat the test.'
          : 'No threshold was detected (no torque response before the stop): the session\'s values are unchanged. ' +
            'Repeat the test and stop only after a clear response.');
      }
      // The end event carries the state; the run's figures are in its view.
      const v = end.values || (tracking ? ((await api('GET', `/runs/${runId}`).catch(() => null)) || {}).values || {} : {});
      const figures = Number.isFinite(v.tracking_rms_deg)
        ? h('p', { id: 'run-tracking' }, `Tracking error ${fmtDeg(v.tracking_rms_deg)} RMS, largest ${fmtDeg(v.tracking_max_error_deg)}` +
          (Number.isFinite(v.overshoot_deg) ? `, overshoot ${fmtDeg(v.overshoot_deg)}, settling ${fmtFixed(v.settling_s, 1, 's')}` : '') +
          `, charge delivered ${fmtFixed(v.charge_uc / 1000, 1, 'mC')}, at the stimulation limit for ${fmtFixed(v.saturated_s, 1, 's')}` +
          (adaptive ? `, muscle strength estimate at the end ${fmtNm(v.tau_scale_nm)}` : '') + '.')
        : '';
      // A daily check says what moved and what it did about it.
      const daily = r && r.verdict
        ? h('div', { id: 'run-daily-check' },
          h('p', { class: `msg ${r.verdict === 'rapid_due' ? 'msg-error' : 'msg-info'}` },
            `Daily check: ${DAILY_VERDICT[r.verdict] || r.verdict}. ${r.summary}.`),
          table(['What the check measures', 'In the stored set', 'Today', 'Change', 'Allowed change', 'Moved?'], (r.drifts || []).map((d) => {
            const row = DAILY_DRIFT[d.name] || { label: d.name, value: (x) => fmt(x, 4) };
            const absolute = d.name === 'irc_threshold_ma';
            return [row.label, row.value(d.stored), row.value(d.today),
              absolute ? fmtMa(d.change) : fmtFixed(100 * d.change, 1, '%'),
              absolute ? `± ${fmtMa(d.bound)}` : `± ${fmtFixed(100 * d.bound, 1, '%')}`, d.moved ? 'yes' : 'no'];
          }), { id: 'daily-check-table' }))
        : '';
      endSlot.replaceChildren(h('p', { class: `msg ${end.state === 'done' ? 'msg-ok' : 'msg-error'}`, role: 'status' }, parts.join(' ')),
        recorded, figures, daily,
        end.parameter_set_id ? h('p', { class: 'row' }, h('a', { href: `#/parameter-sets/${end.parameter_set_id}`, id: 'run-parameter-set' },
          `Open parameter set ${end.parameter_set_id}`),
        h('a', { href: `#/parameter-sets/${end.parameter_set_id}/check`, id: 'run-model-check' },
          'Check this model on fresh trials')) : '');
      // A tolerance test writes threshold / max tolerated into the session:
      // show them at once (and the defaults they give the next protocol).
      await Promise.all([refreshSession(), loadRuns(), loadTrials()]).catch((e) => say(endSlot, 'error', e.message));
      live.dataset.state = end.state;
      ctx.refreshBench();
    };

    streamEvents(`/runs/${runId}/stream`, (name, ev) => {
      if (name === 'state') {
        stateText.textContent = ev.state;
        live.dataset.state = ev.state;
        ctx.runs.update({ state: ev.state });
        showProgress(ev);
      } else if (name === 'progress') {
        showProgress(ev);
      } else if (name === 'samples') {
        const s = ev.samples;
        const n = s.angle_deg.length;
        for (let i = 0; i < n; i++) {
          data.t.push((ev.first_sample + i) / rate_hz);
          data.angle.push(s.angle_deg[i]);
          data.torque.push(s.torque_nm[i]);
          data.stim.push(s.stim_ma[i]);
          const target = s.target_deg ? s.target_deg[i] : null;
          data.target.push(target);
          data.error.push(target === null ? null : s.angle_deg[i] - target);
          data.tau.push(s.tau_scale_nm ? s.tau_scale_nm[i] : null);
        }
        samplesSeen += n;
        const cut = data.t.length - Math.round(WINDOW_S * rate_hz);
        if (cut > 0) for (const k of Object.keys(data)) data[k].splice(0, cut);
        if (!drawPending) {
          drawPending = true;
          requestAnimationFrame(redraw);
        }
      } else if (name === 'trial') {
        trialsText.textContent = `trial ${ev.trial_name || ev.trial_id || ''} stored`;
      } else if (name === 'end') {
        redraw();
        finish(ev);
      }
    }, abort.signal).then(async () => {
      if (!finished && !abort.signal.aborted) {
        const view = await api('GET', `/runs/${runId}`).catch(() => null);
        if (view && isFinal(view.state)) finish(view);
      }
    }).catch((e) => say(endSlot, 'error', e.message));
  }

  ctx.main.replaceChildren(
    h('p', { class: 'crumbs' }, h('a', { href: '#/subjects' }, 'Subjects'), ' › ',
      h('a', { href: `#/subjects/${subject.id}` }, subject.code), ' › ', `Session ${session.id}`),
    h('h1', {}, `Session ${session.id} — ${subject.code}, ${session.leg} leg, ${session.date}`),
    detailsSlot,
    h('section', { 'aria-labelledby': 'start-h' }, h('h2', { id: 'start-h' }, 'Run a protocol'), form, formStatus),
    live,
    h('section', { 'aria-labelledby': 'runs-h' }, h('h2', { id: 'runs-h' }, 'Runs of this session'), runsSlot),
    h('section', { 'aria-labelledby': 'trials-h' }, h('h2', { id: 'trials-h' }, 'Trials of this session'), trialsSlot,
      trialStatus, trialPlot),
    await exchangeSection(sessionId, loadTrials));
  // Without recorded limits only the tolerance test can run: offer it first;
  // with them, the protocol the catalogue offers first (GET /protocols).
  const d = session.details;
  const limits = Number.isFinite(d.threshold_ma) && Number.isFinite(d.max_tolerated_ma);
  const first = protocols.find((p) => (limits ? p.offered_first : p.measures_max_tolerated));
  if (first) select.value = first.name;
  renderParameters();
  const [, , trials] = await Promise.all([renderDetails(), loadRuns(), loadTrials()]);
  // Opened from a run's page: a trial to plot, or the run to run again.
  if (trialId) {
    const t = trials.find((x) => x.id === trialId);
    if (t) {
      await plotTrial(t);
      trialPlot.scrollIntoView({ block: 'start' });
    }
  }
  if (againRunId && mayRun) {
    const run = await api('GET', `/runs/${againRunId}`).catch(() => null);
    if (run && run.session_id === sessionId) runAgain(run);
  }
  // A run of this session already on the bench (started here before leaving
  // the page, or re-attached after a reload): follow it.
  const st = bench.state && typeof bench.state === 'object' ? bench.state : bench;
  if (st.run_id && !isFinal(st.run_state)) {
    const run = await api('GET', `/runs/${st.run_id}`).catch(() => null);
    if (run && run.session_id === sessionId && !isFinal(run.state)) follow(run);
  }
}
