// The stream's live position (WebSocket /v1/stream, docs/execution.md "Streaming setpoints"):
// **Stream** sends the form's plan or sequence request to the page's own host (ws:// or wss://
// as the page) at RATE_HZ, acknowledges by the page's own clock (real time: the trajectory's
// time is the first chunk's t0 plus the seconds since it arrived), and shows, at every frame,
// the setpoint due at that clock: the robot drawn there in the 3-D scene and the readout
// `stream-live` (time, q, P, chunks received, lateness: how far past its own t0 on our
// clock the latest chunk arrived, and the largest so far). **Stop** sends {"type": "stop"};
// `switched`, `done` and `error` (with its field) are shown. A panel with its own request
// (as calibration.js): init() and clear(), not one of app.js's VIEWS.
//
// The API key (a browser cannot set a WebSocket's headers) goes as a subprotocol,
// `planner.key.<base64url>`, beside `planner.stream` (the route's docstring).

import { apiKeyValue } from './api.js';
import { posture } from './kin.js';

const $ = (id) => document.getElementById(id);
const RATE_HZ = 250;
const LOOKAHEAD_S = 0.1;

let ws = null;
let run = null;   // {design, asm, t: [], q: [], qd: [], chunks, clock0, wall0, late, maxLate, ...}
let hooks = null; // {scene, request: () => {endpoint, request}, before: () => void}

const base64url = (s) => btoa(String.fromCharCode(...new TextEncoder().encode(s)))
  .replace(/\+/g, '-').replace(/\//g, '_').replace(/=+$/, '');

/** The trajectory's time on the page's clock (real time since the first chunk). */
const clock = () => run.clock0 + (performance.now() - run.wall0) / 1000;

export function init(h) {
  hooks = h;
  $('stream-run').addEventListener('click', start);
  $('stream-stop').addEventListener('click', () => {
    if (ws?.readyState === WebSocket.OPEN) ws.send(JSON.stringify({ type: 'stop' }));
    $('stream-stop').disabled = true;
  });
}

/** Close the stream, if any, and hide its readout. */
export function clear() {
  if (ws) ws.close();
  ws = null;
  run = null;
  const box = $('stream-live');
  box.hidden = true;
  for (const k of ['t', 'q', 'qd', 'chunks', 'lateness', 'switched', 'loc']) delete box.dataset[k];
  box.dataset.state = '';
  $('stream-text').textContent = '';
  $('stream-note').textContent = '';
  $('stream-stop').disabled = true;
  $('stream-run').disabled = false;
}

function start() {
  const { endpoint, request } = hooks.request();
  clear();
  const box = $('stream-live');
  box.hidden = false;
  if (endpoint !== 'plan' && endpoint !== 'sequence') {
    say('idle', 'A stream is a plan or a sequence: choose a goal of one of those kinds.');
    return;
  }
  hooks.before();
  run = {
    design: request.design, asm: request.start?.assembly_mode || '+',
    t: [], q: [], qd: [], chunks: 0, late: 0, maxLate: 0, clock0: null, wall0: null,
    switched: null, end: null, shown: -1,
  };
  const key = apiKeyValue();
  const protocols = ['planner.stream', ...(key ? [`planner.key.${base64url(key)}`] : [])];
  const url = `${location.protocol === 'https:' ? 'wss' : 'ws'}://${location.host}/v1/stream`;
  const socket = new WebSocket(url, protocols);
  ws = socket;
  say('connecting', 'connecting…');
  $('stream-run').disabled = true;
  socket.onopen = () => socket.send(JSON.stringify({
    type: endpoint, request, rate_hz: RATE_HZ, lookahead_s: LOOKAHEAD_S,
  }));
  socket.onmessage = (ev) => { if (ws === socket) received(JSON.parse(ev.data)); };
  socket.onclose = () => {
    if (ws !== socket) return;
    $('stream-run').disabled = false;
    $('stream-stop').disabled = true;
    if (run && run.end === null && box.dataset.state !== 'error') say('closed', 'the stream closed before its end');
  };
  requestAnimationFrame(frame);
}

function received(m) {
  if (m.type === 'setpoints') {
    if (run.clock0 === null) {
      run.clock0 = m.t0;
      run.wall0 = performance.now();
      $('stream-stop').disabled = false;
      say('streaming', `streaming at ${RATE_HZ} Hz, ${1000 * LOOKAHEAD_S} ms ahead`);
    }
    run.chunks++;
    run.late = clock() - m.t0;
    run.maxLate = Math.max(run.maxLate, run.late);
    // a switch restarts the grid at `at`: setpoints from there replace the ones sent after it
    while (run.t.length && run.t.at(-1) >= m.t0 - 1e-12) { run.t.pop(); run.q.pop(); run.qd.pop(); }
    m.q.forEach((q, i) => { run.t.push(m.t0 + i * m.dt); run.q.push(q); run.qd.push(m.qd[i]); });
    ack();
  } else if (m.type === 'switched') {
    run.switched = m.at;
    $('stream-live').dataset.switched = String(m.at);
    say('streaming', `switched at t = ${m.at.toFixed(3)} s: stopping`);
  } else if (m.type === 'done') {
    run.end = m.t;
  } else if (m.type === 'error') {
    const where = (m.loc || []).join('.');
    say('error', `error${where ? ` at ${where}` : ''}: ${m.msg}`);
    $('stream-live').dataset.loc = where;
    run.end = null;
  }
}

function ack() {
  if (ws?.readyState === WebSocket.OPEN && run?.clock0 !== null) {
    ws.send(JSON.stringify({ type: 'ack', t: clock() }));
  }
}

/** The index of the last setpoint at or before time t (-1 before the first). */
function dueAt(t) {
  let lo = -1, hi = run.t.length - 1;
  while (lo < hi) {
    const mid = (lo + hi + 1) >> 1;
    if (run.t[mid] <= t + 1e-12) lo = mid; else hi = mid - 1;
  }
  return lo;
}

function frame() {
  if (!run || $('stream-live').dataset.state === 'error') return;
  if (run.clock0 === null) { requestAnimationFrame(frame); return; }
  const now = clock();
  const i = dueAt(now);
  const last = run.t.length - 1;
  const finished = run.end !== null && i >= last;
  if (i >= 0 && i !== run.shown) draw(finished ? last : i);
  if (finished) {
    const rest = run.qd[last].every((v) => v === 0);
    say('done', `done at t = ${run.end.toFixed(3)} s${rest ? ', at rest' : ''}`
      + (run.switched === null ? '' : ` (stopped: switched at ${run.switched.toFixed(3)} s)`));
    return;
  }
  ack();  // the clock moves on between chunks too
  requestAnimationFrame(frame);
}

function draw(i) {
  run.shown = i;
  const q = run.q[i];
  const x = posture(run.design, q, run.asm);
  if (x) hooks.scene.setPosture(x, q[0]);
    const box = $('stream-live');
  box.dataset.t = String(run.t[i]);
  box.dataset.q = JSON.stringify(q);
  box.dataset.qd = JSON.stringify(run.qd[i]);
  box.dataset.chunks = String(run.chunks);
  box.dataset.lateness = String(run.late);
  const f = (v, d) => v.toFixed(d);
  $('stream-text').textContent = `t = ${f(run.t[i], 3)} s · q = ${q.map((v) => f(v, 4)).join(', ')} rad · `
    + `P = ${x ? x.P.map((v) => f(v, 4)).join(', ') : '—'} m · chunks ${run.chunks} · `
    + `lateness ${f(1000 * run.late, 1)} ms (max ${f(1000 * run.maxLate, 1)} ms; < 0: ahead)`;
}

function say(state, text) {
  $('stream-live').dataset.state = state;
  $('stream-note').textContent = text;
}
