// Small DOM helpers: element builder, messages, form errors, number format.

/// h('div', {class: 'x', onclick: fn}, child, 'text', ...)
export function h(tag, attrs = {}, ...children) {
  const el = document.createElement(tag);
  for (const [key, value] of Object.entries(attrs || {})) {
    if (value === undefined || value === null || value === false) continue;
    if (key.startsWith('on') && typeof value === 'function') el.addEventListener(key.slice(2), value);
    else if (key === 'class') el.className = value;
    else if (key === 'dataset') Object.assign(el.dataset, value);
    else if (value === true) el.setAttribute(key, '');
    else el.setAttribute(key, String(value));
  }
  for (const child of children.flat()) {
    if (child === null || child === undefined || child === false) continue;
    el.appendChild(child instanceof Node ? child : document.createTextNode(String(child)));
  }
  return el;
}

export function fmt(value, digits = 3) {
  if (value === null || value === undefined || Number.isNaN(value)) return '—';
  if (typeof value !== 'number') return String(value);
  if (Number.isInteger(value)) return String(value);
  return value.toPrecision(digits);
}

/// Clinical number formats: a fixed number of decimals (mA, degrees and
/// N·m to 0.1) and the unit, '—' for a missing value.
export function fmtFixed(value, decimals, unit = '') {
  if (value === null || value === undefined || !Number.isFinite(value)) return '—';
  return `${value.toFixed(decimals)}${unit ? (unit === '°' || unit === '%' ? unit : ` ${unit}`) : ''}`;
}
export const fmtMa = (v) => fmtFixed(v, 1, 'mA');
export const fmtDeg = (v) => fmtFixed(v, 1, '°');
export const fmtNm = (v) => fmtFixed(v, 1, 'N·m');

export function fmtDuration(seconds) {
  if (!Number.isFinite(seconds)) return '—';
  const s = Math.max(0, Math.round(seconds));
  return s >= 60 ? `${Math.floor(s / 60)} min ${s % 60} s` : `${s} s`;
}

/// A message box: kind 'error' | 'ok' | 'info'.
export function message(kind, text) {
  return h('p', { class: `msg msg-${kind}`, role: kind === 'error' ? 'alert' : 'status' }, text);
}

/// Replaces the contents of `slot` with a message.
export function say(slot, kind, text) {
  slot.replaceChildren(text ? message(kind, text) : '');
}

/// A labelled input row. options: {type, value, step, help, required, options (select),
/// idPrefix (default 'f-': the input's id is prefix + name)}.
export function field(name, label, options = {}) {
  const id = `${options.idPrefix || 'f-'}${name.replace(/[^a-z0-9_-]/gi, '-')}`;
  let input;
  if (options.options) {
    input = h('select', { id, name },
      options.options.map((o) => h('option', { value: o.value, selected: o.value === options.value }, o.label)));
  } else if (options.type === 'textarea') {
    input = h('textarea', { id, name, rows: 2 }, options.value ?? '');
  } else {
    input = h('input', { id, name, type: options.type || 'text', value: options.value ?? '',
      step: options.step, inputmode: options.type === 'number' ? 'decimal' : undefined,
      autocomplete: 'off' });
  }
  const errorId = `${id}-error`;
  input.setAttribute('aria-describedby', errorId);
  return h('div', { class: 'field' },
    h('label', { for: id }, label, options.required ? h('span', { class: 'req', 'aria-hidden': 'true' }, ' *') : ''),
    input,
    options.help ? h('small', { class: 'help' }, options.help) : '',
    h('span', { class: 'field-error', id: errorId, 'aria-live': 'polite' }));
}

/// Clears the field messages of a form.
export function clearErrors(form) {
  for (const e of form.querySelectorAll('.field-error')) e.textContent = '';
  for (const e of form.querySelectorAll('[aria-invalid]')) e.removeAttribute('aria-invalid');
}

/// Shows a server error beside the field it names (field path "details.age_years",
/// "parameters.max_ma", … matched by full name, then by its last part); returns
/// true if a field was found. Focuses that field.
export function showFieldError(form, error) {
  if (!error.field) return false;
  const last = error.field.split('.').pop().replace(/\[\d+\]$/, '');
  const input = form.querySelector(`[name="${CSS.escape(error.field)}"]`) ||
    form.querySelector(`[name="${CSS.escape(last)}"]`);
  if (!input) return false;
  input.setAttribute('aria-invalid', 'true');
  const slot = form.querySelector(`#${CSS.escape(input.id)}-error`);
  if (slot) slot.textContent = error.message;
  input.focus();
  return true;
}

/// Shows every problem of a client-side check at once ([{field, message}]);
/// focuses the first marked field.
export function showFieldErrors(form, problems) {
  let first = null;
  for (const p of problems) {
    const input = form.querySelector(`[name="${CSS.escape(p.field)}"]`);
    if (!input) continue;
    input.setAttribute('aria-invalid', 'true');
    const slot = form.querySelector(`#${CSS.escape(input.id)}-error`);
    if (slot) slot.textContent = p.message;
    first = first || input;
  }
  if (first) first.focus();
}

/// A table from rows of cells; first row is the header.
export function table(header, rows, attrs = {}) {
  return h('table', attrs,
    h('thead', {}, h('tr', {}, header.map((c) => h('th', { scope: 'col' }, c)))),
    h('tbody', {}, rows.map((r) => h('tr', {}, r.map((c, i) => (i === 0 ? h('th', { scope: 'row' }, c) : h('td', {}, c)))))));
}

export function todayIso() {
  const d = new Date();
  const pad = (n) => String(n).padStart(2, '0');
  return `${d.getFullYear()}-${pad(d.getMonth() + 1)}-${pad(d.getDate())}`;
}
