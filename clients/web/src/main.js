// fesbench web client: layout (navigation, who is signed in, the e-stop
// button on every page, the connection banner) and the hash router.
import './style.css';
import { api, getToken, onConnectivity, setToken, UNREACHABLE_MESSAGE } from './api.js';
import { fmtDuration, h, say } from './dom.js';
import { createRunController, isFinal, progressOf } from './runs.js';
import { signInView } from './views/signin.js';
import { subjectsView, subjectView } from './views/subjects.js';
import { sessionView } from './views/session.js';
import { parameterSetView, compareView } from './views/paramset.js';
import { historyView } from './views/history.js';
import { predictionView } from './views/predict.js';
import { adminView } from './views/admin.js';
import { runView } from './views/run.js';

const state = { user: null, cleanup: [] };

const routes = [
  [/^#\/signin$/, () => signInView(ctx)],
  [/^#\/subjects$/, () => subjectsView(ctx)],
  [/^#\/subjects\/(\d+)$/, (m) => subjectView(ctx, Number(m[1]))],
  [/^#\/subjects\/(\d+)\/history$/, (m) => historyView(ctx, Number(m[1]))],
  [/^#\/sessions\/(\d+)$/, (m) => sessionView(ctx, Number(m[1]))],
  [/^#\/sessions\/(\d+)\/trials\/(\d+)$/, (m) => sessionView(ctx, Number(m[1]), { trialId: Number(m[2]) })],
  [/^#\/sessions\/(\d+)\/again\/(\d+)$/, (m) => sessionView(ctx, Number(m[1]), { againRunId: Number(m[2]) })],
  [/^#\/runs\/(\d+)$/, (m) => runView(ctx, Number(m[1]))],
  [/^#\/parameter-sets\/(\d+)$/, (m) => parameterSetView(ctx, Number(m[1]))],
  [/^#\/parameter-sets\/(\d+)\/check$/, (m) => parameterSetView(ctx, Number(m[1]), { check: true })],
  [/^#\/compare\/(\d+)\/(\d+)$/, (m) => compareView(ctx, Number(m[1]), Number(m[2]))],
  [/^#\/predict(?:\/(\d+))?$/, (m) => predictionView(ctx, m[1] ? Number(m[1]) : null)],
  [/^#\/admin$/, () => adminView(ctx)],
];

/// What views get: the main element, the user, and a way to register
/// cleanups (streams, timers) run when the page changes.
const ctx = {
  get user() {
    return state.user;
  },
  main: null,
  /// The app's run controller (heartbeat, run bar): runs.control(run) after a start.
  get runs() {
    return runs;
  },
  /// The bench as last read (null: unknown) and its state object.
  get bench() {
    return bench;
  },
  get benchState() {
    return benchStateOf(bench);
  },
  refreshBench: () => pollBench(),
  /// Marks a button as a start control: disabled while the e-stop is latched,
  /// the bench state is unknown or busy (the reason in the element `hint`),
  /// or for the view's own reason `blocked` (e.g. the role).
  startControl(button, hint, blocked = '') {
    button.classList.add('start-control');
    if (blocked) button.dataset.blocked = blocked;
    if (hint) {
      if (!hint.id) hint.id = `${button.id || 'start'}-hint`;
      button.dataset.hint = hint.id;
      button.setAttribute('aria-describedby', hint.id);
    }
    applyStartControl(button, benchBlock(), hint);
    return button;
  },
  onLeave(fn) {
    state.cleanup.push(fn);
  },
  async signIn(token) {
    setToken(token);
    try {
      state.user = await api('GET', '/me');
    } catch (e) {
      setToken('');
      state.user = null;
      throw e;
    }
    await loadProtocolTraits();
    renderChrome();
    pollBench();
  },
  signOut() {
    setToken('');
    state.user = null;
    runs.end();
    renderChrome();
    pollBench();
    location.hash = '#/signin';
  },
};

function renderChrome() {
  const nav = document.getElementById('nav');
  const who = document.getElementById('who');
  if (!state.user) {
    nav.replaceChildren();
    who.replaceChildren(h('span', {}, 'Not signed in'));
    return;
  }
  const link = (href, text) => h('a', { href }, text);
  nav.replaceChildren(h('ul', {},
    h('li', {}, link('#/subjects', 'Subjects')),
    h('li', {}, link('#/predict', 'Prediction')),
    state.user.role === 'admin' ? h('li', {}, link('#/admin', 'Users and tokens')) : ''));
  who.replaceChildren(
    h('span', { id: 'who-name' }, h('span', { class: 'wide-only' }, 'Signed in as '), state.user.name),
    h('span', { class: `role role-${state.user.role}`, id: 'who-role' }, state.user.role),
    h('button', { type: 'button', class: 'link', onclick: () => ctx.signOut() }, 'Sign out'));
}

async function route() {
  for (const fn of state.cleanup.splice(0)) {
    try {
      fn();
    } catch {
      /* a cleanup must not stop navigation */
    }
  }
  const main = document.getElementById('main');
  ctx.main = main;
  let hash = location.hash || '#/subjects';
  if (!state.user && hash !== '#/signin') {
    location.hash = '#/signin';
    return;
  }
  for (const [pattern, view] of routes) {
    const m = hash.match(pattern);
    if (m) {
      main.replaceChildren(h('p', { class: 'loading' }, 'Loading…'));
      main.dataset.page = hash.split('/')[1] || '';
      try {
        await view(m);
      } catch (e) {
        main.replaceChildren(h('h1', {}, 'Something went wrong'),
          h('p', { class: 'msg msg-error', role: 'alert' }, e.message || String(e)));
      }
      return;
    }
  }
  main.replaceChildren(h('h1', {}, 'Not found'), h('p', {}, h('a', { href: '#/subjects' }, 'Go to the subjects')));
}

// --- connection banner -------------------------------------------------------
function setBanner(text) {
  const banner = document.getElementById('banner');
  banner.hidden = !text;
  banner.textContent = text || '';
}
onConnectivity((ok, error) => setBanner(ok ? '' : (error && error.message) || UNREACHABLE_MESSAGE));

async function checkHealth() {
  try {
    const res = await fetch('/api/v1/health', { cache: 'no-store' });
    if (!res.ok) throw new Error(String(res.status));
    setBanner('');
  } catch {
    setBanner(UNREACHABLE_MESSAGE);
  }
}

// --- bench state, e-stop, run bar (every page) ----------------------------------
// The bench as last read: null = unknown (not signed in, or the server does
// not answer). GET /bench carries its state under "state" (docs/API.md, "The bench").
let bench = null;
const benchStateOf = (b) => (b && b.state && typeof b.state === 'object' ? b.state : b);

/// Why a start control is disabled now ('' = it may start).
function benchBlock() {
  const st = benchStateOf(bench);
  if (!st) return 'The bench state is unknown (the server does not answer): nothing can start.';
  if (st.estopped) return 'The e-stop is latched: nothing can start until it is cleared.';
  if (st.busy || (st.run_id && !isFinal(st.run_state))) return `The bench is busy with run ${st.run_id}.`;
  return '';
}

/// Every start control (ctx.startControl) follows the bench: disabled while
/// the e-stop is latched, the bench state is unknown or another run holds it.
function applyStartControl(button, why = benchBlock(), hint = null) {
  const own = button.dataset.blocked || '';
  button.disabled = !!(own || why);
  const slot = hint || (button.dataset.hint && document.getElementById(button.dataset.hint));
  if (slot) slot.textContent = own || why;
}
function applyStartControls() {
  const why = benchBlock();
  for (const button of document.querySelectorAll('.start-control')) applyStartControl(button, why);
}

function renderLatch() {
  const latch = document.getElementById('latch');
  const st = benchStateOf(bench);
  const latched = !!(st && st.estopped);
  document.body.classList.toggle('estopped', latched);
  if (!latched) {
    // A failed e-stop stays until it is dismissed or an e-stop latches: the
    // next bench refresh must not wipe the message to use the hardware stop.
    if (latch.dataset.shown === 'failed' && !latch.hidden) return;
    dismissLatch();
    return;
  }
  if (latch.dataset.shown === 'latched' && !latch.hidden) return;
  latch.dataset.shown = 'latched';
  const mayClear = state.user && (state.user.role === 'clinician' || state.user.role === 'admin');
  latch.replaceChildren(
    h('strong', {}, 'E-STOP LATCHED'),
    h('span', {}, `Stimulation is off and the motor disabled${st.estop_source ? ` (e-stop from ${st.estop_source})` : ''}.` +
      ' Nothing can start until the e-stop is cleared.'),
    mayClear ? h('button', { type: 'button', id: 'estop-clear', onclick: openClearDialog }, 'Clear e-stop…') : '');
  latch.hidden = false;
}

function showBench() {
  const slot = estopState();
  const st = benchStateOf(bench);
  document.body.classList.toggle('bench-unknown', !st);
  let text = 'idle';
  if (!st) text = 'unknown';
  else if (st.estopped) text = 'LATCHED';
  else if (st.run_id && !isFinal(st.run_state)) text = `run ${st.run_id}`;
  // "Bench: " folds away at narrow widths (the slot keeps its width).
  slot.replaceChildren(h('span', { class: 'wide-only' }, 'Bench: '), text);
  slot.title = `Bench: ${text}`;
  renderLatch();
  applyStartControls();
}

const estopState = () => document.getElementById('estop-state');

function dismissLatch() {
  const latch = document.getElementById('latch');
  latch.hidden = true;
  latch.replaceChildren();
  delete latch.dataset.shown;
}

/// A failed e-stop is the loudest thing on the page, and stays until the
/// user dismisses it (or an e-stop latches).
function estopFailed(text) {
  const latch = document.getElementById('latch');
  latch.dataset.shown = 'failed';
  latch.replaceChildren(h('strong', {}, 'E-STOP NOT CONFIRMED'), h('span', {}, ` — ${text} Use the bench's hardware stop.`),
    h('button', { type: 'button', id: 'estop-failed-dismiss', onclick: dismissLatch }, 'Dismiss'));
  latch.hidden = false;
}

async function pressEstop() {
  if (!getToken()) {
    estopFailed('Sign in to send the e-stop.');
    return;
  }
  try {
    await api('POST', '/bench/estop');
    await pollBench();
  } catch (e) {
    estopFailed(e.message);
  }
}

// Clearing re-arms the bench: a dialog that says so and a second, explicit
// confirmation (a checkbox, then the button it enables).
function openClearDialog() {
  const check = h('input', { type: 'checkbox', id: 'estop-confirm-check' });
  const status = h('div', { id: 'estop-dialog-status' });
  const confirm = h('button', { type: 'button', class: 'danger', id: 'estop-confirm', disabled: true }, 'Clear e-stop');
  const dialog = h('dialog', { id: 'estop-dialog', 'aria-labelledby': 'estop-dialog-h' },
    h('h2', { id: 'estop-dialog-h' }, 'Clear the e-stop?'),
    h('p', {}, 'Clearing re-arms the bench: the stimulator and the motor can be driven again by the next protocol ' +
      'anyone starts. The run the e-stop ended stays aborted; nothing restarts by itself.'),
    h('p', {}, 'Before clearing, check the subject (skin under the electrodes, discomfort), the electrodes and the leg ' +
      'fixation, and find out why the e-stop was pressed.'),
    h('label', { class: 'inline' }, check, ' I have checked the subject and the bench; it is safe to stimulate again.'),
    status,
    h('div', { class: 'actions' },
      h('button', { type: 'button', id: 'estop-keep', onclick: () => dialog.close() }, 'Keep latched'), confirm));
  check.addEventListener('change', () => { confirm.disabled = !check.checked; });
  confirm.addEventListener('click', async () => {
    confirm.disabled = true;
    try {
      await api('DELETE', '/bench/estop');
      dialog.close();
      await pollBench();
    } catch (e) {
      say(status, 'error', `Cannot clear the e-stop: ${e.message}`);
      confirm.disabled = !check.checked;
    }
  });
  dialog.addEventListener('close', () => dialog.remove());
  document.body.appendChild(dialog);
  dialog.showModal();
  document.getElementById('estop-keep').focus();
}

// --- the run bar ---------------------------------------------------------------
// The protocols that measure the max tolerated amplitude (GET /protocols,
// measures_max_tolerated): their run bar offers the subject's stop, which
// records it, before a cancel that records nothing.
let measuringMaxTolerated = new Set();
async function loadProtocolTraits() {
  const catalog = await api('GET', '/protocols').catch(() => null);
  if (!catalog) return;
  measuringMaxTolerated = new Set(catalog.protocols.filter((p) => p.measures_max_tolerated).map((p) => p.name));
}

let lastEnded = null; // {run_id, protocol, state, reason, session_id}: shown until dismissed

function renderRunBar(run) {
  const bar = document.getElementById('runbar');
  document.body.classList.toggle('run-active', !!run);
  if (run) {
    const { fraction, eta_s } = progressOf(run);
    const mayCancel = state.user && (state.user.role === 'clinician' || state.user.role === 'admin');
    let progress = bar.querySelector('#runbar-progress');
    if (!progress || bar.dataset.runId !== String(run.run_id)) {
      lastEnded = null;
      bar.dataset.runId = String(run.run_id);
      bar.dataset.state = run.state || 'running';
      progress = h('progress', { id: 'runbar-progress', max: 1, value: 0, 'aria-label': 'Run progress' });
      bar.replaceChildren(
        h('strong', { class: 'runbar-title' }, `Run ${run.run_id} in progress: `, h('span', { id: 'runbar-protocol' }, run.protocol || '')),
        progress,
        h('span', { id: 'runbar-text' }),
        h('span', { id: 'runbar-link' }),
        h('span', { id: 'runbar-owner', class: 'help' }),
        // A tolerance test: the subject's stop (recorded) first, in the bar too.
        mayCancel && measuringMaxTolerated.has(run.protocol)
          ? h('button', { type: 'button', class: 'primary small', id: 'runbar-stop', onclick: async (e) => {
            e.target.disabled = true;
            try {
              await api('POST', `/runs/${run.run_id}/stop`);
            } catch (err) {
              bar.querySelector('#runbar-owner').textContent = `Stop failed: ${err.message}`;
              e.target.disabled = false;
            }
          } }, 'Subject says stop')
          : '',
        mayCancel ? h('button', { type: 'button', class: measuringMaxTolerated.has(run.protocol) ? 'small' : 'danger small', id: 'runbar-cancel', onclick: async (e) => {
          e.target.disabled = true;
          try {
            await runs.cancel();
          } catch (err) {
            bar.querySelector('#runbar-owner').textContent = `Cancel failed: ${err.message}`;
            e.target.disabled = false;
          }
        } }, measuringMaxTolerated.has(run.protocol) ? 'Cancel (records nothing)' : 'Cancel run') : '');
    }
    bar.dataset.state = run.state || 'running';
    progress.value = fraction;
    bar.querySelector('#runbar-text').textContent =
      `${run.state || 'running'} · ${Math.round(fraction * 100)} % · ETA ${fmtDuration(eta_s)}`;
    const link = bar.querySelector('#runbar-link');
    if (run.session_id && !link.firstChild) {
      link.appendChild(h('a', { href: `#/sessions/${run.session_id}`, id: 'runbar-session' }, `Go to session ${run.session_id}`));
    }
    bar.querySelector('#runbar-owner').textContent = run.controlled ? '' : `controlled by ${run.owner || run.controller || 'another client'}`;
    bar.hidden = false;
    return;
  }
  if (lastEnded) {
    bar.dataset.runId = String(lastEnded.run_id);
    bar.dataset.state = lastEnded.state;
    bar.replaceChildren(
      h('span', { id: 'runbar-text', class: lastEnded.state === 'done' ? '' : 'runbar-bad' },
        `Run ${lastEnded.run_id} (${lastEnded.protocol}) ended: ${lastEnded.state}${lastEnded.reason ? ` — ${lastEnded.reason}` : ''}.`),
      lastEnded.session_id ? h('a', { href: `#/sessions/${lastEnded.session_id}` }, `Session ${lastEnded.session_id}`) : '',
      h('button', { type: 'button', class: 'link', id: 'runbar-dismiss', onclick: () => { lastEnded = null; renderRunBar(null); } }, 'Dismiss'));
    bar.hidden = false;
    return;
  }
  bar.hidden = true;
  bar.replaceChildren();
  delete bar.dataset.runId;
}

const runs = createRunController();
runs.onChange(renderRunBar);

async function noteEnd(runId) {
  const run = await api('GET', `/runs/${runId}`).catch(() => null);
  if (run && isFinal(run.state)) {
    lastEnded = { run_id: run.run_id, protocol: run.protocol, state: run.state, reason: run.reason, session_id: run.session_id };
    renderRunBar(runs.current);
  }
}

async function pollBench() {
  if (!state.user) {
    bench = null;
    showBench();
    return;
  }
  const generation = runs.generation;
  try {
    bench = await api('GET', '/bench');
  } catch {
    bench = null; // unknown, not idle; the banner says why
    showBench();
    return;
  }
  const st = benchStateOf(bench);
  if (runs.generation !== generation) {
    // A run was started or ended while this answer was on its way: the next
    // poll decides (an old answer must not end a run's heartbeat).
    showBench();
    return;
  }
  const active = st.run_id && !isFinal(st.run_state) && !runs.hasEnded(st.run_id) ? st : null;
  const current = runs.current;
  if (current && (!active || active.run_id !== current.run_id)) {
    const ended = current.run_id;
    runs.end();
    noteEnd(ended);
  }
  if (active) {
    const fields = { run_id: active.run_id, protocol: active.protocol, state: active.run_state || 'running',
      progress: active.progress, eta_s: active.eta_s, owner: active.owner };
    const mine = state.user && (active.owner_user_id === state.user.id ||
      (active.owner_user_id === undefined && active.owner === state.user.name));
    if (runs.current && runs.current.run_id === active.run_id) {
      runs.update(fields);
    } else if (mine && (state.user.role === 'clinician' || state.user.role === 'admin')) {
      // After a reload: the server says this user controls the run, so this
      // page takes the heartbeat over again, at once (the watchdog allows 1 s).
      runs.control(fields);
      const run = await api('GET', `/runs/${active.run_id}`).catch(() => null);
      if (run) runs.update({ session_id: run.session_id, state: run.state });
    } else {
      const run = await api('GET', `/runs/${active.run_id}`).catch(() => null);
      runs.observe({ ...fields, session_id: run ? run.session_id : undefined });
    }
  }
  showBench();
}

// --- start --------------------------------------------------------------------
async function start() {
  document.getElementById('estop').addEventListener('click', pressEstop);
  window.addEventListener('hashchange', route);
  if (getToken()) {
    try {
      await ctx.signIn(getToken());
    } catch {
      /* back to sign-in */
    }
  }
  renderChrome();
  await pollBench(); // before the first view: a run this user controls is re-attached at once
  await route();
  checkHealth();
  setInterval(checkHealth, 3000);
  setInterval(pollBench, 1000);
}

start();
