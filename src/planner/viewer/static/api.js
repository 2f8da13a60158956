// Calls to the service's /v1 API (same origin), with the API key when one is typed in.

export class ApiError extends Error {
  constructor(status, detail) {
    // FastAPI's answers: a 422's list of {loc, msg}, or one sentence (a 404's, a 413's)
    const first = Array.isArray(detail) && detail.length ? detail[0].msg : typeof detail === 'string' && detail ? detail : `HTTP ${status}`;
    super(first);
    this.status = status;
    this.detail = Array.isArray(detail) ? detail : [];
  }
}

let apiKey = '';
export const setApiKey = (key) => { apiKey = key.trim(); };
/** The key typed in ('' when none), for what cannot take headers (stream.js's WebSocket). */
export const apiKeyValue = () => apiKey;

function headers(json) {
  const h = {};
  if (json) h['Content-Type'] = 'application/json';
  if (apiKey) h['X-API-Key'] = apiKey;
  return h;
}

async function answer(response) {
  if (response.ok) return response;
  let detail = [];
  try { detail = (await response.json()).detail; } catch { /* not JSON */ }
  throw new ApiError(response.status, detail);
}

export async function getJSON(path) {
  return (await answer(await fetch(path, { headers: headers(false) }))).json();
}

export async function postJSON(path, body) {
  const r = await fetch(path, { method: 'POST', headers: headers(true), body: JSON.stringify(body) });
  return (await answer(r)).json();
}

export async function getBlob(path) {
  return (await answer(await fetch(path, { headers: headers(false) }))).blob();
}

export async function putJSON(path, body) {
  const r = await fetch(path, { method: 'PUT', headers: headers(true), body: JSON.stringify(body) });
  return (await answer(r)).json();
}

export async function deleteJSON(path) {
  return (await answer(await fetch(path, { method: 'DELETE', headers: headers(false) }))).json();
}
