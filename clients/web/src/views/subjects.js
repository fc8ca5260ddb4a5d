// Subjects: list, search by code, create; one subject: its sessions (list,
// create), its parameter sets (open, compare two, history).
import { api, listAll } from '../api.js';
import { clearErrors, field, fmt, fmtFixed, h, message, say, showFieldError, showFieldErrors, table, todayIso } from '../dom.js';
import { codeProblem, dateProblem, numberProblem, sessionProblems, SUBJECT_LIMITS } from '../checks.js';
import { correctionForm, revisionHistory } from './corrections.js';

const SEX_OPTIONS = [{ value: '', label: '(not given)' }, { value: 'female', label: 'female' },
  { value: 'male', label: 'male' }, { value: 'other', label: 'other' }, { value: 'undisclosed', label: 'undisclosed' }];

export const SUBJECT_FIELDS = [
  { name: 'age_years', label: 'Age (years)', type: 'number', ...SUBJECT_LIMITS.age_years },
  { name: 'sex', label: 'Sex', type: 'select', options: SEX_OPTIONS },
  { name: 'height_cm', label: 'Height (cm)', type: 'number', ...SUBJECT_LIMITS.height_cm },
  { name: 'weight_kg', label: 'Body mass (kg)', type: 'number', ...SUBJECT_LIMITS.weight_kg,
    help: 'with the shank length gives the leg inertia (Eq. 4.13)' },
  { name: 'shank_length_cm', label: 'Shank length (cm)', type: 'number', ...SUBJECT_LIMITS.shank_length_cm,
    help: 'femoral condyle to medial malleolus' },
  { name: 'calf_circumference_cm', label: 'Calf circumference (cm)', type: 'number', ...SUBJECT_LIMITS.calf_circumference_cm },
  { name: 'rom_min_deg', label: 'Range of motion, extension (°)', type: 'number', ...SUBJECT_LIMITS.rom_min_deg,
    help: 'the knee\'s own limit, hyperextension negative; the bench never moves it beyond' },
  { name: 'rom_max_deg', label: 'Range of motion, flexion (°)', type: 'number', ...SUBJECT_LIMITS.rom_max_deg,
    help: 'give both ends or neither' },
];
const SUBJECT_LABELS = Object.fromEntries(SUBJECT_FIELDS.map((f) => [f.name, f.label]));

/// "right" / "left" for a leg id of this subject (never the internal id).
export function legSide(subject, legId) {
  const leg = subject && subject.legs.find((l) => l.id === legId);
  return leg ? leg.side : 'unknown leg';
}

async function submitForm(form, status, send, success) {
  clearErrors(form);
  say(status, 'info', 'Saving…');
  try {
    const created = await send();
    say(status, 'ok', success(created));
    return created;
  } catch (e) {
    const onField = showFieldError(form, e);
    say(status, 'error', onField ? `Please correct the marked field: ${e.message}` : e.message);
    return null;
  }
}

function subjectRows(subjects) {
  return subjects.map((s) => [
    h('a', { href: `#/subjects/${s.id}` }, s.code),
    s.legs.map((l) => l.side).join(', ') || '—',
    fmt(s.details.age_years),
    s.details.sex || '—',
    fmt(s.details.weight_kg),
    s.created_at_utc.slice(0, 10),
  ]);
}

export async function subjectsView(ctx) {
  const listSlot = h('div', { id: 'subject-list' });
  const listStatus = h('div');
  const search = h('input', { id: 'subject-search', name: 'code', type: 'search', placeholder: 'e.g. S01' });

  async function load() {
    const code = search.value.trim();
    try {
      const subjects = code
        ? (await api('GET', `/subjects?code=${encodeURIComponent(code)}`)).items
        : await listAll('/subjects');
      say(listStatus, '', '');
      listSlot.replaceChildren(subjects.length
        ? table(['Code', 'Legs', 'Age', 'Sex', 'Weight (kg)', 'Created'], subjectRows(subjects), { id: 'subjects-table' })
        : h('p', {}, code ? `No subject with code ${code}.` : 'No subjects yet.'));
    } catch (e) {
      say(listStatus, 'error', e.message);
    }
  }

  const status = h('div', { id: 'subject-form-status' });
  const form = h('form', { id: 'subject-form', novalidate: true, class: 'grid-form', onsubmit: async (event) => {
    event.preventDefault();
    const f = event.target;
    const details = {};
    const problems = [];
    const codeMessage = codeProblem(f.elements.code.value.trim());
    if (codeMessage) problems.push({ field: 'code', message: codeMessage });
    for (const spec of SUBJECT_FIELDS.filter((x) => x.type === 'number')) {
      const raw = f.elements[spec.name].value.trim();
      const problem = numberProblem(spec, raw);
      if (problem) problems.push({ field: spec.name, message: problem });
      else if (raw !== '') details[spec.name] = Number(raw);
    }
    clearErrors(f);
    if (problems.length) {
      showFieldErrors(f, problems);
      say(status, 'error', `Please correct the ${problems.length === 1 ? 'marked field' : `${problems.length} marked fields`}.`);
      return;
    }
    if (f.elements.sex.value) details.sex = f.elements.sex.value;
    const legs = ['left', 'right'].filter((side) => f.elements[`leg_${side}`].checked);
    const created = await submitForm(f, status,
      () => api('POST', '/subjects', { code: f.elements.code.value.trim(), details, legs }),
      (s) => `Subject ${s.code} created.`);
    if (created) {
      f.reset();
      await load();
    }
  } },
  field('code', 'Pseudonymous code', { required: true, help: 'letters, digits, _ and - (no names)' }),
  field('age_years', 'Age (years)', { type: 'number' }),
  field('sex', 'Sex', { options: SEX_OPTIONS }),
  field('height_cm', 'Height (cm)', { type: 'number' }),
  field('weight_kg', 'Body mass (kg)', { type: 'number' }),
  field('shank_length_cm', 'Shank length (cm)', { type: 'number' }),
  field('calf_circumference_cm', 'Calf circumference (cm)', { type: 'number' }),
  field('rom_min_deg', 'Range of motion, extension (°)', { type: 'number', help: 'hyperextension negative, e.g. -10' }),
  field('rom_max_deg', 'Range of motion, flexion (°)', { type: 'number', help: 'e.g. 140; give both ends or neither' }),
  h('fieldset', { class: 'field' }, h('legend', {}, 'Legs'),
    h('label', { class: 'inline' }, h('input', { type: 'checkbox', name: 'leg_left' }), ' left'),
    h('label', { class: 'inline' }, h('input', { type: 'checkbox', name: 'leg_right', checked: true }), ' right')),
  h('div', { class: 'actions' }, h('button', { type: 'submit', class: 'primary' }, 'Create subject')));

  const searchForm = h('form', { role: 'search', class: 'row', onsubmit: (e) => { e.preventDefault(); load(); } },
    h('label', { for: 'subject-search' }, 'Find by code'), search,
    h('button', { type: 'submit' }, 'Search'),
    h('button', { type: 'button', onclick: () => { search.value = ''; load(); } }, 'Show all'));

  ctx.main.replaceChildren(
    h('h1', {}, 'Subjects'),
    h('section', { 'aria-labelledby': 'list-h' }, h('h2', { id: 'list-h' }, 'All subjects'), searchForm, listStatus, listSlot),
    h('section', { 'aria-labelledby': 'new-h' }, h('h2', { id: 'new-h' }, 'New subject'), form, status));
  await load();
}

export async function subjectView(ctx, subjectId) {
  let subject = await api('GET', `/subjects/${subjectId}`);
  const mayEdit = ctx.user.role === 'clinician' || ctx.user.role === 'admin';
  const sessionsSlot = h('div', { id: 'session-list' });
  const setsSlot = h('div', { id: 'set-list' });

  async function loadSessions() {
    const sessions = await listAll(`/subjects/${subjectId}/sessions`);
    sessionsSlot.replaceChildren(sessions.length
      ? table(['Session', 'Date', 'Leg', 'Threshold, tolerance test (mA)', 'Max tolerated (mA)', 'Accelerometer'],
        sessions.map((s) => [h('a', { href: `#/sessions/${s.id}` }, `Session ${s.id}`), s.date, s.leg,
          fmtFixed(s.details.threshold_ma, 1), fmtFixed(s.details.max_tolerated_ma, 1), s.details.accelerometer_placement || '—']),
        { id: 'sessions-table' })
      : h('p', {}, 'No sessions yet.'));
  }

  async function loadSets() {
    const sets = await listAll(`/parameter-sets?subject_id=${subjectId}`);
    if (!sets.length) {
      setsSlot.replaceChildren(h('p', {}, 'No parameter sets yet: run the rapid parameterisation in a session.'));
      return;
    }
    const options = sets.map((s) => h('option', { value: s.id }, `#${s.id} v${s.version} ${s.created_at_utc.slice(0, 16).replace('T', ' ')}`));
    const a = h('select', { id: 'compare-a', name: 'a' }, options.map((o) => o.cloneNode(true)));
    const b = h('select', { id: 'compare-b', name: 'b' }, options.map((o) => o.cloneNode(true)));
    if (sets.length > 1) b.selectedIndex = 1;
    setsSlot.replaceChildren(
      table(['Set', 'Created', 'Leg', 'Model', 'Methods'], sets.map((s) => [
        h('a', { href: `#/parameter-sets/${s.id}` }, `Parameter set ${s.id}`),
        s.created_at_utc.slice(0, 19).replace('T', ' '), legSide(subject, s.leg_id), s.model,
        `${s.irc_method}, ${s.passive_method}, ${s.active_method}`]), { id: 'sets-table' }),
      h('p', {}, h('a', { href: `#/subjects/${subjectId}/history`, id: 'history-link' }, 'Parameter history over time')),
      h('form', { class: 'row', id: 'compare-form', onsubmit: (e) => { e.preventDefault(); location.hash = `#/compare/${a.value}/${b.value}`; } },
        h('label', { for: 'compare-a' }, 'Compare'), a, h('label', { for: 'compare-b' }, 'with'), b,
        h('button', { type: 'submit' }, 'Compare')));
  }

  const status = h('div', { id: 'session-form-status' });
  const legOptions = (subject.legs.length ? subject.legs.map((l) => l.side) : ['right', 'left'])
    .map((side) => ({ value: side, label: side }));
  const form = h('form', { id: 'session-form', novalidate: true, class: 'grid-form', onsubmit: async (event) => {
    event.preventDefault();
    const f = event.target;
    const body = { leg: f.elements.leg.value, date: f.elements.date.value.trim() };
    const values = {};
    for (const name of ['threshold_ma', 'max_tolerated_ma']) values[name] = f.elements[name].value.trim();
    const problems = sessionProblems(values);
    const dateMessage = dateProblem(body.date);
    if (dateMessage) problems.unshift({ field: 'date', message: dateMessage });
    clearErrors(f);
    if (problems.length) {
      showFieldErrors(f, problems);
      say(status, 'error', `Please correct the ${problems.length === 1 ? 'marked field' : `${problems.length} marked fields`}.`);
      return;
    }
    for (const name of ['threshold_ma', 'max_tolerated_ma']) {
      if (values[name] !== '') body[name] = Number(values[name]);
    }
    if (f.elements.accelerometer_placement.value.trim()) body.accelerometer_placement = f.elements.accelerometer_placement.value.trim();
    if (f.elements.notes.value.trim()) body.notes = f.elements.notes.value.trim();
    const created = await submitForm(f, status, () => api('POST', `/subjects/${subjectId}/sessions`, body),
      (s) => `Session ${s.id} opened.`);
    // "Open session" opens it: the session's page (a second click on a
    // still-filled form would make a duplicate).
    if (created) location.hash = `#/sessions/${created.id}`;
  } },
  field('leg', 'Leg', { options: legOptions }),
  field('date', 'Date (YYYY-MM-DD)', { value: todayIso(), required: true }),
  field('threshold_ma', 'Stimulation threshold (mA)', { type: 'number',
    help: 'leave empty: the tolerance test records it in the session' }),
  field('max_tolerated_ma', 'Max tolerated (mA)', { type: 'number',
    help: 'leave empty: the tolerance test records it in the session' }),
  field('accelerometer_placement', 'Accelerometer placement', { help: 'e.g. 20 cm below the knee, lateral' }),
  field('notes', 'Notes', { type: 'textarea' }),
  h('div', { class: 'actions' }, h('button', { type: 'submit', class: 'primary' }, 'Open session')));

  const detailsSlot = h('div', { id: 'subject-details-box' });
  const subjectPath = `/subjects/${subjectId}`;
  const editForm = correctionForm({ id: 'subject-edit', path: subjectPath, fields: SUBJECT_FIELDS, mayEdit,
    current: () => subject.details,
    onSaved: async () => {
      subject = await api('GET', subjectPath);
      await renderDetails();
    } });
  async function renderDetails() {
    const d = subject.details;
    detailsSlot.replaceChildren(
      table(['Field', 'Value'], [
        ['Legs', subject.legs.map((l) => l.side).join(', ') || '—'], ['Age (years)', fmt(d.age_years)], ['Sex', d.sex || '—'],
        ['Height (cm)', fmt(d.height_cm)], ['Body mass (kg)', fmt(d.weight_kg)], ['Shank length (cm)', fmt(d.shank_length_cm)],
        ['Calf circumference (cm)', fmt(d.calf_circumference_cm)],
        ['Range of motion (°)', d.rom_min_deg == null ? '— (the bench\'s)' : `${fmt(d.rom_min_deg)} to ${fmt(d.rom_max_deg)}`],
        ['Revision', String(subject.revision ?? 1)]],
      { class: 'kv', id: 'subject-details' }),
      editForm,
      await revisionHistory(subjectPath, SUBJECT_LABELS, 'subject-revisions').catch((e) => message('error', `Revision history unavailable: ${e.message}`)));
  }
  ctx.main.replaceChildren(
    h('p', { class: 'crumbs' }, h('a', { href: '#/subjects' }, 'Subjects'), ' › ', subject.code),
    h('h1', {}, `Subject ${subject.code}`),
    detailsSlot,
    h('section', { 'aria-labelledby': 'sess-h' }, h('h2', { id: 'sess-h' }, 'Sessions'), sessionsSlot),
    h('section', { 'aria-labelledby': 'newsess-h' }, h('h2', { id: 'newsess-h' }, 'New session'), form, status),
    h('section', { 'aria-labelledby': 'sets-h' }, h('h2', { id: 'sets-h' }, 'Parameter sets'), setsSlot));
  await Promise.all([renderDetails(), loadSessions(), loadSets()]);
}
