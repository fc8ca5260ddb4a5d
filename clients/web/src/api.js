// The server's JSON API (/api/v1) with the signed-in user's bearer token.
// Every failure becomes an ApiError with a plain message; a failed fetch
// (server down, network gone) is code "unreachable".

const TOKEN_KEY = 'fesbench.token';

export class ApiError extends Error {
  constructor(status, code, message, field = '') {
    super(message);
    this.status = status;
    this.code = code;
    this.field = field;
  }
}

export const UNREACHABLE_MESSAGE =
  'The fesbench server cannot be reached. Check that it is running and that this computer is on the lab network.';

let token = sessionStorage.getItem(TOKEN_KEY) || '';
const listeners = new Set();

export function getToken() {
  return token;
}

export function setToken(value) {
  token = value;
  if (value) sessionStorage.setItem(TOKEN_KEY, value);
  else sessionStorage.removeItem(TOKEN_KEY);
}

/// Called with (ok, error) after every request: the page's connection banner.
export function onConnectivity(listener) {
  listeners.add(listener);
}

function report(ok, error) {
  for (const l of listeners) l(ok, error);
}

export function authHeaders(extra = {}) {
  return token ? { Authorization: `Bearer ${token}`, ...extra } : { ...extra };
}

/// method, path under /api/v1, optional JSON body → parsed JSON (or null).
export async function api(method, path, body) {
  let res;
  try {
    res = await fetch(`/api/v1${path}`, {
      method,
      headers: authHeaders(body !== undefined ? { 'Content-Type': 'application/json' } : {}),
      body: body !== undefined ? JSON.stringify(body) : undefined,
      cache: 'no-store',
    });
  } catch {
    const error = new ApiError(0, 'unreachable', UNREACHABLE_MESSAGE);
    report(false, error);
    throw error;
  }
  const text = await res.text();
  let data = null;
  if (text) {
    try {
      data = JSON.parse(text);
    } catch {
      data = null;
    }
  }
  report(true, null);
  if (!res.ok) {
    const e = (data && data.error) || {};
    let message = e.message || `The server answered ${res.status} ${res.statusText}.`;
    if (res.status === 401) message = `Not signed in or the token is not valid (${message}).`;
    if (res.status === 403) message = `Your role may not do this (${message}).`;
    if (res.status >= 500) message = `The server failed (${res.status}): ${message}`;
    throw new ApiError(res.status, e.code || `http_${res.status}`, message, e.field || '');
  }
  return data;
}

/// Every item of a paged list (follows next_cursor).
export async function listAll(path, limit = 500) {
  const items = [];
  let cursor = null;
  do {
    const sep = path.includes('?') ? '&' : '?';
    const page = await api('GET', `${path}${sep}limit=${limit}${cursor ? `&cursor=${encodeURIComponent(cursor)}` : ''}`);
    items.push(...page.items);
    cursor = page.next_cursor;
  } while (cursor);
  return items;
}

/// Follows a job (identification, prediction) until done; its result.
export async function waitForJob(job, { intervalMs = 150, signal } = {}) {
  let current = job;
  while (current.state !== 'done' && current.state !== 'failed') {
    if (signal && signal.aborted) throw new ApiError(0, 'cancelled', 'Stopped waiting for the job.');
    await new Promise((r) => setTimeout(r, intervalMs));
    current = await api('GET', `/jobs/${current.id}`);
  }
  if (current.state === 'failed') {
    const e = current.error || {};
    throw new ApiError(0, e.code || 'job_failed', e.message || 'The job failed.', e.field || '');
  }
  return current.result;
}

/// POSTs a file's bytes (an upload) with `contentType`; the JSON answer.
export async function upload(path, file, contentType) {
  let res;
  try {
    res = await fetch(`/api/v1${path}`, {
      method: 'POST', headers: authHeaders({ 'Content-Type': contentType }), body: file, cache: 'no-store',
    });
  } catch {
    throw new ApiError(0, 'unreachable', UNREACHABLE_MESSAGE);
  }
  const data = await res.json().catch(() => null);
  if (!res.ok) {
    const e = (data && data.error) || {};
    throw new ApiError(res.status, e.code || `http_${res.status}`, e.message || `The upload failed (${res.status}).`, e.field || '');
  }
  return data;
}

/// Downloads a file from the API with the bearer token (a link cannot send
/// it): fetch, then save the Blob under the server's file name.
export async function download(path, fallbackName) {
  let res;
  try {
    res = await fetch(`/api/v1${path}`, { headers: authHeaders(), cache: 'no-store' });
  } catch {
    throw new ApiError(0, 'unreachable', UNREACHABLE_MESSAGE);
  }
  if (!res.ok) {
    let message = `The download failed (${res.status}).`;
    try {
      const body = await res.json();
      if (body.error) message = `The download failed: ${body.error.message}`;
    } catch {
      /* keep the generic message */
    }
    throw new ApiError(res.status, 'download', message);
  }
  const disposition = res.headers.get('Content-Disposition') || '';
  const m = disposition.match(/filename="?([^";]+)"?/);
  const name = m ? m[1] : fallbackName;
  const url = URL.createObjectURL(await res.blob());
  const a = document.createElement('a');
  a.href = url;
  a.download = name;
  document.body.appendChild(a);
  a.click();
  a.remove();
  setTimeout(() => URL.revokeObjectURL(url), 1000);
  return name;
}
