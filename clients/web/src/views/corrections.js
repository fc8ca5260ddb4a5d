// Corrections as revisions (docs/API.md, "Corrections"): an edit form for a subject's or
// a session's details that PATCHes only what changed (an emptied field is
// cleared with null) with a required reason, and the revision history.
import { api } from '../api.js';
import { dateProblem, numberProblem } from '../checks.js';
import { clearErrors, field, fmt, h, say, showFieldError, showFieldErrors, table } from '../dom.js';

const REASON_MAX = 500;

const wide = (el) => {
  el.classList.add('field-wide');
  return el;
};

/// fields: [{name, label, type: 'number'|'text'|'date'|'textarea'|'select', options, min, max, unit,
/// integer}]; a field named 'date' is checked as YYYY-MM-DD.
/// current(): the details object now. path: '/subjects/3'. onSaved(updated).
export function correctionForm({ id, path, fields, current, onSaved, mayEdit }) {
  const status = h('div', { id: `${id}-status` });
  const valueOf = (f) => {
    const v = current()[f.name];
    return v === null || v === undefined ? '' : String(v);
  };
  const form = h('form', { id, novalidate: true, class: 'grid-form', onsubmit: async (event) => {
    event.preventDefault();
    clearErrors(form);
    const details = {};
    const problems = [];
    for (const f of fields) {
      const raw = form.elements[f.name].value.trim();
      if (raw === valueOf(f)) continue;
      if (raw === '') {
        details[f.name] = null;
        continue;
      }
      if (f.type === 'number') {
        const problem = numberProblem(f, raw);
        if (problem) problems.push({ field: f.name, message: problem });
        details[f.name] = Number(raw);
      } else if (f.name === 'date' && dateProblem(raw)) {
        problems.push({ field: f.name, message: dateProblem(raw) });
      } else {
        details[f.name] = raw;
      }
    }
    const reason = form.elements.reason.value.trim();
    if (!reason) problems.push({ field: 'reason', message: 'say why this is corrected (kept in the revision history)' });
    else if (reason.length > REASON_MAX) problems.push({ field: 'reason', message: `at most ${REASON_MAX} characters` });
    if (!problems.length && !Object.keys(details).length) {
      say(status, 'error', 'Nothing changed: edit a value first.');
      return;
    }
    if (problems.length) {
      showFieldErrors(form, problems);
      say(status, 'error', `Please correct the ${problems.length === 1 ? 'marked field' : `${problems.length} marked fields`}.`);
      return;
    }
    say(status, 'info', 'Saving the correction…');
    try {
      const updated = await api('PATCH', path, { reason, details });
      await onSaved(updated);
      box.refresh();
      form.elements.reason.value = '';
      say(status, 'ok', `Saved as revision ${updated.revision}.`);
    } catch (e) {
      const onField = showFieldError(form, e);
      say(status, 'error', onField ? `Please correct the marked field: ${e.message}` : `Not saved: ${e.message}`);
    }
  } },
  ...fields.map((f) => field(f.name, f.label, { type: f.type === 'select' ? undefined : f.type, options: f.options,
    value: valueOf(f), step: f.type === 'number' ? 'any' : undefined, help: f.help, idPrefix: `${id}-` })),
  wide(field('reason', 'Reason for the correction', { required: true, type: 'textarea', idPrefix: `${id}-`,
    help: 'kept with the revision, e.g. "body mass measured on the scale"' })),
  h('div', { class: 'actions' }, h('button', { type: 'submit', class: 'primary', disabled: !mayEdit }, 'Save correction'),
    mayEdit ? '' : h('small', {}, ' Only a clinician or an admin may correct records.')));
  const box = h('details', { class: 'edit', id: `${id}-box` }, h('summary', {}, 'Correct these details…'), form, status);
  /// Shows the current values again (after a save, or when the record changed
  /// elsewhere, e.g. a tolerance test): a later correction starts from them.
  box.refresh = () => {
    for (const f of fields) form.elements[f.name].value = valueOf(f);
  };
  return box;
}

/// The revision history (oldest first) as a table; `labels` names the detail keys.
export async function revisionHistory(path, labels, id) {
  const { items } = await api('GET', `${path}/revisions`);
  const describe = (rev, prev) => {
    const now = rev.details || {};
    const before = (prev && prev.details) || {};
    const changed = Object.keys(labels).filter((k) => JSON.stringify(now[k] ?? null) !== JSON.stringify(before[k] ?? null));
    if (!prev) return changed.filter((k) => now[k] !== '').map((k) => `${labels[k]} ${fmt(now[k])}`).join('; ') || '—';
    return changed.map((k) => `${labels[k]}: ${fmt(before[k] ?? null)} → ${fmt(now[k] ?? null)}`).join('; ') || 'no change';
  };
  return h('details', { class: 'revisions', id, open: items.length > 1 },
    h('summary', {}, `Revision history (${items.length})`),
    table(['Revision', 'When (UTC)', 'By', 'Reason', 'Values'], items.map((r, i) => [
      String(r.revision), (r.changed_at_utc || '').slice(0, 19).replace('T', ' '), r.changed_by || '—',
      r.reason || (i === 0 ? 'created' : '—'), describe(r, items[i - 1])]), { id: `${id}-table` }));
}
