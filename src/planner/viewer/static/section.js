// The design's workspace section in the linkage plane (u along AB, w in the plane) from
// POST /v1/workspace, coloured by the smallest kappa(A) of the cell (an isoconditioning map),
// with the path of P drawn on it. uPlot draws the axes; the grid and the path are drawn in
// its draw hook at the axes' scale.
import { MODE_COLORS } from './scene.js';

const uPlot = globalThis.uPlot;
let chart = null;
let grid = null;        // the section of POST /v1/workspace
let image = null;       // the grid as an image, for the current working mode
let imageMode = null;
let path = null;        // {u, w, segmentOf, modes, transits}
let index = 0;
let kappaMax = 10;

/** kappa in [1, kappaMax] -> a colour from teal (isotropic) to yellow; above: orange. */
function kappaColor(k) {
  if (k === null || !Number.isFinite(k)) return [120, 120, 120];
  if (k > kappaMax) return [240, 140, 60];
  const s = Math.min(1, Math.log(k) / Math.log(kappaMax));
  return [Math.round(40 + 215 * s), Math.round(150 + 80 * s), Math.round(170 - 120 * s)];
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
  ctx.imageSmoothingEnabled = false;
  ctx.drawImage(image, x0, y0, x1 - x0, y1 - y0);
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

/** Show the section of a /v1/workspace answer. */
export function setSection(section, kappa_max) {
  grid = section;
  kappaMax = kappa_max;
  image = null;
  const el = document.getElementById('section');
  chart?.destroy();
  el.replaceChildren();
  const ux = [grid.x[0], grid.x.at(-1)], wy = [grid.y[0], grid.y.at(-1)];
  const width = Math.max(220, el.clientWidth);
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
}

/** Draw the path of P (in-plane coordinates of each sample). */
export function setPath(p) { path = p; index = 0; chart?.redraw(false, false); }

/** Move the current point. */
export function setIndex(i) { index = i; chart?.redraw(false, false); }
