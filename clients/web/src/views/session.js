// A session: start a protocol (parameters prefilled from the protocol
// description and the session's threshold / max tolerated), follow it live
// (progress with ETA, knee angle, torque and stimulation from the event
// stream), cancel it; the session's runs.
import { api, listAll } from '../api.js';
import { clearErrors, field, fmt, fmtDuration, h, say, showFieldError, table } from '../dom.js';
import { makePlot } from '../plot.js';
import { streamEvents } from '../sse.js';

const WINDOW_S = 30; // bench seconds shown in the live plots

// The value the server will use when the field is left alone: the same
// scaling as its DefaultFor (server/protocols/protocol.cc), so an mA field
// shows mA and an angle field the range the run will use.
function defaultFor(param, session, limits) {
  const d = session.details;
  const thr = d.threshold_ma, max = d.max_tolerated_ma;
  const known = Number.isFinite(thr) && Number.isFinite(max);
  switch (param.scales_to) {
    case 'threshold': return Number.isFinite(thr) ? thr : param.default;
    case 'max_tolerated': return Number.isFinite(max) ? max : param.default;
    case 'stim_range':
      return known ? Math.round((thr + param.default * (max - thr)) * 10) / 10 : param.default;
    case 'range_min': return limits.min_angle_deg;
    case 'range_max': return limits.max_angle_deg;
    default: return param.default;
  }
}

export async function sessionView(ctx, sessionId) {
  const [session, protocolList, bench] = await Promise.all([
    api('GET', `/sessions/${sessionId}`), api('GET', '/protocols'), api('GET', '/bench')]);
  const subject = await api('GET', `/subjects/${session.subject_id}`);
  const protocols = protocolList.protocols;
  const rate_hz = bench.limits.sample_rate_hz;
  const mayRun = ctx.user.role === 'clinician' || ctx.user.role === 'admin';

  const runsSlot = h('div', { id: 'run-list' });
  async function loadRuns() {
    const runs = await listAll(`/sessions/${sessionId}/runs`);
    runsSlot.replaceChildren(runs.length
      ? table(['Run', 'Protocol', 'State', 'Started (UTC)', 'Message'], runs.map((r) => [
        `Run ${r.id}`, r.protocol, r.state, (r.started_at_utc || r.created_at_utc || '').slice(0, 19).replace('T', ' '),
        r.message || '—']),
      { id: 'runs-table' })
      : h('p', {}, 'No runs yet.'));
  }

  // --- protocol form ------------------------------------------------------------
  const select = h('select', { id: 'protocol', name: 'protocol' },
    protocols.map((p) => h('option', { value: p.name }, p.title)));
  const description = h('p', { class: 'help', id: 'protocol-description' });
  const paramSlot = h('div', { class: 'grid-form', id: 'protocol-parameters' });
  const formStatus = h('div', { id: 'run-form-status' });
  function renderParameters() {
    const p = protocols.find((x) => x.name === select.value);
    description.textContent = `${p.description} Bench mode: ${p.bench_mode}.`;
    paramSlot.replaceChildren(...p.parameters.map((param) => field(param.name,
      `${param.name.replace(/_/g, ' ')} (${param.unit})`,
      { type: 'number', value: defaultFor(param, session, bench.limits), step: param.integer ? 1 : 'any',
        help: `${param.description}; ${param.min}–${param.max}` })));
    for (const input of paramSlot.querySelectorAll('input')) input.dataset.prefilled = input.value;
  }
  select.addEventListener('change', renderParameters);
  const startButton = h('button', { type: 'submit', class: 'primary', id: 'start-run', disabled: !mayRun }, 'Start protocol');
  const form = h('form', { id: 'run-form', novalidate: true, onsubmit: async (event) => {
    event.preventDefault();
    clearErrors(form);
    const p = protocols.find((x) => x.name === select.value);
    const parameters = {};
    // Only what the clinician changed: the server derives the rest from the
    // protocol's defaults and the session (some defaults depend on others).
    for (const param of p.parameters) {
      const input = form.elements[param.name];
      const raw = input.value.trim();
      if (raw === '' || raw === input.dataset.prefilled) continue;
      const n = Number(raw);
      parameters[param.name] = Number.isFinite(n) ? n : raw;
    }
    say(formStatus, 'info', 'Starting…');
    try {
      const run = await api('POST', `/sessions/${sessionId}/runs`, { protocol: p.name, parameters });
      say(formStatus, 'ok', `Run ${run.run_id} started.`);
      follow(run);
    } catch (e) {
      const onField = showFieldError(form, e);
      say(formStatus, 'error', onField ? `Please correct the marked parameter: ${e.message}` : `Cannot start: ${e.message}`);
    }
  } },
  h('div', { class: 'field' }, h('label', { for: 'protocol' }, 'Protocol'), select), description, paramSlot,
  h('div', { class: 'actions' }, startButton,
    mayRun ? '' : h('small', {}, ' Only a clinician or an admin may start protocols.')));

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
    const cancel = h('button', { type: 'button', class: 'danger', id: 'cancel-run', onclick: async () => {
      try {
        await api('POST', `/runs/${runId}/cancel`);
      } catch (e) {
        say(endSlot, 'error', `Cancel failed: ${e.message}`);
      }
    } }, 'Cancel run');
    const stop = run.protocol === 'tolerance_test'
      ? h('button', { type: 'button', id: 'stop-run', onclick: async () => {
        try {
          await api('POST', `/runs/${runId}/stop`);
        } catch (e) {
          say(endSlot, 'error', `Stop failed: ${e.message}`);
        }
      } }, 'Stop here (max tolerated)')
      : '';
    const plotsBox = h('div', { class: 'plots' });
    live.hidden = false;
    live.dataset.state = run.state;
    live.dataset.samples = '0';
    live.dataset.runId = String(runId);
    live.replaceChildren(h('h2', { id: 'live-h' }, `Run ${runId}: ${run.protocol}`),
      h('div', { class: 'progress-row' }, progress, progressText, eta),
      h('p', {}, 'State: ', stateText, ' ', phase, ' ', trialsText),
      h('div', { class: 'actions' }, cancel, stop), endSlot, plotsBox);

    const data = { t: [], angle: [], torque: [], stim: [] };
    const mk = (title, label, unit, color) => makePlot(plotsBox, [{ label, color }], [[], []],
      { title, xLabel: 'bench time (s)', yLabel: unit, height: 180, id: label });
    const plots = {
      angle: mk('Knee angle', 'angle', 'deg', '#1f5fbf'),
      torque: mk('Torque', 'torque', 'N·m', '#c0392b'),
      stim: mk('Stimulation', 'stimulation', 'mA', '#1e8449'),
    };
    let drawPending = false;
    let samplesSeen = 0;
    const redraw = () => {
      drawPending = false;
      for (const key of ['angle', 'torque', 'stim']) plots[key].setData([data.t, data[key]]);
      live.dataset.samples = String(samplesSeen);
    };
    const showProgress = (p) => {
      if (!p) return;
      progress.value = p.fraction;
      progressText.textContent = `${Math.round(p.fraction * 100)} %`;
      eta.textContent = `ETA ${fmtDuration(p.eta_s)} (bench ${fmt(p.bench_elapsed_s, 3)} of ${fmt(p.bench_total_s, 3)} s)`;
      phase.textContent = `phase ${p.phase}, step ${p.step}`;
    };
    showProgress(run.progress);

    let finished = false;
    const heartbeat = mayRun && run.owner_user_id === ctx.user.id
      ? setInterval(() => api('POST', `/runs/${runId}/heartbeat`).catch(() => {}), 400) : null;
    stopLive = () => {
      abort.abort();
      if (heartbeat) clearInterval(heartbeat);
      for (const p of Object.values(plots)) p.disconnect();
      stopLive = () => {};
    };
    const finish = async (end) => {
      if (finished) return;
      finished = true;
      if (heartbeat) clearInterval(heartbeat);
      cancel.disabled = true;
      if (stop) stop.disabled = true;
      stateText.textContent = end.state;
      live.dataset.state = end.state;
      const parts = [`Run ${runId} ended: ${end.state}.`];
      if (end.reason) parts.push(`Reason: ${end.reason}.`);
      endSlot.replaceChildren(h('p', { class: `msg ${end.state === 'done' ? 'msg-ok' : 'msg-error'}`, role: 'status' }, parts.join(' ')),
        end.parameter_set_id ? h('p', {}, h('a', { href: `#/parameter-sets/${end.parameter_set_id}`, id: 'run-parameter-set' },
          `Open parameter set ${end.parameter_set_id}`)) : '');
      await loadRuns().catch(() => {});
    };

    streamEvents(`/runs/${runId}/stream`, (name, ev) => {
      if (name === 'state') {
        stateText.textContent = ev.state;
        live.dataset.state = ev.state;
        showProgress(ev.progress);
      } else if (name === 'progress') {
        showProgress(ev.progress);
      } else if (name === 'samples') {
        const s = ev.samples;
        const n = s.angle_deg.length;
        for (let i = 0; i < n; i++) {
          data.t.push((ev.first_sample + i) / rate_hz);
          data.angle.push(s.angle_deg[i]);
          data.torque.push(s.torque_nm[i]);
          data.stim.push(s.stim_ma[i]);
        }
        samplesSeen += n;
        const cut = data.t.length - Math.round(WINDOW_S * rate_hz);
        if (cut > 0) for (const k of Object.keys(data)) data[k].splice(0, cut);
        if (!drawPending) {
          drawPending = true;
          requestAnimationFrame(redraw);
        }
      } else if (name === 'trial') {
        trialsText.textContent = `trial ${ev.name || ev.trial_id || ''} stored`;
      } else if (name === 'end') {
        redraw();
        finish(ev);
      }
    }, abort.signal).then(async () => {
      if (!finished && !abort.signal.aborted) {
        const view = await api('GET', `/runs/${runId}`).catch(() => null);
        if (view && view.finished_at) finish(view);
      }
    }).catch((e) => say(endSlot, 'error', e.message));
  }

  ctx.main.replaceChildren(
    h('p', { class: 'crumbs' }, h('a', { href: '#/subjects' }, 'Subjects'), ' › ',
      h('a', { href: `#/subjects/${subject.id}` }, subject.code), ' › ', `Session ${session.id}`),
    h('h1', {}, `Session ${session.id} — ${subject.code}, ${session.leg} leg, ${session.date}`),
    table(['Field', 'Value'], [['Threshold (mA)', fmt(session.details.threshold_ma)],
      ['Max tolerated (mA)', fmt(session.details.max_tolerated_ma)],
      ['Accelerometer placement', session.details.accelerometer_placement || '—'], ['Notes', session.details.notes || '—']],
    { class: 'kv' }),
    h('section', { 'aria-labelledby': 'start-h' }, h('h2', { id: 'start-h' }, 'Run a protocol'), form, formStatus),
    live,
    h('section', { 'aria-labelledby': 'runs-h' }, h('h2', { id: 'runs-h' }, 'Runs of this session'), runsSlot));
  const rapid = protocols.find((p) => p.name === 'rapid_parameterisation');
  if (rapid) select.value = rapid.name;
  renderParameters();
  await loadRuns();
  // A run of this session already on the bench: follow it.
  const st = bench.state;
  if (st.busy && st.run_id) {
    const run = await api('GET', `/runs/${st.run_id}`).catch(() => null);
    if (run && run.session_id === sessionId && !run.finished_at) follow(run);
  }
}
