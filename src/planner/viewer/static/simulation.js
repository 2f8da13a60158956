// The simulated robot (POST /v1/simulate, docs/simulation.md) as a view of an answer with a
// trajectory (a plan's, a straight path's or a sequence's): **Simulate** runs the answer's
// own trajectory (t, q, qd, qdd; not planned again) on the simulated robot of its request
// (its design with the inertia, gravity, the start's assembly mode, limits.torque where the
// actuators saturate) under the chosen controller at the service's default 1 kHz, and shows
// (`sim-plot`) the planned and the realised P over time, the tracking error over time, and
// the tracking summary (`sim-summary`: p_max_mm, p_rms_mm, planned vs realised duration,
// settle times). The same view interface as sequence.js: show, clear, setTime (and resize).

import { ApiError, postJSON } from './api.js';
import { along } from './kin.js';
import { chart, fit } from './plots.js';

const $ = (id) => document.getElementById(id);
const COORDS = ['x', 'y', 'z'];
/** Realised P: the joint colours; planned P: their light tints, wider and drawn first, so
 * both show where they coincide (computed torque tracks to hundredths of a mm). */
const REALISED = ['#1f77b4', '#ff7f0e', '#2ca02c'];
const PLANNED = ['#aec7e8', '#ffbb78', '#98df8a'];
const ERROR = '#9467bd';
const MARK = '#555';

let answerOf = null;  // {request, response, seek}: the answer on screen, the one to simulate
let charts = [];
let now = 0;
let ends = [];        // [{t, label}]: the planned and the realised end, drawn on both charts
let drawn = null;     // what the plot shows (read by the tests): {body, answer, planned}
let asked = 0;        // the simulation in flight; an answer for an older one is dropped

/** The body of POST /v1/simulate for an answer's trajectory under `kind` ('computed_torque'
 * or 'pd'): the robot is the request's (the service's defaults where the request has none). */
export function simulateBody(request, response, kind) {
  const { t, q, qd, qdd } = response.trajectory;
  const body = {
    design: request.design, assembly_mode: request.start?.assembly_mode || '+',
    trajectory: { t, q, qd, qdd }, controller: { kind },
  };
  if (request.gravity) body.gravity = request.gravity;
  if (request.limits?.torque) body.limits = { torque: request.limits.torque };
  return body;
}

/** An answer with a trajectory can be simulated: the view offers it; else it hides. */
export function show(request, response, endpoint, { seek }) {
  clear();
  const traj = response?.trajectory;
  if (!traj?.t?.length || !traj.qd || !traj.qdd) return;
  answerOf = { request, response, seek };
  $('sim-view').hidden = false;
}

export function clear() {
  asked++;
  answerOf = null;
  drawn = null;
  ends = [];
  for (const c of charts) c.destroy();
  charts = [];
  $('sim-view').hidden = true;
  $('sim-plot').replaceChildren();
  $('sim-plot').hidden = true;
  $('sim-summary').hidden = true;
  $('sim-note').textContent = '';
  $('sim-run').disabled = false;
}

export function setTime(t) {
  now = t;
  for (const c of charts) c.redraw(false, false);
}

export function resize() {
  for (const c of charts) fit(c);
}

/** What the plot shows ({body, answer, planned: {t, p}}), or null before a simulation. */
export const simulationData = () => drawn;

function marks(u) {
  const { ctx } = u;
  const { top, height } = u.bbox;
  const px = devicePixelRatio;
  ctx.save();
  ctx.font = `${11 * px}px system-ui, sans-serif`;
  for (const [k, m] of ends.entries()) {
    const x = u.valToPos(m.t, 'x', true);
    ctx.strokeStyle = MARK;
    ctx.fillStyle = MARK;
    ctx.setLineDash([4 * px, 3 * px]);
    ctx.lineWidth = px;
    ctx.beginPath(); ctx.moveTo(x, top); ctx.lineTo(x, top + height); ctx.stroke();
    ctx.textAlign = 'right';  // left of its line, the realised end's a row lower (the two are close)
    const y = top + (11 + 12 * k) * px;
    const w = ctx.measureText(m.label).width;
    ctx.fillStyle = 'rgba(255, 255, 255, 0.85)';  // readable over the curves
    ctx.fillRect(x - 5 * px - w, y - 10 * px, w + 4 * px, 12 * px);
    ctx.fillStyle = MARK;
    ctx.fillText(m.label, x - 3 * px, y);
  }
  const x = u.valToPos(now, 'x', true);
  ctx.setLineDash([]);
  ctx.strokeStyle = '#d62728';
  ctx.lineWidth = 1.5 * px;
  ctx.beginPath(); ctx.moveTo(x, top); ctx.lineTo(x, top + height); ctx.stroke();
  ctx.restore();
}

const mm = (ps, k) => ps.map((p) => 1000 * p[k]);

/** The planned P: the answer's own samples of P, else the page's kinematics of its q. */
function plannedP(request, traj) {
  return traj.p || along(request.design, traj.q, request.start?.assembly_mode || '+').map((x) => x?.P || [NaN, NaN, NaN]);
}

function draw(request, response, answer) {
  const box = $('sim-plot');
  box.hidden = false;
  box.replaceChildren();
  const traj = response.trajectory;
  const planned = { t: traj.t, p: plannedP(request, traj) };
  // planned and realised on their own clocks (the realised one runs on through the settling)
  const data = globalThis.uPlot.join([[planned.t, ...[0, 1, 2].map((k) => mm(planned.p, k))], [answer.t, ...[0, 1, 2].map((k) => mm(answer.p, k))]]);
  const series = [
    ...COORDS.map((c, k) => ({ label: `planned ${c}`, stroke: PLANNED[k], width: 5, spanGaps: true })),
    ...COORDS.map((c, k) => ({ label: `realised ${c}`, stroke: REALISED[k], width: 1.5, spanGaps: true })),
  ];
  ends = [{ t: traj.t.at(-1), label: 'planned end' }];
  if (typeof answer.realised_duration === 'number') ends.push({ t: answer.realised_duration + traj.t[0], label: 'realised end' });
  const seek = (t) => answerOf?.seek(t);
  charts = [
    chart(box, 'P (mm): planned (wide, light) and realised on the simulated robot', series, data, { yLabel: 'mm', draw: marks }, seek),
    chart(box, `tracking error |P realised − P planned| (mm), ${answer.controller}`, [
      { label: 'P error', stroke: ERROR, width: 1.5 },
    ], [answer.t, answer.p_error_mm], { yLabel: 'mm', draw: marks }, seek),
  ];
  box.dataset.samples = String(answer.t.length);
  drawn = { answer, planned };
}

const num = (x, d) => (typeof x === 'number' && Number.isFinite(x) ? x.toFixed(d) : '—');

/** One number of the summary: its text for the eye, its value as the answer gave it. */
function put(id, value, text) {
  $(id).textContent = text;
  $(id).dataset.value = value === null || value === undefined ? 'null' : JSON.stringify(value);
}

function summarise(answer) {
  $('sim-summary').hidden = false;
  put('sim-p-max', answer.tracking.p_max_mm, `${num(answer.tracking.p_max_mm, 4)} mm`);
  put('sim-p-rms', answer.tracking.p_rms_mm, `${num(answer.tracking.p_rms_mm, 4)} mm`);
  put('sim-planned', answer.planned_duration, `${num(answer.planned_duration, 4)} s`);
  const realised = answer.realised_duration;
  const diff = typeof realised === 'number' && answer.planned_duration > 0
    ? ` (${(100 * (realised / answer.planned_duration - 1)).toFixed(2)} %)` : '';
  put('sim-realised', realised, typeof realised === 'number' ? `${num(realised, 4)} s${diff}` : 'not settled');
  put('sim-settle', answer.settle_times, answer.settle_times.map((s) => (s === null ? 'not settled' : `${num(s, 4)} s`)).join(', ') || '—');
  $('sim-engine').textContent = `${answer.engine}, ${answer.controller} at ${answer.rate_hz} Hz, `
    + `${answer.saturated_samples} saturated sample${answer.saturated_samples === 1 ? '' : 's'}`
    + (answer.assembly_kept ? '' : '; the loop left its assembly mode');
}

async function simulate() {
  if (!answerOf) return;
  const { request, response } = answerOf;
  const body = simulateBody(request, response, $('sim-controller').value);
  const mine = ++asked;
  $('sim-run').disabled = true;
  $('sim-note').textContent = 'simulating…';
  try {
    const answer = await postJSON('/v1/simulate', body);
    if (mine !== asked) return;
    $('sim-note').textContent = '';
    draw(request, response, answer);
    summarise(answer);
    drawn.body = body;
  } catch (err) {
    if (mine !== asked) return;
    const said = err instanceof ApiError && err.detail.length
      ? err.detail.map((d) => `${(d.loc || []).join('.')}: ${d.msg}`).join('; ') : err.message;
    $('sim-note').textContent = `The simulation was refused: ${said}`;
  } finally {
    if (mine === asked) $('sim-run').disabled = false;
  }
}

$('sim-run').addEventListener('click', simulate);
