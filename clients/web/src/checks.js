// Client-side checks of form fields against the limits the server applies
// (server/http/resources_json.cc, GET /protocols): the same wording as the
// server's 400 ("weight_kg must be 1–400 kg, got -5", shown beside the
// field without the name). Every form checks every field and shows all
// problems of a submit at once; the server checks again.

/// Subject details: unit and range as POST/PATCH /subjects accept them.
export const SUBJECT_LIMITS = {
  age_years: { unit: 'years', min: 0, max: 130, integer: true },
  height_cm: { unit: 'cm', min: 30, max: 250 },
  weight_kg: { unit: 'kg', min: 1, max: 400 },
  shank_length_cm: { unit: 'cm', min: 10, max: 80 },
  calf_circumference_cm: { unit: 'cm', min: 10, max: 100 },
  rom_min_deg: { unit: '°', min: -30, max: 60 },
  rom_max_deg: { unit: '°', min: 60, max: 180 },
};

/// Session details: stimulation in mA, 0–100 (the stimulator's limit).
export const SESSION_LIMITS = {
  threshold_ma: { unit: 'mA', min: 0, max: 100 },
  max_tolerated_ma: { unit: 'mA', min: 0, max: 100 },
};

const CODE_RE = /^[A-Za-z0-9_-]{1,32}$/;
const DATE_RE = /^\d{4}-\d{2}-\d{2}$/;

/// The problem with `raw` (a form value, trimmed) as a number of `spec`
/// ({unit, min, max, integer}), or null. '' is not a problem (absent).
export function numberProblem(spec, raw) {
  if (raw === '') return null;
  const unit = spec.unit && spec.unit !== '1' ? ` ${spec.unit}` : '';
  const n = Number(raw);
  if (!Number.isFinite(n)) return `must be a number${unit ? ` in${unit}` : ''}, got ${raw}`;
  if (spec.integer && !Number.isInteger(n)) return `must be a whole number${unit ? ` of${unit}` : ''}, got ${raw}`;
  const hasMin = Number.isFinite(spec.min);
  const hasMax = Number.isFinite(spec.max);
  if ((hasMin && n < spec.min) || (hasMax && n > spec.max)) {
    const range = hasMin && hasMax ? `${spec.min}–${spec.max}` : hasMin ? `≥ ${spec.min}` : `≤ ${spec.max}`;
    return `must be ${range}${unit}, got ${raw}`;
  }
  return null;
}

/// A subject code's problem, or null.
export function codeProblem(raw) {
  if (raw === '') return 'a pseudonymous code is required';
  return CODE_RE.test(raw) ? null : `only letters, digits, _ and - (1–32 of them), got "${raw}"`;
}

/// A calendar date's problem (YYYY-MM-DD), or null.
export function dateProblem(raw) {
  const message = `must be a calendar date YYYY-MM-DD, got ${raw || 'nothing'}`;
  if (!DATE_RE.test(raw)) return message;
  const d = new Date(`${raw}T00:00:00Z`);
  return Number.isNaN(d.getTime()) || d.toISOString().slice(0, 10) !== raw ? message : null;
}

/// Checks a session's threshold and max tolerated together: every problem.
export function sessionProblems(values) {
  const problems = [];
  for (const [name, spec] of Object.entries(SESSION_LIMITS)) {
    const message = numberProblem(spec, values[name] ?? '');
    if (message) problems.push({ field: name, message });
  }
  const t = Number(values.threshold_ma);
  const m = Number(values.max_tolerated_ma);
  if (!problems.length && values.threshold_ma && values.max_tolerated_ma && m < t) {
    problems.push({ field: 'max_tolerated_ma', message: `must not be below the threshold (${t} mA), got ${m}` });
  }
  return problems;
}
