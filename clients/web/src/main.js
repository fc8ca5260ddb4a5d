// fesbench web client: layout (navigation, who is signed in, the e-stop
// button on every page, the connection banner) and the hash router.
import './style.css';
import { api, getToken, onConnectivity, setToken, UNREACHABLE_MESSAGE } from './api.js';
import { h } from './dom.js';
import { signInView } from './views/signin.js';
import { subjectsView, subjectView } from './views/subjects.js';
import { sessionView } from './views/session.js';
import { parameterSetView, compareView } from './views/paramset.js';
import { historyView } from './views/history.js';
import { predictionView } from './views/predict.js';

const state = { user: null, cleanup: [] };

const routes = [
  [/^#\/signin$/, () => signInView(ctx)],
  [/^#\/subjects$/, () => subjectsView(ctx)],
  [/^#\/subjects\/(\d+)$/, (m) => subjectView(ctx, Number(m[1]))],
  [/^#\/subjects\/(\d+)\/history$/, (m) => historyView(ctx, Number(m[1]))],
  [/^#\/sessions\/(\d+)$/, (m) => sessionView(ctx, Number(m[1]))],
  [/^#\/parameter-sets\/(\d+)$/, (m) => parameterSetView(ctx, Number(m[1]))],
  [/^#\/compare\/(\d+)\/(\d+)$/, (m) => compareView(ctx, Number(m[1]), Number(m[2]))],
  [/^#\/predict(?:\/(\d+))?$/, (m) => predictionView(ctx, m[1] ? Number(m[1]) : null)],
];

/// What views get: the main element, the user, and a way to register
/// cleanups (streams, timers) run when the page changes.
const ctx = {
  get user() {
    return state.user;
  },
  main: null,
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
    renderChrome();
  },
  signOut() {
    setToken('');
    state.user = null;
    renderChrome();
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
    h('li', {}, link('#/predict', 'Prediction'))));
  who.replaceChildren(
    h('span', { id: 'who-name' }, `Signed in as ${state.user.name}`),
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

// --- e-stop (every page) ------------------------------------------------------
const estopState = () => document.getElementById('estop-state');

function showBench(bench) {
  const slot = estopState();
  const st = bench && bench.state;
  document.body.classList.toggle('estopped', !!(st && st.estopped));
  if (!st) return;
  if (st.estopped) {
    const clear = h('button', { type: 'button', class: 'small', id: 'estop-clear',
      onclick: async () => {
        try {
          await api('DELETE', '/bench/estop');
          showBench(await api('GET', '/bench'));
        } catch (e) {
          slot.textContent = `Cannot clear the e-stop: ${e.message}`;
        }
      } }, 'Clear e-stop');
    slot.replaceChildren(h('strong', {}, 'E-STOP LATCHED'), ' ', clear);
  } else {
    slot.textContent = st.busy ? `Bench busy: ${st.protocol}` : 'Bench idle';
  }
}

async function pressEstop() {
  const slot = estopState();
  if (!getToken()) {
    slot.textContent = 'Sign in to send the e-stop; use the bench\'s hardware stop now.';
    return;
  }
  try {
    await api('POST', '/bench/estop');
    showBench(await api('GET', '/bench'));
  } catch (e) {
    slot.textContent = `E-STOP NOT CONFIRMED: ${e.message} Use the bench's hardware stop.`;
  }
}

async function pollBench() {
  if (!state.user) return;
  try {
    showBench(await api('GET', '/bench'));
  } catch {
    /* the banner says it */
  }
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
  await route();
  checkHealth();
  setInterval(checkHealth, 3000);
  setInterval(pollBench, 1000);
  pollBench();
}

start();
