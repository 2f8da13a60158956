// Plots against time (uPlot, loaded as the global uPlot by index.html): kappa(A) and the
// serial margin against their margins; q, qd, qdd of the three actuated joints; the actuator
// torques tau against +-limits.torque when the trajectory carries them. Transits are
// vertical lines with their kind, the current time a red line; a click seeks.

const uPlot = globalThis.uPlot;
const JOINT_COLORS = ['#1f77b4', '#ff7f0e', '#2ca02c'];
const TRANSIT = '#6a1b9a';

let charts = [];
let torque = null;  // the torque chart's {t, tau, limits}: what it plots (read by the tests)
let now = 0;
let transits = [];

function overlay(u) {
  const { ctx } = u;
  const { top, height } = u.bbox;
  ctx.save();
  ctx.font = `${11 * devicePixelRatio}px system-ui, sans-serif`;
  for (const tr of transits) {
    const x = u.valToPos(tr.t, 'x', true);
    ctx.strokeStyle = TRANSIT;
    ctx.setLineDash([4 * devicePixelRatio, 3 * devicePixelRatio]);
    ctx.lineWidth = devicePixelRatio;
    ctx.beginPath(); ctx.moveTo(x, top); ctx.lineTo(x, top + height); ctx.stroke();
    ctx.fillStyle = TRANSIT;
    ctx.fillText(tr.kind, x + 3 * devicePixelRatio, top + 11 * devicePixelRatio);
  }
  const x = u.valToPos(now, 'x', true);
  ctx.setLineDash([]);
  ctx.strokeStyle = '#d62728';
  ctx.lineWidth = 1.5 * devicePixelRatio;
  ctx.beginPath(); ctx.moveTo(x, top); ctx.lineTo(x, top + height); ctx.stroke();
  ctx.restore();
}

/** Ticks for a y axis from min to max: steps of 1, 2, 2.5 or 5 times a power of ten, the
 * largest such step that leaves at least three intervals (so at least four ticks, at most
 * seven), whatever the range (uPlot's own choice can leave a short axis one tick). */
export function yTicks(min, max) {
  const span = max - min;
  if (!(span > 0) || !Number.isFinite(span)) return [min];
  const raw = span / 3;
  const p = 10 ** Math.floor(Math.log10(raw));
  const step = [5, 2.5, 2, 1].map((m) => m * p).find((s) => s <= raw * (1 + 1e-9));
  const ticks = [];
  for (let v = Math.ceil(min / step - 1e-9) * step; v <= max + step * 1e-9; v += step) ticks.push(Math.abs(v) < step * 1e-9 ? 0 : +v.toPrecision(12));
  return ticks;
}

const HEIGHT = 170;

/** One uPlot chart against time appended to `el`, fitted to its width: `series` after the
 * time axis, `data` [t, ...ys], the y axis `yRange` (else automatic) with its `yLabel`;
 * `draw` (default: the transits and the current time) draws over the plot; a click calls
 * onSeek(t). Shared by every view that plots against time (simulation.js too). */
export function chart(el, title, series, data, { yRange, yLabel, draw = overlay } = {}, onSeek) {
  const box = document.createElement('div');
  el.appendChild(box);
  const width = Math.max(200, el.clientWidth - 12);
  const u = new uPlot({
    title, width, height: HEIGHT,
    legend: { show: true, live: false },
    cursor: { drag: { x: false, y: false }, points: { show: false } },
    scales: { x: { time: false }, y: yRange ? { range: yRange } : { auto: true } },
    axes: [{ label: 't (s)', labelSize: 16, size: 30 }, {
      label: yLabel, labelSize: 18, size: 56, splits: (self, i, min, max) => yTicks(min, max),
      // each tick as its value (uPlot's own labels round to the step it would have chosen)
      values: (self, ticks) => ticks.map((v) => String(v)),
    }],
    series: [{ label: 't' }, ...series],
    hooks: { draw: [draw] },
  }, data, box);
  u.over.addEventListener('click', () => {
    if (u.cursor.left >= 0) onSeek(u.posToVal(u.cursor.left, 'x'));
  });
  return u;
}

const joints = (m, k) => m.map((v) => v[k]);

/** Draw every plot for a trajectory and the page's kinematics along it. */
export function show({ t, q, qd, qdd, tau, torqueLimits, kappa, serial, margins, transitTimes, onSeek }) {
  clear();
  transits = transitTimes;
  now = 0;
  const kEl = document.getElementById('kappa-plot');
  const jEl = document.getElementById('joint-plot');
  const finiteKappa = kappa.map((k) => (Number.isFinite(k) ? k : null));
  const kTop = Math.max(margins.kappa_max * 1.15, ...finiteKappa.filter((k) => k !== null)) || 2;
  const dashed = { dash: [6, 4], width: 1.5 };
  charts = [
    chart(kEl, 'κ(A) along the trajectory', [
      { label: 'κ(A)', stroke: '#d62728', width: 2 },
      { label: `κ max = ${margins.kappa_max}`, stroke: '#555', ...dashed },
    ], [t, finiteKappa, t.map(() => margins.kappa_max)], { yRange: [1, kTop], yLabel: 'κ(A)' }, onSeek),
    chart(kEl, 'serial margin: min(|sin(θ4-θ2)|, |sin(θ5-θ3)|, |w|/(L1+L2))', [
      { label: 'serial margin', stroke: '#1f77b4', width: 2 },
      { label: `serial min = ${margins.serial_min}`, stroke: '#555', ...dashed },
    ], [t, serial, t.map(() => margins.serial_min)], { yRange: [0, 1], yLabel: 'margin' }, onSeek),
  ];
  for (const [name, m, unit] of [['q', q, 'rad'], ['qd', qd, 'rad/s'], ['qdd', qdd, 'rad/s²']]) {
    charts.push(chart(jEl, `${name} (${unit})`, [0, 1, 2].map((k) => ({
      label: `θ${k + 1}`, stroke: JOINT_COLORS[k], width: 1.5,
    })), [t, ...[0, 1, 2].map((k) => joints(m, k))], { yLabel: unit }, onSeek));
  }
  if (tau) showTorque(t, tau, torqueLimits, onSeek);
}

/** tau_j(t) of the three actuators and, for each limited joint, the lines +-limit in its colour. */
function showTorque(t, tau, limits, onSeek) {
  const el = document.getElementById('torque-plot');
  const series = [0, 1, 2].map((k) => ({ label: `τ${k + 1}`, stroke: JOINT_COLORS[k], width: 1.5 }));
  const data = [t, ...[0, 1, 2].map((k) => joints(tau, k))];
  const lines = [];
  for (let k = 0; k < 3; k++) {
    const lim = limits?.[k];
    if (typeof lim !== 'number') continue;
    for (const sign of [1, -1]) {  // the line's own value, signed: "limit τ1 = -12"
      series.push({ label: `limit τ${k + 1} = ${sign * lim}`, stroke: JOINT_COLORS[k], dash: [6, 4], width: 1 });
      data.push(t.map(() => sign * lim));
      lines.push({ joint: k, value: sign * lim });
    }
  }
  // symmetric about 0, the limits inside: a torque's sign reads at a glance
  const top = 1.08 * Math.max(1e-9, ...tau.flat().map(Math.abs).filter(Number.isFinite), ...lines.map((l) => Math.abs(l.value)));
  charts.push(chart(el, 'actuator torques τ (N m) against the torque limits', series, data, { yLabel: 'N m', yRange: [-top, top] }, onSeek));
  torque = { t, tau, lines, yTicks: yTicks(-top, top), yRange: [-top, top] };
  el.dataset.lines = String(lines.length);
  el.dataset.yTicks = String(torque.yTicks.length);
}

/** What the torque chart plots ({t, tau, lines: [{joint, value}]}), or null without one. */
export const torqueData = () => torque;

/** Remove every plot. */
export function clear() {
  for (const c of charts) c.destroy();
  charts = [];
  torque = null;
  for (const id of ['kappa-plot', 'joint-plot', 'torque-plot']) document.getElementById(id).replaceChildren();
  delete document.getElementById('torque-plot').dataset.lines;
  delete document.getElementById('torque-plot').dataset.yTicks;
}

/** Move the current-time line. */
export function setTime(t) {
  now = t;
  for (const c of charts) c.redraw(false, false);
}

/** Fit a chart made by chart() to its container's width. */
export function fit(c) {
  const w = Math.max(200, c.root.parentElement.parentElement.clientWidth - 12);
  if (Math.abs(c.width - w) > 2) c.setSize({ width: w, height: HEIGHT });
}

/** Fit the plots to their containers' width. */
export function resize() {
  for (const c of charts) fit(c);
}
