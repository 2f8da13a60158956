// The design's region map from POST /v1/design/regions (with cell_regions): in the
// (theta2, theta3) grid of one assembly mode, each cell coloured by the region holding its
// centre posture (hue: the working mode, shade: the region), the regions and the transits
// between them listed, the path's (theta2, theta3) trace on it, and, for a plan proved
// infeasible, the regions of the start and of the goal with the components that separate them.
import { MODE_COLORS } from './scene.js';
import { swatch } from './section.js';

const canvas = document.getElementById('regions-canvas');
let map = null;        // the /v1/design/regions answer
let design = null;
let trace = null;      // {q2: [], q3: [], assembly, start, goal, proof}
const MARGIN = { left: 46, right: 20, top: 10, bottom: 34 };

const hex = (h) => [1, 3, 5].map((i) => parseInt(h.slice(i, i + 2), 16));

/** The region id of (theta2, theta3) in assembly mode asm, or -1 (outside the box, or none). */
export function regionAt(q2, q3, asm) {
  if (!map || !design) return -1;
  const n = map.resolution;
  const [lo2, lo3] = [design.joint_min[1], design.joint_min[2]];
  const [hi2, hi3] = [design.joint_max[1], design.joint_max[2]];
  const k2 = Math.floor(((q2 - lo2) / (hi2 - lo2)) * n), k3 = Math.floor(((q3 - lo3) / (hi3 - lo3)) * n);
  if (k2 < 0 || k3 < 0 || k2 >= n || k3 >= n) return -1;
  return map.cell_regions[asm === '-' ? 1 : 0][k3][k2];
}

export const regionById = (id) => map?.regions.find((r) => r.id === id) || null;

/** Show a new map (its request's design). */
export function setMap(answer, d) {
  map = answer;
  design = d;
  const modes = document.getElementById('regions-mode');
  const present = [...new Set(map.regions.map((r) => r.working_mode))].sort();
  const keep = modes.value;
  modes.replaceChildren(new Option('all', ''), ...present.map((m) => new Option(m, m)));
  modes.value = present.includes(keep) ? keep : '';
  draw();
}

/** The path's (theta2, theta3) trace and its start and goal (or null). */
export function setTrace(t) {
  trace = t;
  if (t) document.getElementById('regions-assembly').value = t.assembly;
  draw();
}

function shade(region) {
  const base = hex(MODE_COLORS[region.working_mode] || '#777777');
  const same = map.regions.filter((r) => r.working_mode === region.working_mode && r.assembly_mode === region.assembly_mode);
  const rank = same.findIndex((r) => r.id === region.id);
  const f = 0.55 + 0.45 * (same.length > 1 ? 1 - rank / (same.length - 1) : 1);  // largest: full colour
  return base.map((c) => Math.round(255 - (255 - c) * f));
}

/** Redraw the map, the trace and the lists for the chosen assembly and working mode. */
export function draw() {
  if (!map) return;
  const asm = document.getElementById('regions-assembly').value;
  const mode = document.getElementById('regions-mode').value;
  const ai = asm === '-' ? 1 : 0;
  const n = map.resolution;
  const cssW = Math.max(200, canvas.parentElement.clientWidth);
  const plot = Math.min(cssW - MARGIN.left - MARGIN.right, 420);
  const cssH = plot + MARGIN.top + MARGIN.bottom;
  const dpr = window.devicePixelRatio || 1;
  canvas.style.width = `${plot + MARGIN.left + MARGIN.right}px`;
  canvas.style.height = `${cssH}px`;
  canvas.width = Math.round((plot + MARGIN.left + MARGIN.right) * dpr);
  canvas.height = Math.round(cssH * dpr);
  const ctx = canvas.getContext('2d');
  ctx.setTransform(dpr, 0, 0, dpr, 0, 0);
  ctx.clearRect(0, 0, canvas.width, canvas.height);
  // cells: an n x n image, row 0 at the top = the largest theta3
  const img = document.createElement('canvas');
  img.width = n; img.height = n;
  const ictx = img.getContext('2d');
  const data = ictx.createImageData(n, n);
  const highlight = proofRegions();
  const colours = new Map(map.regions.map((r) => [r.id, shade(r)]));
  for (let k3 = 0; k3 < n; k3++) {
    for (let k2 = 0; k2 < n; k2++) {
      const id = map.cell_regions[ai][k3][k2];
      const o = 4 * ((n - 1 - k3) * n + k2);
      if (id < 0) { data.data[o + 3] = 0; continue; }
      const r = regionById(id);
      let c = colours.get(id);
      let alpha = !mode || r.working_mode === mode ? 255 : 60;
      if (highlight) {
        const side = highlight.start.has(r.component) ? 0 : highlight.goal.has(r.component) ? 1 : -1;
        c = side === 0 ? [46, 125, 50] : side === 1 ? [198, 40, 40] : [200, 200, 200];
        alpha = side < 0 ? 90 : 255;
      }
      data.data.set([...c, alpha], o);
    }
  }
  ictx.putImageData(data, 0, 0);
  ctx.imageSmoothingEnabled = false;
  ctx.fillStyle = '#f1f3f6';
  ctx.fillRect(MARGIN.left, MARGIN.top, plot, plot);
  ctx.drawImage(img, MARGIN.left, MARGIN.top, plot, plot);
  ctx.strokeStyle = '#999';
  ctx.strokeRect(MARGIN.left, MARGIN.top, plot, plot);
  drawn = [];
  delete canvas.dataset.markers;
  axes(ctx, plot);
  drawTrace(ctx, plot, ai);
  canvas.dataset.labels = JSON.stringify(drawn);
  lists(asm, mode, highlight);
}

const toX = (q2, plot) => MARGIN.left + ((q2 - design.joint_min[1]) / (design.joint_max[1] - design.joint_min[1])) * plot;
const toY = (q3, plot) => MARGIN.top + (1 - (q3 - design.joint_min[2]) / (design.joint_max[2] - design.joint_min[2])) * plot;

/** The boxes of the text drawn on the map ({text, x, y, w, h}, CSS px), kept on the canvas
 * as data-labels (tick labels, the start's and goal's labels) and data-markers (the start's
 * and goal's centres): what the tests check is on the canvas and clear of the rest. */
let drawn = [];

/** Write `text` at (x, y) with the context's alignment, and keep its box. */
function text(ctx, t, x, y) {
  const w = ctx.measureText(t).width, h = 12;
  const left = ctx.textAlign === 'center' ? x - w / 2 : ctx.textAlign === 'right' ? x - w : x;
  const top = ctx.textBaseline === 'top' ? y : ctx.textBaseline === 'bottom' ? y - h : y - h / 2;
  ctx.fillText(t, x, y);
  drawn.push({ text: t, x: left, y: top, w, h });
}

function axes(ctx, plot) {
  ctx.fillStyle = '#1d2430';
  ctx.font = '12px system-ui, sans-serif';
  ctx.textBaseline = 'top';
  for (let i = 0; i <= 4; i++) {  // the end ticks aligned inward: clear of the other axis's
    const q = design.joint_min[1] + (i / 4) * (design.joint_max[1] - design.joint_min[1]);
    ctx.textAlign = i === 0 ? 'left' : i === 4 ? 'right' : 'center';
    text(ctx, q.toFixed(2), toX(q, plot), MARGIN.top + plot + 3);
  }
  ctx.textAlign = 'center';
  text(ctx, 'θ2 (rad)', MARGIN.left + plot / 2, MARGIN.top + plot + 18);
  ctx.textAlign = 'right';
  for (let i = 0; i <= 4; i++) {
    const q = design.joint_min[2] + (i / 4) * (design.joint_max[2] - design.joint_min[2]);
    ctx.textBaseline = i === 0 ? 'bottom' : i === 4 ? 'top' : 'middle';
    text(ctx, q.toFixed(2), MARGIN.left - 4, toY(q, plot));
  }
  ctx.save();
  ctx.translate(11, MARGIN.top + plot / 2);
  ctx.rotate(-Math.PI / 2);
  ctx.textAlign = 'center';
  ctx.textBaseline = 'middle';
  ctx.fillText('θ3 (rad)', 0, 0);
  ctx.restore();
}

function drawTrace(ctx, plot, ai) {
  if (!trace || (trace.assembly === '-' ? 1 : 0) !== ai) return;
  ctx.save();
  ctx.beginPath();
  ctx.rect(MARGIN.left, MARGIN.top, plot, plot);
  ctx.clip();
  ctx.strokeStyle = '#111';
  ctx.lineWidth = 2;
  ctx.beginPath();
  trace.q2.forEach((q2, i) => {
    const x = toX(q2, plot), y = toY(trace.q3[i], plot);
    if (i) ctx.lineTo(x, y); else ctx.moveTo(x, y);
  });
  ctx.stroke();
  const at = (q) => (q ? { x: toX(q[1], plot), y: toY(q[2], plot) } : null);
  const start = at(trace.start), goal = at(trace.goal);
  // the goal a ring, the start a dot drawn over it: both show where they meet (a cycle)
  if (goal) {
    ctx.lineWidth = 3;
    ctx.strokeStyle = '#fff';
    ctx.beginPath(); ctx.arc(goal.x, goal.y, 8, 0, 2 * Math.PI); ctx.stroke();
    ctx.lineWidth = 2.5;
    ctx.strokeStyle = '#c62828';
    ctx.beginPath(); ctx.arc(goal.x, goal.y, 8, 0, 2 * Math.PI); ctx.stroke();
  }
  if (start) {
    ctx.fillStyle = '#2e7d32';
    ctx.strokeStyle = '#fff';  // ringed: it may lie on a region of its own colour
    ctx.lineWidth = 1.5;
    ctx.beginPath(); ctx.arc(start.x, start.y, 4.5, 0, 2 * Math.PI); ctx.fill(); ctx.stroke();
  }
  ctx.restore();
  const near = start && goal && Math.hypot(start.x - goal.x, start.y - goal.y) < 18;
  const labels = near ? [[start, 'start = goal']] : [[start, 'start'], [goal, 'goal']].filter(([p]) => p);
  for (const [p, name] of labels) label(ctx, p, name, plot);
  canvas.dataset.markers = JSON.stringify({ start, goal });
}

/** A marker's name beside it, on whichever side keeps it inside the plot and clear of the
 * labels already written. */
function label(ctx, p, name, plot) {
  ctx.font = '600 12px system-ui, sans-serif';
  const w = ctx.measureText(name).width, h = 12, gap = 10;
  const sides = [[p.x + gap, p.y - gap - h], [p.x - gap - w, p.y - gap - h], [p.x + gap, p.y + gap], [p.x - gap - w, p.y + gap]];
  const inside = ([x, y]) => x >= MARGIN.left && x + w <= MARGIN.left + plot && y >= MARGIN.top && y + h <= MARGIN.top + plot;
  const clear = ([x, y]) => drawn.every((b) => x + w <= b.x || b.x + b.w <= x || y + h <= b.y || b.y + b.h <= y);
  const [x, y] = sides.find((s) => inside(s) && clear(s)) || sides.find(inside) || sides[0];
  ctx.textAlign = 'left';
  ctx.textBaseline = 'top';
  ctx.lineWidth = 3;
  ctx.strokeStyle = '#fff';
  ctx.strokeText(name, x, y);
  ctx.fillStyle = '#111';
  text(ctx, name, x, y);
}

/** For a proved-infeasible answer: the components of the start's and the goal's regions. */
function proofRegions() {
  if (!trace?.proof || !trace.start || !trace.goal) return null;
  const s = regionById(regionAt(trace.start[1], trace.start[2], trace.assembly));
  const g = regionById(regionAt(trace.goal[1], trace.goal[2], trace.goalAssembly || trace.assembly));
  if (!s || !g) return null;
  return { start: new Set([s.component]), goal: new Set([g.component]), s, g };
}

function lists(asm, mode, highlight) {
  const shown = map.regions.filter((r) => r.assembly_mode === asm && (!mode || r.working_mode === mode));
  const ids = new Set(shown.map((r) => r.id));
  const note = document.getElementById('regions-note');
  const all = map.regions.filter((r) => r.assembly_mode === asm);
  note.textContent = `${all.length} regions in assembly mode ${asm} (${map.regions.length} in all, `
    + `${map.components} components joined by ${map.transits.length} transits), κ(A) ≤ ${map.margins.kappa_max}, `
    + `serial margin ≥ ${map.margins.serial_min}, ${map.resolution} × ${map.resolution} cells.`;
  const startId = trace?.start && trace.assembly === asm ? regionAt(trace.start[1], trace.start[2], asm) : -1;
  if (startId >= 0) note.dataset.startRegion = String(startId); else delete note.dataset.startRegion;
  if (highlight) {
    const { s, g } = highlight;
    note.textContent += s.component === g.component
      ? ` Start (region ${s.id}) and goal (region ${g.id}) are in one component.`
      : ` Proved infeasible: the start is in region ${s.id} (${s.working_mode}, component ${s.component}, green), `
        + `the goal in region ${g.id} (${g.working_mode}, component ${g.component}, red); no chain of transits joins them.`;
    note.dataset.separated = String(s.component !== g.component);
  } else {
    delete note.dataset.separated;
  }
  document.getElementById('regions-list').replaceChildren(...shown.map((r) => {
    const li = document.createElement('li');
    li.dataset.region = r.id;
    li.append(swatch(shade(r)), `region ${r.id}: ${r.working_mode} / ${r.assembly_mode}, ${r.cells} cells, component ${r.component}`);
    return li;
  }));
  const pairs = new Map();  // one line per pair of regions, with every kind of surface between them
  for (const t of map.transits.filter((x) => ids.has(x.from) || ids.has(x.to))) {
    const key = `${t.from}-${t.to}`;
    if (!pairs.has(key)) pairs.set(key, { ...t, kinds: [] });
    pairs.get(key).kinds.push(t.kind);
  }
  document.getElementById('regions-transits').replaceChildren(...[...pairs.values()].map((t) => {
    const li = document.createElement('li');
    const a = regionById(t.from), b = regionById(t.to);
    li.textContent = `transit ${t.from} (${a?.working_mode}) ↔ ${t.to} (${b?.working_mode}): sign ${t.flipped} flips across ${t.kinds.join(', ')}`;
    return li;
  }));
}

document.getElementById('regions-assembly').addEventListener('change', draw);
document.getElementById('regions-mode').addEventListener('change', draw);
