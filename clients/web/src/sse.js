// Server-Sent Events over fetch (EventSource cannot send the bearer token):
// parses the text/event-stream format and calls onEvent(name, data, id).
import { authHeaders, ApiError, UNREACHABLE_MESSAGE } from './api.js';

export async function streamEvents(path, onEvent, signal) {
  let res;
  try {
    res = await fetch(`/api/v1${path}`, {
      headers: authHeaders({ Accept: 'text/event-stream' }),
      signal,
      cache: 'no-store',
    });
  } catch (e) {
    if (signal && signal.aborted) return;
    throw new ApiError(0, 'unreachable', UNREACHABLE_MESSAGE);
  }
  if (!res.ok) {
    let message = `The live stream could not be opened (${res.status}).`;
    try {
      const body = await res.json();
      if (body.error) message = `The live stream could not be opened: ${body.error.message}`;
    } catch {
      /* keep the generic message */
    }
    throw new ApiError(res.status, 'stream', message);
  }
  const reader = res.body.getReader();
  const decoder = new TextDecoder();
  let buffer = '';
  let event = { name: 'message', data: [], id: '' };
  const dispatchLine = (line) => {
    if (line === '') {
      if (event.data.length) {
        let data = event.data.join('\n');
        try {
          data = JSON.parse(data);
        } catch {
          /* plain text event */
        }
        onEvent(event.name, data, event.id);
      }
      event = { name: 'message', data: [], id: '' };
      return;
    }
    if (line.startsWith(':')) return;
    const colon = line.indexOf(':');
    const field = colon < 0 ? line : line.slice(0, colon);
    let value = colon < 0 ? '' : line.slice(colon + 1);
    if (value.startsWith(' ')) value = value.slice(1);
    if (field === 'event') event.name = value;
    else if (field === 'data') event.data.push(value);
    else if (field === 'id') event.id = value;
  };
  try {
    for (;;) {
      const { value, done } = await reader.read();
      if (done) break;
      buffer += decoder.decode(value, { stream: true });
      let nl;
      while ((nl = buffer.indexOf('\n')) >= 0) {
        const line = buffer.slice(0, nl).replace(/\r$/, '');
        buffer = buffer.slice(nl + 1);
        dispatchLine(line);
      }
    }
  } catch (e) {
    if (signal && signal.aborted) return;
    throw new ApiError(0, 'unreachable', 'The live stream was interrupted: ' + UNREACHABLE_MESSAGE);
  }
}
