// Sign in with a bearer token; shows who is signed in and with which role.
import { h, message, say } from '../dom.js';

export async function signInView(ctx) {
  const status = h('div', { id: 'signin-status' });
  const input = h('input', { id: 'token', name: 'token', type: 'password', autocomplete: 'off',
    required: true, 'aria-describedby': 'token-help', spellcheck: 'false' });
  const form = h('form', { id: 'signin-form', novalidate: true, onsubmit: async (event) => {
    event.preventDefault();
    const token = input.value.trim();
    if (!token) {
      say(status, 'error', 'Enter your token.');
      input.focus();
      return;
    }
    say(status, 'info', 'Checking the token…');
    try {
      await ctx.signIn(token);
      location.hash = '#/subjects';
    } catch (e) {
      say(status, 'error', e.code === 'unreachable' ? e.message : `Sign-in failed: ${e.message}`);
      input.focus();
    }
  } },
  h('div', { class: 'field' },
    h('label', { for: 'token' }, 'Access token'),
    input,
    h('small', { id: 'token-help', class: 'help' },
      'Your administrator gives you a token (it starts with fsb_). It is kept only in this browser tab.')),
  h('button', { type: 'submit', class: 'primary' }, 'Sign in'));
  ctx.main.replaceChildren(h('h1', {}, 'Sign in'),
    ctx.user ? message('info', `Signed in as ${ctx.user.name} (${ctx.user.role}).`) : '',
    form, status);
  input.focus();
}
