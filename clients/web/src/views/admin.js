// Users and tokens, for an admin (docs/API.md, users and tokens): add a
// user with a role, deactivate one (their tokens stop working), issue a
// token (its secret shown once, here only) and revoke one.
import { api, listAll } from '../api.js';
import { clearErrors, field, h, say, showFieldError, table } from '../dom.js';

const utc = (iso) => (iso ? iso.slice(0, 19).replace('T', ' ') : '—');
const ROLES = [
  { value: 'clinician', label: 'clinician (runs the bench, approves sets)' },
  { value: 'analyst', label: 'analyst (identifies and compares models)' },
  { value: 'admin', label: 'admin (users, tokens, backups)' },
];

export async function adminView(ctx) {
  if (ctx.user.role !== 'admin') {
    ctx.main.replaceChildren(h('h1', {}, 'Users and tokens'),
      h('p', { class: 'msg msg-info' }, 'Only an admin issues users and tokens.'));
    return;
  }
  const usersSlot = h('div', { id: 'users-list' });
  const tokensSlot = h('div', { id: 'tokens-list' });
  const secretSlot = h('div', { id: 'token-secret', 'aria-live': 'polite' });
  let users = [];

  async function load() {
    const [u, t] = await Promise.all([listAll('/users'), listAll('/tokens')]);
    users = u;
    usersSlot.replaceChildren(table(['User', 'Role', 'Active', 'Created (UTC)', ''], u.map((x) => [
      `${x.id}: ${x.name}`, x.role, x.active ? 'yes' : 'no', utc(x.created_at_utc),
      x.active && x.id !== ctx.user.id
        ? h('button', { type: 'button', class: 'small', 'data-deactivate': String(x.id), 'aria-label': `Deactivate ${x.name}`,
          onclick: () => deactivate(x) }, 'Deactivate…')
        : '']), { id: 'users-table' }));
    tokensSlot.replaceChildren(table(['Token', 'User', 'Label', 'Created (UTC)', 'Expires (UTC)', 'State', ''], t.map((x) => [
      String(x.id), x.user_name, x.label || '—', utc(x.created_at_utc), x.expires_at_utc ? utc(x.expires_at_utc) : 'never',
      x.revoked ? `revoked ${utc(x.revoked_at_utc)}` : 'valid',
      x.revoked ? '' : h('button', { type: 'button', class: 'small danger', 'data-revoke': String(x.id),
        'aria-label': `Revoke token ${x.id} of ${x.user_name}`, onclick: () => revoke(x) }, 'Revoke')]), { id: 'tokens-table' }));
    tokenForm.elements.user_id.replaceChildren(...users.filter((x) => x.active).map((x) =>
      h('option', { value: x.id }, `${x.name} (${x.role})`)));
  }

  async function deactivate(user) {
    const reason = window.prompt(`Why is ${user.name} deactivated? (kept in the audit log)`);
    if (!reason) return;
    try {
      await api('POST', `/users/${user.id}/deactivate`, { reason });
      say(status, 'ok', `${user.name} is deactivated; their tokens no longer work.`);
      await load();
    } catch (e) {
      say(status, 'error', e.message);
    }
  }

  async function revoke(token) {
    try {
      await api('DELETE', `/tokens/${token.id}`);
      say(status, 'ok', `Token ${token.id} of ${token.user_name} is revoked.`);
      await load();
    } catch (e) {
      say(status, 'error', e.message);
    }
  }

  const status = h('div', { id: 'admin-status' });
  const userForm = h('form', { id: 'user-form', novalidate: true },
    h('div', { class: 'grid-form' },
      field('name', 'Name', { required: true, idPrefix: 'user-' }),
      field('role', 'Role', { options: ROLES, idPrefix: 'user-' })),
    h('div', { class: 'actions' }, h('button', { type: 'submit', class: 'primary' }, 'Add user')));
  userForm.addEventListener('submit', async (ev) => {
    ev.preventDefault();
    clearErrors(userForm);
    try {
      const user = await api('POST', '/users', { name: userForm.elements.name.value.trim(), role: userForm.elements.role.value });
      say(status, 'ok', `User ${user.name} (${user.role}) added: issue them a token below.`);
      userForm.reset();
      await load();
      tokenForm.elements.user_id.value = String(user.id);
    } catch (e) {
      if (!showFieldError(userForm, e)) say(status, 'error', e.message);
    }
  });

  const tokenForm = h('form', { id: 'token-form', novalidate: true },
    h('div', { class: 'grid-form' },
      h('div', { class: 'field' }, h('label', { for: 'token-user' }, 'For user'), h('select', { id: 'token-user', name: 'user_id' })),
      field('label', 'Label (e.g. the workstation)', { idPrefix: 'token-' }),
      field('expires_in_days', 'Expires after (days; empty: never)', { type: 'number', step: 1, idPrefix: 'token-' })),
    h('div', { class: 'actions' }, h('button', { type: 'submit', class: 'primary' }, 'Issue token')));
  tokenForm.addEventListener('submit', async (ev) => {
    ev.preventDefault();
    clearErrors(tokenForm);
    const body = { user_id: Number(tokenForm.elements.user_id.value) };
    const label = tokenForm.elements.label.value.trim();
    if (label) body.label = label;
    const days = tokenForm.elements.expires_in_days.value.trim();
    if (days) {
      const n = Number(days);
      if (!Number.isInteger(n) || n < 1) {
        showFieldError(tokenForm, { field: 'expires_in_days', message: 'a whole number of days, at least 1' });
        return;
      }
      body.expires_in_s = n * 86400;
    }
    try {
      const issued = await api('POST', '/tokens', body);
      const user = users.find((x) => x.id === issued.user_id);
      const secret = h('input', { type: 'text', id: 'token-secret-value', readonly: true, value: issued.token,
        'aria-label': 'The new token (shown once)', size: Math.min(issued.token.length, 60) });
      secretSlot.replaceChildren(h('div', { class: 'msg msg-ok', role: 'status' },
        h('p', {}, h('strong', {}, `Token ${issued.id} for ${user ? user.name : `user ${issued.user_id}`}. `),
          'Copy it now and give it to them: it is shown only this once and cannot be read again.'),
        secret,
        h('button', { type: 'button', class: 'small', onclick: async () => {
          secret.select();
          await navigator.clipboard?.writeText(issued.token).catch(() => {});
        } }, 'Copy'),
        h('button', { type: 'button', class: 'small link', onclick: () => secretSlot.replaceChildren() }, 'I have copied it: hide')));
      secret.select();
      await load();
    } catch (e) {
      if (!showFieldError(tokenForm, e)) say(status, 'error', e.message);
    }
  });

  ctx.main.replaceChildren(
    h('h1', {}, 'Users and tokens'),
    status,
    h('section', { 'aria-labelledby': 'users-h' }, h('h2', { id: 'users-h' }, 'Users'), usersSlot,
      h('h3', {}, 'Add a user'), userForm),
    h('section', { 'aria-labelledby': 'tokens-h' }, h('h2', { id: 'tokens-h' }, 'Tokens'),
      h('p', {}, 'A token signs a person in (the web page, the fesbench command line, the Python client). Revoking it signs them out everywhere it is used.'),
      tokenForm, secretSlot, tokensSlot));
  await load();
}
