// Runs as the whole app sees them (not one view): the run this page
// controls keeps heart-beating on every view, a "run in progress" bar
// shows on every view, and closing or reloading the tab asks first.
// One run vocabulary (docs/PROTOCOLS.md, "Runs"): states queued, running,
// done, failed, aborted; fields run_id, reason, created_at_utc.
import { api } from './api.js';

export const FINAL_STATES = ['done', 'failed', 'aborted'];
export const isFinal = (state) => FINAL_STATES.includes(state);

/// Progress as a fraction 0–1 and its ETA in seconds (a run object, an
/// SSE event or the bench state carry one or both).
export function progressOf(x) {
  if (!x) return { fraction: 0, eta_s: NaN };
  const p = x.progress;
  const fraction = typeof p === 'number' ? p : (p && p.fraction) || 0;
  const eta = Number.isFinite(x.eta_s) ? x.eta_s : p && Number.isFinite(p.eta_s) ? p.eta_s : NaN;
  return { fraction, eta_s: eta };
}

const HEARTBEAT_MS = 400; // the server's watchdog wants one at least every second

/// The app's run: {run_id, session_id, protocol, state, progress, eta_s,
/// controlled (this page heart-beats it)}. Listeners get it on every change
/// (null: no run).
export function createRunController() {
  let current = null;
  let heartbeat = null;
  let generation = 0; // bumped when the app takes or leaves a run
  const ended = new Set(); // runs seen to end here: never re-attached
  const listeners = new Set();
  const emit = () => {
    for (const l of listeners) l(current);
  };
  const stopHeartbeat = () => {
    if (heartbeat) clearInterval(heartbeat);
    heartbeat = null;
  };

  const controller = {
    get current() {
      return current;
    },
    /// Changes when a run is taken over or left: a bench answer older than
    /// the change must not undo it.
    get generation() {
      return generation;
    },
    hasEnded(runId) {
      return ended.has(runId);
    },
    onChange(fn) {
      listeners.add(fn);
      return () => listeners.delete(fn);
    },
    /// This page started (or re-attached to) the run: heart-beat it until it ends.
    control(run) {
      stopHeartbeat();
      generation += 1;
      current = { ...run, controlled: true };
      const id = run.run_id;
      heartbeat = setInterval(() => {
        api('POST', `/runs/${id}/heartbeat`).catch((e) => {
          // A finished run answers 409/404: the bench poll reports the end.
          if (e.status === 404 || e.status === 409) stopHeartbeat();
        });
      }, HEARTBEAT_MS);
      api('POST', `/runs/${id}/heartbeat`).catch(() => {});
      emit();
    },
    /// A run on the bench this page does not control (another user's).
    observe(run) {
      if (current && current.run_id === run.run_id) {
        current = { ...current, ...run, controlled: current.controlled };
      } else {
        stopHeartbeat();
        generation += 1;
        current = { ...run, controlled: false };
      }
      emit();
    },
    /// Updates from the bench poll or a view's event stream.
    update(fields) {
      if (!current) return;
      current = { ...current, ...fields };
      if (isFinal(current.state)) {
        stopHeartbeat();
        ended.add(current.run_id);
        generation += 1;
        current = null;
      }
      emit();
    },
    /// The run ended (or the bench no longer has it).
    end() {
      stopHeartbeat();
      if (current) {
        ended.add(current.run_id);
        generation += 1;
        current = null;
        emit();
      }
    },
    async cancel() {
      if (!current) return;
      await api('POST', `/runs/${current.run_id}/cancel`);
    },
  };

  // Closing or reloading the tab during a run this page controls ends the
  // heartbeat and so the run (the watchdog): ask first.
  window.addEventListener('beforeunload', (event) => {
    if (current && current.controlled) {
      event.preventDefault();
      event.returnValue = '';
    }
  });
  return controller;
}
