// A run as a record: what it ran with (the protocol's parameters in its
// words and units), what it gave (its outcome and, for a daily check, what
// moved), its safety events and its trials, with the way to its session,
// its set and its model check, and "run again with these parameters".
import { api, listAll } from '../api.js';
import { fmt, h, table } from '../dom.js';
import { DAILY_VERDICT, parameterRows, runOutcome } from './outcome.js';

const utc = (iso) => (iso ? iso.slice(0, 19).replace('T', ' ') : '—');

export async function runView(ctx, runId) {
  const run = await api('GET', `/runs/${runId}`);
  const [session, catalog, trials] = await Promise.all([
    api('GET', `/sessions/${run.session_id}`),
    api('GET', '/protocols').catch(() => ({ protocols: [] })),
    listAll(`/sessions/${run.session_id}/trials`)]);
  const subject = await api('GET', `/subjects/${session.subject_id}`);
  const protocol = (catalog.protocols || []).find((p) => p.name === run.protocol);
  const own = trials.filter((t) => t.run_id === run.run_id);
  const mayRun = ctx.user.role === 'clinician' || ctx.user.role === 'admin';
  const rows = parameterRows(protocol, run.parameters);
  const events = run.safety_events || [];
  const duration = (t) => (Number.isFinite(t.duration_s) ? t.duration_s : t.num_samples / t.sample_rate_hz);
  const res = run.result || {};
  ctx.main.replaceChildren(
    h('p', { class: 'crumbs' }, h('a', { href: '#/subjects' }, 'Subjects'), ' › ',
      h('a', { href: `#/subjects/${subject.id}` }, subject.code), ' › ',
      h('a', { href: `#/sessions/${session.id}` }, `Session ${session.id}`), ' › ', `Run ${run.run_id}`),
    h('h1', {}, `Run ${run.run_id}: ${protocol ? protocol.title : run.protocol}`),
    table(['Field', 'Value'], [
      ['State', run.state + (run.reason ? ` — ${run.reason}` : '')],
      ['Started (UTC)', utc(run.started_at_utc || run.created_at_utc)],
      ['Finished (UTC)', utc(run.finished_at_utc)],
      ['Outcome', runOutcome(run)],
      ...(res.verdict ? [['Daily check', `${DAILY_VERDICT[res.verdict] || res.verdict}. ${res.summary || ''}`]] : []),
      ['Safety events', events.length ? events.map((e) => e.kind).join(', ') : 'none']],
    { class: 'kv', id: 'run-summary' }),
    h('p', { class: 'row' },
      mayRun ? h('a', { href: `#/sessions/${session.id}/again/${run.run_id}`, id: 'run-again-link' }, 'Run again with these parameters (the form, to check and start)') : ''),
    h('section', { 'aria-labelledby': 'run-params-h' }, h('h2', { id: 'run-params-h' }, 'Parameters it ran with'),
      rows.length ? table(['Parameter', 'Value'], rows, { class: 'kv', id: 'run-parameters-table' }) : h('p', {}, 'None.')),
    h('section', { 'aria-labelledby': 'run-trials-h' }, h('h2', { id: 'run-trials-h' }, 'Trials it recorded'),
      own.length ? table(['Trial', 'Duration (s)', 'Samples', 'Recorded (UTC)', ''], own.map((t) => [
        `${t.id}: ${t.name || t.kind || '—'}`, fmt(duration(t), 4), String(t.num_samples), utc(t.created_at_utc),
        h('a', { href: `#/sessions/${session.id}/trials/${t.id}`, 'aria-label': `Plot trial ${t.id}` }, 'Plot')]),
      { id: 'run-trials-table' }) : h('p', {}, 'No trials.')));
}
