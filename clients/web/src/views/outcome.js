// What a run gave, in a clinician's words and units: the parameter set it
// made (with its model check), the tolerance test's values, the tracking
// error, the daily check's verdict, its trials. Shared by the session's
// runs table and the run's own page.
import { fmtDeg, fmtFixed, fmtMa, fmtNm, h } from '../dom.js';

// The daily check (docs/PROTOCOLS.md) in words and units.
export const DAILY_VERDICT = {
  no_change: 'no change, the approved set stands',
  refit: 'the recruitment moved, the set was re-fitted',
  rapid_due: 'a full rapid parameterisation is due',
};
export const DAILY_DRIFT = {
  irc_threshold_ma: { label: 'Recruitment threshold (current where the muscle starts to respond)', value: fmtMa },
  irc_slope: { label: 'Recruitment slope (torque gained per mA)', value: (x) => fmtFixed(x, 3, 'per mA') },
  full_scale: { label: 'Torque at full recruitment', value: fmtNm },
  pole: { label: 'Muscle contraction speed (pole)', value: (x) => fmtFixed(x, 1, '1/s') },
};

/// The run's outcome as inline content ('—' when it has none).
export function runOutcome(r) {
  const parts = [];
  const res = r.result || {};
  if (r.parameter_set_id) {
    parts.push(h('a', { href: `#/parameter-sets/${r.parameter_set_id}` }, `Parameter set ${r.parameter_set_id}`));
    parts.push(h('a', { href: `#/parameter-sets/${r.parameter_set_id}/check` }, 'model check'));
  }
  const used = r.parameters && r.parameters.parameter_set_id;
  if (!r.parameter_set_id && used >= 1) {
    parts.push(h('a', { href: `#/parameter-sets/${used}` }, `used parameter set ${used}`));
  }
  if ('max_tolerated_ma' in res) {
    parts.push(Number.isFinite(res.max_tolerated_ma)
      ? `threshold ${fmtMa(res.threshold_ma)}, max tolerated ${fmtMa(res.max_tolerated_ma)}`
      : 'no max tolerated recorded');
  }
  if (r.values && Number.isFinite(r.values.tracking_rms_deg)) parts.push(`tracking error ${fmtDeg(r.values.tracking_rms_deg)} RMS`);
  if (res.verdict) parts.push(`daily check: ${DAILY_VERDICT[res.verdict] || res.verdict}`);
  if (r.trial_ids && r.trial_ids.length) parts.push(`${r.trial_ids.length} trial${r.trial_ids.length === 1 ? '' : 's'}`);
  return parts.length ? h('span', { class: 'run-outcome' }, ...parts.flatMap((x, i) => (i ? ['; ', x] : [x]))) : '—';
}

/// A run's parameters as [label with unit, value] rows, in the protocol's
/// order and words (`protocol`: its catalogue entry, or undefined for a
/// protocol the server no longer offers): mA and degrees to 0.1, choices
/// by name.
export function parameterRows(protocol, parameters) {
  const specs = new Map(((protocol && protocol.parameters) || []).map((p) => [p.name, p]));
  const value = (spec, v) => {
    if (typeof v !== 'number') return String(v);
    if (spec && spec.choices && spec.choices[v] !== undefined) return spec.choices[v].replace(/_/g, ' ');
    if (spec && (spec.unit === 'mA' || spec.unit === 'deg')) return fmtFixed(v, 1);
    return Number.isInteger(v) ? String(v) : String(Number(v.toPrecision(4)));
  };
  const names = Object.keys(parameters || {});
  const ordered = [...[...specs.keys()].filter((n) => names.includes(n)), ...names.filter((n) => !specs.has(n))];
  return ordered.map((name) => {
    const spec = specs.get(name);
    const unit = spec && spec.unit && spec.unit !== '1' ? ` (${spec.unit === 'deg' ? '°' : spec.unit})` : '';
    return [`${spec ? spec.label || name : name}${unit}`, value(spec, parameters[name])];
  });
}
