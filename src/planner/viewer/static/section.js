// The design's workspace section in the linkage plane (u along AB, w in the plane) from
// POST /v1/workspace, coloured by the smallest kappa(A) of the cell in the bands of the
// paper's isoconditioning figure (fig. 15: levels 1.25, 1.5, 2, 3, 5, 10): the page's own
// isoconditioning map, drawn for the size it is shown at (its text is the page's), with the
// path of P drawn on it. uPlot draws the axes; the grid and the path are drawn in its draw
// hook at the axes' scale. A click on it reports the (u, w) point (to pick waypoints).
import { MODE_COLORS } from './scene.js';

const uPlot = globalThis.uPlot;
let chart = null;
let grid = null;        // the section of POST /v1/workspace
let image = null;       // the grid as an image, for the current working mode
let imageMode = null;
let path = null;        // {u, w, segmentOf, modes, transits}
let index = 0;
let kappaMax = 10;
let rest = null;        // {u, w}: the part of a straight path not achieved
let onPick = null;
let walls = null;       // [{joint, values, u, w}]: where a joint is at its literal limit (kin.limitWalls)

/** The levels of figure 15 (planner.plotting.ISO_LEVELS) and one colour per band between
 * them (pale to dark blue-green; beyond the last: the pink of near-parallel-singular). */
export const ISO_LEVELS = [1, 1.25, 1.5, 2, 3, 5, 10];
const BAND_COLORS = [[222, 242, 184], [186, 228, 181], [136, 208, 187], [90, 184, 194], [55, 146, 190], [42, 102, 168], [245, 158, 158]];

/** The band of kappa: i such that ISO_LEVELS[i] <= k < ISO_LEVELS[i + 1] (6: k >= 10). */
export function band(k) {
  let i = 0;
  while (i < ISO_LEVELS.length - 1 && k >= ISO_LEVELS[i + 1]) i++;
  return i;
}

function kappaColor(k) {
  if (k === null || !Number.isFinite(k)) return [120, 120, 120];
  return BAND_COLORS[band(k)];
}

/** A colour swatch (styled through the CSSOM: the page's CSP forbids inline style text). */
export function swatch(c) {
  const i = document.createElement('i');
  i.style.background = `rgb(${c.join(',')})`;
  return i;
}

/** The legend of the bands (HTML, so it reads at any size). */
export function legend(el) {
  el.replaceChildren(...BAND_COLORS.map((c, i) => {
    const s = document.createElement('span');
    const lo = ISO_LEVELS[i], hi = ISO_LEVELS[i + 1];
    s.append(swatch(c), hi ? `${lo} – ${hi}` : `κ ≥ ${lo}`);
    s.title = hi ? `${lo} <= κ(A) < ${hi}` : `κ(A) >= ${lo}: near a parallel singularity`;
    return s;
  }));
  const head = document.createElement('strong');
  head.textContent = 'κ(A):';
  el.prepend(head);
}

function buildImage(mode) {
  const nx = grid.x.length, ny = grid.y.length;
  const canvas = document.createElement('canvas');
  canvas.width = nx; canvas.height = ny;
  const ctx = canvas.getContext('2d');
  const img = ctx.createImageData(nx, ny);
  const bit = mode ? 1 << grid.labels.indexOf(mode) : 0;
  for (let j = 0; j < ny; j++) {
    for (let i = 0; i < nx; i++) {
      const reached = grid.reached[j][i];
      const o = 4 * ((ny - 1 - j) * nx + i);  // row 0 of the image is the largest w
      if (!reached) { img.data[o + 3] = 0; continue; }
      const [r, g, b] = kappaColor(grid.best_kappa[j][i]);
      img.data[o] = r; img.data[o + 1] = g; img.data[o + 2] = b;
      img.data[o + 3] = !bit || reached & bit ? 255 : 70;
    }
  }
  ctx.putImageData(img, 0, 0);
  image = canvas;
  imageMode = mode;
}

function draw(u) {
  if (!grid) return;
  const { ctx } = u;
  const mode = path ? path.modes[path.segmentOf[index]] : null;
  if (!image || imageMode !== mode) buildImage(mode);
  const dx = (grid.x[1] - grid.x[0]) / 2, dy = (grid.y[1] - grid.y[0]) / 2;
  const x0 = u.valToPos(grid.x[0] - dx, 'x', true), x1 = u.valToPos(grid.x.at(-1) + dx, 'x', true);
  const y0 = u.valToPos(grid.y.at(-1) + dy, 'y', true), y1 = u.valToPos(grid.y[0] - dy, 'y', true);
  ctx.save();
  const { left, top, width, height } = u.bbox;
  ctx.beginPath();
  ctx.rect(left, top, width, height);
  ctx.clip();  // a waypoint out of reach may lie beyond the axes
  ctx.imageSmoothingEnabled = false;
  ctx.drawImage(image, x0, y0, x1 - x0, y1 - y0);
  drawWalls(u, ctx);
  if (rest && rest.u.length >= 2) {
    ctx.strokeStyle = '#555';
    ctx.setLineDash([5 * devicePixelRatio, 4 * devicePixelRatio]);
    ctx.lineWidth = 2 * devicePixelRatio;
    ctx.beginPath();
    rest.u.forEach((uu, i) => {
      const x = u.valToPos(uu, 'x', true), y = u.valToPos(rest.w[i], 'y', true);
      if (i) ctx.lineTo(x, y); else ctx.moveTo(x, y);
    });
    ctx.stroke();
    ctx.setLineDash([]);
  }
  if (path) {
    const px = (i) => u.valToPos(path.u[i], 'x', true), py = (i) => u.valToPos(path.w[i], 'y', true);
    ctx.lineWidth = 2 * devicePixelRatio;
    for (let i = 1; i < path.u.length; i++) {
      ctx.strokeStyle = MODE_COLORS[path.modes[path.segmentOf[i]]] || '#333';
      ctx.beginPath(); ctx.moveTo(px(i - 1), py(i - 1)); ctx.lineTo(px(i), py(i)); ctx.stroke();
    }
    ctx.font = `${11 * devicePixelRatio}px system-ui, sans-serif`;
    path.transits.forEach((tr, n) => {
      ctx.fillStyle = '#6a1b9a';
      ctx.beginPath(); ctx.arc(px(tr.sample), py(tr.sample), 4 * devicePixelRatio, 0, 2 * Math.PI); ctx.fill();
      ctx.fillText(String(n + 1), px(tr.sample) + 6 * devicePixelRatio, py(tr.sample) - 4 * devicePixelRatio);
    });
    ctx.fillStyle = '#d62728';
    ctx.beginPath(); ctx.arc(px(index), py(index), 5 * devicePixelRatio, 0, 2 * Math.PI); ctx.fill();
  }
  ctx.restore();
}

/** The joint-limit walls of the start's working mode: dashed, each named once. */
function drawWalls(u, ctx) {
  if (!walls) return;
  ctx.save();
  ctx.strokeStyle = '#6d4c41';
  ctx.fillStyle = '#4e342e';
  ctx.lineWidth = 2 * devicePixelRatio;
  ctx.setLineDash([3 * devicePixelRatio, 3 * devicePixelRatio]);
  ctx.font = `${11 * devicePixelRatio}px system-ui, sans-serif`;
  for (const wall of walls) {
    ctx.beginPath();
    let open = false, named = null;
    wall.u.forEach((uu, i) => {
      if (!Number.isFinite(uu)) { open = false; return; }
      const x = u.valToPos(uu, 'x', true), y = u.valToPos(wall.w[i], 'y', true);
      if (open) ctx.lineTo(x, y); else ctx.moveTo(x, y);
      open = true;
      named ||= [x, y];
    });
    ctx.stroke();
    const text = `θ${wall.joint} = ${wall.values.map((v) => v.toFixed(4)).join(' | ')}`;
    if (named) ctx.fillText(text, named[0] + 4 * devicePixelRatio, named[1] - 4 * devicePixelRatio);
  }
  ctx.restore();
}

/** The joint-limit walls to draw (straight-path mode), or null. */
export function setWalls(list) { walls = list; chart?.redraw(false, false); }

/** What the section draws as joint-limit walls (for the tests). */
export const wallsData = () => walls;

/** Show the section of a /v1/workspace answer. */
export function setSection(section, kappa_max) {
  grid = section;
  kappaMax = kappa_max;
  image = null;
  build();
}

/** Draw the chart for the width of its box (again when that changes). */
function build() {
  const el = document.getElementById('section');
  if (!grid) return;
  chart?.destroy();
  el.replaceChildren();
  const ux = [grid.x[0], grid.x.at(-1)], wy = [grid.y[0], grid.y.at(-1)];
  const width = Math.max(220, el.clientWidth);  // the box's own width: drawn 1:1
  const plotH = Math.min(420, Math.max(160, ((width - 60) * (wy[1] - wy[0])) / (ux[1] - ux[0])));
  chart = new uPlot({
    width, height: plotH + 40,
    legend: { show: false },
    cursor: { show: false },
    scales: { x: { time: false, range: ux }, y: { range: wy } },
    axes: [{ label: 'u (m, along AB)', labelSize: 16, size: 30 }, { label: 'w (m, in the plane)', labelSize: 18, size: 50 }],
    series: [{}, { show: false }],
    hooks: { draw: [draw] },
  }, [ux, [null, null]], el);
  chart.over.addEventListener('click', (ev) => {
    if (!onPick) return;
    const r = chart.over.getBoundingClientRect();
    onPick(chart.posToVal(ev.clientX - r.left, 'x'), chart.posToVal(ev.clientY - r.top, 'y'));
  });
  chart.over.style.cursor = onPick ? 'crosshair' : '';
}

/** Redraw at the box's width when it changed. */
export function resize() {
  const el = document.getElementById('section');
  if (chart && Math.abs(chart.width - Math.max(220, el.clientWidth)) > 2) build();
}

/** Call f(u, w) on a click (m, in the linkage plane), or stop (f = null). */
export function setPick(f) {
  onPick = f;
  if (chart) chart.over.style.cursor = f ? 'crosshair' : '';
}

/** The part of a straight path not achieved (in-plane coordinates), or null. */
export function setRest(r) { rest = r; chart?.redraw(false, false); }

/** Draw the path of P (in-plane coordinates of each sample). */
export function setPath(p) { path = p; index = 0; chart?.redraw(false, false); }

/** Move the current point. */
export function setIndex(i) { index = i; chart?.redraw(false, false); }
