// A subject's parameter history across sessions: τ_scale, inertia, pole
// and threshold of every parameter set over time (and the threshold the
// clinician recorded per session).
import { api, listAll } from '../api.js';
import { fmt, fmtFixed, h, table } from '../dom.js';
import { parameterScalars, SCALAR_LABELS } from '../model.js';
import { makePlot } from '../plot.js';

const unix = (iso) => Date.parse(iso.endsWith('Z') ? iso : `${iso}Z`) / 1000;

export async function historyView(ctx, subjectId) {
  const subject = await api('GET', `/subjects/${subjectId}`);
  const summaries = await listAll(`/parameter-sets?subject_id=${subjectId}`);
  const sets = await Promise.all(summaries.map((s) => api('GET', `/parameter-sets/${s.id}`)));
  sets.sort((x, y) => unix(x.created_at_utc) - unix(y.created_at_utc));
  const sessions = await listAll(`/subjects/${subjectId}/sessions`);
  const crumbs = h('p', { class: 'crumbs' }, h('a', { href: '#/subjects' }, 'Subjects'), ' › ',
    h('a', { href: `#/subjects/${subjectId}` }, subject.code), ' › ', 'History');
  if (!sets.length) {
    ctx.main.replaceChildren(crumbs, h('h1', {}, `Parameter history — ${subject.code}`),
      h('p', {}, 'No parameter sets yet.'));
    return;
  }
  const t = sets.map((s) => unix(s.created_at_utc));
  const scalars = sets.map(parameterScalars);
  const grid = h('div', { class: 'plot-grid', id: 'history-plots' });
  ctx.main.replaceChildren(crumbs, h('h1', {}, `Parameter history — ${subject.code}`), grid,
    h('section', { 'aria-labelledby': 'hist-h' }, h('h2', { id: 'hist-h' }, 'Values'),
      table(['Set', 'Created (UTC)', ...['torque_scale_nm', 'inertia_kgm2', 'pole_per_s', 'threshold_ma'].map((k) => SCALAR_LABELS[k])],
        sets.map((s, i) => [h('a', { href: `#/parameter-sets/${s.id}` }, `Set ${s.id}`), s.created_at_utc.slice(0, 19).replace('T', ' '),
          fmt(scalars[i].torque_scale_nm, 4), fmt(scalars[i].inertia_kgm2, 4), fmt(scalars[i].pole_per_s, 4), fmtFixed(scalars[i].threshold_ma, 1)]),
        { id: 'history-table' })));
  const plot = (key, extra) => {
    const cell = h('div', { class: 'plot-cell' });
    grid.appendChild(cell);
    let data = [t, scalars.map((s) => s[key])];
    const series = [{ label: 'parameter sets' }];
    if (extra) {
      const xs = [...new Set([...t, ...extra.t])].sort((p, q) => p - q);
      const at = (times, values) => xs.map((x) => { const i = times.indexOf(x); return i < 0 ? null : values[i]; });
      data = [xs, at(t, data[1]), at(extra.t, extra.y)];
      series.push({ label: extra.label, dash: [6, 4] });
    }
    const chart = makePlot(cell, series, data, { title: SCALAR_LABELS[key], xLabel: 'date', yLabel: SCALAR_LABELS[key],
      time: true, points: true, id: key });
    ctx.onLeave(() => chart.disconnect());
  };
  plot('torque_scale_nm');
  plot('inertia_kgm2');
  plot('pole_per_s');
  const recorded = sessions.filter((s) => Number.isFinite(s.details.threshold_ma));
  plot('threshold_ma', recorded.length ? {
    label: 'session threshold (recorded)', t: recorded.map((s) => unix(s.created_at_utc)),
    y: recorded.map((s) => s.details.threshold_ma) } : null);
}
