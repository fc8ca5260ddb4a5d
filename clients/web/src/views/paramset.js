// A parameter set as plots (IRC, twitch, passive and active torque–angle
// and torque–velocity) with its values; two sets compared.
import { api, waitForJob } from '../api.js';
import { field, fmt, fmtFixed, h, say, table } from '../dom.js';
import { parameterCurves, parameterScalars, SCALAR_LABELS } from '../model.js';
import { joinCurves, makePlot } from '../plot.js';
import { legSide } from './subjects.js';

function plotsOf(ctx, curvesBySet, labels) {
  const grid = h('div', { class: 'plot-grid', id: 'set-plots' });
  const ids = [...new Set(curvesBySet.flatMap((cs) => cs.map((c) => c.id)))];
  const pending = [];
  for (const id of ids) {
    const present = curvesBySet.map((cs) => cs.find((c) => c.id === id));
    const first = present.find(Boolean);
    const cell = h('div', { class: 'plot-cell' });
    grid.appendChild(cell);
    pending.push(() => {
      const curves = present.filter(Boolean);
      const series = present.map((c, i) => (c ? { label: labels[i] } : null)).filter(Boolean);
      const chart = makePlot(cell, series, joinCurves(curves), { title: first.title, xLabel: first.xLabel,
        yLabel: first.yLabel, id, points: first.x.length < 60 });
      ctx.onLeave(() => chart.disconnect());
    });
  }
  return { grid, draw: () => pending.forEach((f) => f()) };
}

function valueRows(sets) {
  const scalars = sets.map(parameterScalars);
  const rows = Object.entries(SCALAR_LABELS).map(([key, label]) => [label, ...scalars.map((s) => fmt(s[key], 4))]);
  rows.push(['model', ...sets.map((s) => s.model)]);
  rows.push(['IRC method', ...sets.map((s) => s.irc_method)]);
  rows.push(['passive method', ...sets.map((s) => s.passive_method)]);
  rows.push(['active method', ...sets.map((s) => s.active_method)]);
  rows.push(['fitted on trials (training)', ...sets.map((s) => (s.trial_ids || []).join(', '))]);
  rows.push(['created (UTC)', ...sets.map((s) => s.created_at_utc.slice(0, 19).replace('T', ' '))]);
  if (sets.length === 2) {
    for (let i = 0; i < Object.keys(SCALAR_LABELS).length; i++) {
      const key = Object.keys(SCALAR_LABELS)[i];
      const a = scalars[0][key];
      const b = scalars[1][key];
      rows[i].push(Number.isFinite(a) && Number.isFinite(b) ? fmt(b - a, 3) : '—');
    }
    for (let i = Object.keys(SCALAR_LABELS).length; i < rows.length; i++) rows[i].push('');
  }
  return rows;
}

function breakpointTables(set) {
  return parameterCurves(set.parameters).filter((c) => c.id !== 'twitch').map((c) =>
    h('details', {}, h('summary', {}, `${c.title}: ${c.x.length} breakpoints`),
      table([c.xLabel, c.yLabel], c.x.map((x, i) => [fmt(x, 4), fmt(c.y[i], 4)]))));
}

// Whether the set is its leg's approved set, the one the model gate,
// tracking and the daily check use (docs/SAFETY.md), and, for a clinician,
// a form to approve it.
function approvalText(set) {
  const a = set.approval;
  if (!a) return 'A candidate, never approved: the model gate, tracking and the daily check do not use it.';
  const who = `${a.approved_by} at ${a.approved_at_utc.slice(0, 19).replace('T', ' ')} UTC (${a.note})`;
  return set.approved ? `The leg's approved set: approved by ${who}.`
    : `Approved earlier by ${who}; another set of the leg has been approved since.`;
}

// The model check's verdict in words, for the approval's note (the record
// keeps what the clinician saw when approving).
export function verdictNote(check) {
  const trials = check.trials.map((t) => `trial ${t.trial_id} ${errorText(t)}`).join(', ');
  return `Model check: ${(VERDICT_TEXT[check.verdict] || check.verdict).toLowerCase()}${trials ? ` (${trials})` : ''}.`;
}

function approvalSection(ctx, set) {
  const status = h('p', { class: set.approved ? 'msg msg-ok' : 'msg msg-info', id: 'approval-status' }, approvalText(set));
  const mayApprove = ctx.user.role === 'clinician' || ctx.user.role === 'admin';
  if (!mayApprove || set.approved) return h('section', { 'aria-labelledby': 'approval-h' }, h('h2', { id: 'approval-h' }, 'Approval'), status);
  const slot = h('div', { id: 'approval-message' });
  const form = h('form', { id: 'approve-form', novalidate: true },
    field('note', 'Why this set is right for the leg', { required: true, idPrefix: 'approve-' }),
    h('button', { type: 'submit' }, 'Approve for this leg'), slot);
  form.addEventListener('submit', async (ev) => {
    ev.preventDefault();
    try {
      const approved = await api('POST', `/parameter-sets/${set.id}/approve`, { note: form.elements.note.value });
      status.className = 'msg msg-ok';
      status.textContent = approvalText(approved);
      form.remove();
    } catch (e) {
      say(slot, 'error', e.message);
    }
  });
  const section = h('section', { 'aria-labelledby': 'approval-h' }, h('h2', { id: 'approval-h' }, 'Approval'), status, form);
  // After a model check on this page: its verdict beside the approval.
  section.noteVerdict = (check) => {
    const note = form.elements.note;
    if (!note.value.trim()) note.value = verdictNote(check);
  };
  return section;
}

// The model check (docs/MODEL.md, "The model check"): the set predicts the
// leg's validation trials it was not fitted on; a verdict in words, each
// trial's error in its own unit, the fit warnings in a clinician's words.
const VERDICT_TEXT = {
  good_for_control: 'Good for control',
  use_with_care: 'Use with care',
  do_not_use: 'Do not use to drive stimulation',
  no_fresh_trials: 'Not checked yet: no trial to check on',
};
const VERDICT_CLASS = { good_for_control: 'msg-ok', use_with_care: 'msg-info', do_not_use: 'msg-error', no_fresh_trials: 'msg-info' };

function errorText(t) {
  if (!Number.isFinite(t.e_rms)) return '—';
  if (t.unit === 'deg') return fmtFixed(t.e_rms, 1, '°');
  const share = Number.isFinite(t.measured_range) && t.measured_range > 0 ? ` (${fmtFixed(100 * t.e_rms / t.measured_range, 0, '%')} of ${fmtFixed(t.measured_range, 1, 'N·m')})` : '';
  return `${fmtFixed(t.e_rms, 1, 'N·m')}${share}`;
}

export function modelCheckResult(check) {
  const th = check.thresholds;
  return h('div', { id: 'model-check-result', 'data-verdict': check.verdict },
    h('p', { class: `msg ${VERDICT_CLASS[check.verdict] || 'msg-info'}`, id: 'model-check-verdict', role: 'status' },
      h('strong', {}, `${VERDICT_TEXT[check.verdict] || check.verdict}. `), check.summary),
    check.trials.length ? table(['Trial (not used for fitting)', 'Compared', 'Prediction error (RMS)', 'Outside the measured ranges', 'Verdict', 'Why'],
      check.trials.map((t) => [
        h('span', {}, `${t.trial_id}: ${t.trial_name.replace(/_/g, ' ')}`),
        t.quantity ? `${t.quantity} (${t.unit === 'deg' ? '°' : 'N·m'})` : '—',
        errorText(t),
        Number.isFinite(t.share_outside_identified_ranges) ? fmtFixed(100 * t.share_outside_identified_ranges, 0, '%') : '—',
        VERDICT_TEXT[t.verdict] || t.verdict,
        t.explanation]), { id: 'model-check-table' }) : '',
    h('p', { class: 'help' }, `Thresholds: knee angle good ≤ ${fmtFixed(th.angle_good_deg, 1, '°')}, with care ≤ ${fmtFixed(th.angle_care_deg, 1, '°')}; ` +
      `torque good ≤ ${fmtFixed(100 * th.torque_good_share, 0, '%')} of the torque the muscle produced, with care ≤ ${fmtFixed(100 * th.torque_care_share, 0, '%')}; ` +
      `more than ${fmtFixed(100 * th.outside_care_share, 0, '%')} of a swing outside the measured angles and speeds is at best "with care". The set's verdict is its worst trial's.`),
    check.warnings.length ? h('section', { 'aria-labelledby': 'model-check-warnings-h' },
      h('h3', { id: 'model-check-warnings-h' }, 'What the fit noticed'),
      h('ul', { id: 'model-check-warnings' }, check.warnings.map((w) => h('li', {}, w))),
      h('details', {}, h('summary', {}, 'The same, as the fitting software wrote it'),
        h('ul', {}, check.technical_warnings.map((w) => h('li', {}, w))))) : '');
}

function modelCheckSection(ctx, set, runNow, onChecked = () => {}) {
  const slot = h('div', { id: 'model-check-slot' });
  const status = h('div', { id: 'model-check-status' });
  const mayCheck = ['clinician', 'analyst', 'admin'].includes(ctx.user.role);
  const button = h('button', { type: 'button', class: 'primary', id: 'model-check-run', disabled: !mayCheck }, 'Check this model on fresh trials');
  button.addEventListener('click', async () => {
    button.disabled = true;
    say(status, 'info', 'Predicting the trials the set was not fitted on…');
    try {
      const job = await api('POST', `/parameter-sets/${set.id}/model-check`);
      const check = await waitForJob(job);
      say(status, '', '');
      slot.replaceChildren(modelCheckResult(check));
      onChecked(check);
    } catch (e) {
      say(status, 'error', `The model check failed: ${e.message}`);
    } finally {
      button.disabled = !mayCheck;
    }
  });
  // Opened as "check this model": the check runs at once.
  if (runNow && mayCheck) setTimeout(() => button.click(), 0);
  return h('section', { 'aria-labelledby': 'model-check-h', id: 'model-check' },
    h('h2', { id: 'model-check-h' }, 'Model check: is this set fit to drive stimulation?'),
    h('p', {}, 'The set predicts this leg\'s prediction-protocol trials it was not fitted on; each is judged in its own unit (knee angle in degrees, torque in N·m).'),
    h('div', { class: 'actions' }, button, mayCheck ? '' : h('small', {}, ' The model check needs the clinician, analyst or admin role.')),
    status, slot);
}

export async function parameterSetView(ctx, setId, { check = false } = {}) {
  const set = await api('GET', `/parameter-sets/${setId}`);
  const subject = await api('GET', `/subjects/${set.subject_id}`);
  const { grid, draw } = plotsOf(ctx, [parameterCurves(set.parameters)], [`set ${set.id}`]);
  const fit = (set.parameters.provenance && set.parameters.provenance.fit_rms) || {};
  const warnings = (set.parameters.provenance && set.parameters.provenance.warnings) || [];
  const mayPredict = ['clinician', 'analyst', 'admin'].includes(ctx.user.role);
  const approval = approvalSection(ctx, set);
  ctx.main.replaceChildren(
    h('p', { class: 'crumbs' }, h('a', { href: '#/subjects' }, 'Subjects'), ' › ',
      h('a', { href: `#/subjects/${subject.id}` }, subject.code), ' › ', `Parameter set ${set.id}`),
    h('h1', {}, `Parameter set ${set.id} (version ${set.version}) — ${subject.code}, ${legSide(subject, set.leg_id)} leg`),
    h('p', { class: 'row' },
      h('a', { href: `#/subjects/${subject.id}/history` }, 'History of this subject'),
      mayPredict ? h('a', { href: `#/predict/${set.id}`, id: 'predict-link' }, 'Run a prediction with this set') : ''),
    warnings.length ? h('section', { class: 'msg msg-info', id: 'fit-notes', 'aria-label': 'What the fit noticed' },
      h('strong', {}, 'What the fit noticed: '),
      h('ul', {}, (set.fit_notes || warnings).map((w) => h('li', {}, w))),
      h('details', {}, h('summary', {}, 'As the fitting software wrote it'), h('ul', {}, warnings.map((w) => h('li', {}, w))))) : '',
    modelCheckSection(ctx, set, check, (result) => approval.noteVerdict && approval.noteVerdict(result)),
    approval,
    grid,
    h('section', { 'aria-labelledby': 'values-h' }, h('h2', { id: 'values-h' }, 'Values'),
      table(['Quantity', 'Value'], valueRows([set]), { id: 'values-table', class: 'kv' }),
      Object.keys(fit).length ? h('details', {}, h('summary', {}, 'Fit residuals (RMS)'),
        table(['Fit', 'RMS'], Object.entries(fit).map(([k, v]) => [k, fmt(v, 4)]))) : '',
      ...breakpointTables(set)));
  draw();
}

export async function compareView(ctx, idA, idB) {
  const [a, b] = await Promise.all([api('GET', `/parameter-sets/${idA}`), api('GET', `/parameter-sets/${idB}`)]);
  const labels = [`set ${a.id}`, `set ${b.id}`];
  const { grid, draw } = plotsOf(ctx, [parameterCurves(a.parameters), parameterCurves(b.parameters)], labels);
  ctx.main.replaceChildren(
    h('p', { class: 'crumbs' }, h('a', { href: '#/subjects' }, 'Subjects'), ' › ',
      h('a', { href: `#/subjects/${a.subject_id}` }, `Subject ${a.subject_id}`), ' › ', 'Compare'),
    h('h1', {}, `Parameter set ${a.id} compared with ${b.id}`),
    h('section', { 'aria-labelledby': 'cmp-h' }, h('h2', { id: 'cmp-h' }, 'Values'),
      table(['Quantity', ...labels, `${labels[1]} − ${labels[0]}`], valueRows([a, b]), { id: 'compare-table' })),
    grid);
  draw();
}
