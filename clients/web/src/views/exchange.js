// Data in and out of a session: export the whole session (an archive laid
// out after BIDS), import a recording made elsewhere (CSV, TSV, OpenSim
// .sto with its trial kind and column mapping) or a session archive.

import { api, authHeaders, download, upload } from '../api.js';
import { field, h, say, table } from '../dom.js';

const ARCHIVE = /\.(zip|tar\.gz|tgz)$/i;

/// "COLUMN=CHANNEL[:UNIT]" lines → the spec's columns; throws naming the line.
export function parseMappings(text) {
  const columns = [];
  text.split('\n').map((l) => l.trim()).forEach((line, i) => {
    if (!line) return;
    const eq = line.lastIndexOf('=');
    if (eq <= 0 || eq === line.length - 1) {
      throw new Error(`Mapping line ${i + 1}: write COLUMN=CHANNEL or COLUMN=CHANNEL:UNIT, e.g. knee_angle_r=angle_deg:rad.`);
    }
    const [channel, unit] = line.slice(eq + 1).split(':');
    columns.push(unit ? { column: line.slice(0, eq), channel, unit } : { column: line.slice(0, eq), channel });
  });
  return columns;
}

/// The section; `onImported()` reloads the session's trial list.
export async function exchangeSection(sessionId, onImported) {
  const status = h('div', { id: 'exchange-status' });
  const result = h('div', { id: 'import-result' });
  const exportButton = (format) => h('button', {
    type: 'button', class: 'small', id: `export-${format.replace('.', '')}`,
    onclick: async () => {
      say(status, 'info', 'Preparing the archive…');
      try {
        const name = await download(`/sessions/${sessionId}/export?format=${format}`, `fesbench-session-${sessionId}.${format}`);
        say(status, 'ok', `Downloaded ${name}: trials (BIDS motion/EMG TSV), pulses, parameter sets, run log, README.`);
      } catch (e) {
        say(status, 'error', e.message);
      }
    },
  }, `Export session (.${format})`);

  // The report opens in a new tab (a link cannot carry the token: fetched,
  // then shown from a blob); print it to PDF from there.
  const reportButton = h('button', {
    type: 'button', class: 'small', id: 'open-report',
    onclick: async () => {
      const tab = window.open('', '_blank');
      say(status, 'info', 'Preparing the report…');
      try {
        const res = await fetch(`/api/v1/sessions/${sessionId}/report`, { headers: authHeaders(), cache: 'no-store' });
        if (!res.ok) throw new Error(`the server answered ${res.status}`);
        const url = URL.createObjectURL(await res.blob());
        if (tab) tab.location = url;
        else window.location = url;
        say(status, 'ok', 'The report opened in a new tab; print it to PDF to file it.');
      } catch (e) {
        if (tab) tab.close();
        say(status, 'error', `No report: ${e.message}`);
      }
    },
  }, 'Session report');

  let kinds = [];
  try {
    kinds = (await api('GET', '/trial-kinds')).items;
  } catch {
    kinds = [];
  }
  const form = h('form', { id: 'import-form', novalidate: true },
    field('import_file', 'Recording or session archive', { type: 'file',
      help: 'CSV, TSV or OpenSim .sto; or a .zip / .tar.gz exported from a fesbench session' }),
    field('import_kind', 'Trial kind', { options: kinds.map((k) => ({ value: k.name, label: `${k.name} — needs ${k.required_channels.join(', ')}` })),
      help: 'what the recording is; identification and prediction use it like a bench trial' }),
    field('import_time_column', 'Time column', { help: 'default t_s (CSV, TSV) or time (.sto)' }),
    field('import_time_unit', 'Time unit', { options: ['s', 'ms', 'us'].map((u) => ({ value: u, label: u })) }),
    field('import_rate', 'Sample rate (Hz)', { type: 'number', help: 'optional: checked against the time column' }),
    field('import_columns', 'Column mapping', { type: 'textarea',
      help: 'one per line: COLUMN=CHANNEL or COLUMN=CHANNEL:UNIT (e.g. knee_angle_r=angle_deg:rad, Torque=torque_nm:N.mm)' }),
    field('import_ignore', 'Columns to leave out', { help: 'comma-separated' }),
    field('import_source', 'Source', { help: 'where it was recorded (kept with the trial)' }),
    h('button', { type: 'submit', id: 'import-submit' }, 'Import'));
  form.querySelector('#f-import_file').setAttribute('accept', '.csv,.tsv,.sto,.mot,.txt,.zip,.gz,.tgz');

  form.addEventListener('submit', async (e) => {
    e.preventDefault();
    say(result, '', '');
    const file = form.querySelector('#f-import_file').files[0];
    if (!file) {
      say(status, 'error', 'Choose a file to import.');
      return;
    }
    say(status, 'info', `Importing ${file.name}…`);
    try {
      let answer;
      if (ARCHIVE.test(file.name)) {
        const type = /\.zip$/i.test(file.name) ? 'application/zip' : 'application/gzip';
        answer = await upload(`/sessions/${sessionId}/trials?name=${encodeURIComponent(file.name)}`, file, type);
      } else {
        const value = (id) => form.querySelector(`#f-${id}`).value.trim();
        const format = /\.(sto|mot)$/i.test(file.name) ? 'sto' : /\.tsv$/i.test(file.name) ? 'tsv' : 'csv';
        const spec = { kind: value('import_kind'), format, time_unit: value('import_time_unit'),
          columns: parseMappings(value('import_columns')), source: value('import_source') || file.name };
        if (value('import_time_column')) spec.time_column = value('import_time_column');
        if (value('import_rate')) spec.sample_rate_hz = Number(value('import_rate'));
        if (value('import_ignore')) spec.ignore = value('import_ignore').split(',').map((s) => s.trim()).filter(Boolean);
        answer = await api('POST', `/sessions/${sessionId}/trials`, { spec, data: await file.text() });
      }
      const rows = [
        ...answer.trials.map((t) => ['trial', String(t.id), t.name, t.original_id ?? '—']),
        ...answer.parameter_sets.map((s) => ['parameter set', String(s.id), s.name, s.original_id ?? '—']),
      ];
      result.replaceChildren(table(['Imported', 'Id', 'Name', 'Original id'], rows, { id: 'import-table' }),
        ...answer.notes.map((n) => h('p', { class: 'help' }, n)));
      say(status, 'ok', `Imported ${answer.trials.length} trial(s) from ${file.name}.`);
      await onImported();
    } catch (err) {
      say(status, 'error', `Not imported: ${err.message}`);
    }
  });

  return h('section', { 'aria-labelledby': 'exchange-h', id: 'exchange' },
    h('h2', { id: 'exchange-h' }, 'Data in and out'),
    h('p', {}, reportButton, ' ', exportButton('zip'), ' ', exportButton('tar.gz')),
    h('details', {}, h('summary', {}, 'Import a recording or a session archive'), form),
    status, result);
}
