// The belt view (`belt-view`) of a sequence with parts on a belt (targets whose goal has a
// `velocity`, docs/conveyor.md): the belt (the part's straight path through the workspace),
// the part riding it in time with the playback, the tool point P and its path, and the
// meeting point (the leg's `meet_point` at `meet_time`). Drawn twice: in a 2-D view of its
// own, looking along the axis the belt moves least along (a horizontal belt: from above), and
// in the 3-D scene (the belt a tube, the part a cube, the meeting point a wire ball).
//
// The part is where the answer says it is: p + velocity (t - t0) on the belt until the end
// of its dwell (met at meet_time, held for dwell), then in the gripper (at P) until the tool
// rests at the next target (the place), then there. A part never met rides the belt.
//
// A view of an answer (see sequence.js): show(request, response, endpoint, ctx), clear(),
// setTime(t); ctx.scene (the 3-D Scene, when given) receives the 3-D drawing.
import * as THREE from 'three';

/** Colours of the drawing (the tests look for their pixels). */
export const COLORS = { belt: '#f5b700', part: '#c000c0', meet: '#111111', tool: '#d62728', path: '#9aa3b0', reach: '#c9ced6' };
const AXES = ['x', 'y', 'z'];
const PART_PX = 12;  // the part's square, CSS px
const BELT_PX = 10;  // the belt's band, CSS px

const $ = (id) => document.getElementById(id);
const fmt = (x, d) => (typeof x === 'number' && Number.isFinite(x) ? x.toFixed(d) : '—');
const add = (a, b, s = 1) => a.map((x, i) => x + s * b[i]);
const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];

let state = null;  // {belts, tool: {t, p}, reach, proj, scene, group, t}

/** The moving targets of a sequence request and their legs: [{index, p, velocity, t0,
 * dwell, leg, next}] (leg: the answer's leg of the target, next: the leg of the target after). */
export function beltsOf(request, response) {
  const targets = request?.targets || [];
  const legs = response?.legs || [];
  return targets.flatMap((tg, index) => {
    const g = tg.goal || {};
    const ok = (v, n) => Array.isArray(v) && v.length === n && v.every((x) => typeof x === 'number' && Number.isFinite(x));
    if (!ok(g.velocity, 3) || !ok(g.p, 3)) return [];
    const leg = legs.find((l) => l.target_index === index && typeof l.meet_time === 'number') || null;
    const next = legs.find((l) => l.target_index === index + 1) || null;
    return [{ index, p: g.p, velocity: g.velocity, t0: typeof g.t0 === 'number' ? g.t0 : 0, dwell: typeof tg.dwell === 'number' ? tg.dwell : 0, leg, next }];
  });
}

/** The sample of times `ts` (ascending) at or before t (the first when t is before it). */
function sampleAt(ts, t) {
  let lo = 0, hi = ts.length - 1;
  while (lo < hi) {
    const mid = (lo + hi + 1) >> 1;
    if (ts[mid] <= t + 1e-12) lo = mid; else hi = mid - 1;
  }
  return lo;
}

/** Where the part of belt `b` is at sequence time t, and whether on the belt, held or placed. */
export function partAt(b, t, tool) {
  const onBelt = add(b.p, b.velocity, t - b.t0);
  const picked = b.leg ? b.leg.meet_time + b.dwell : Infinity;
  if (!tool || !tool.p || t <= picked) return { p: onBelt, where: 'belt' };
  const placed = b.next && typeof b.next.end_time === 'number' ? b.next.end_time : Infinity;
  const at = tool.p[sampleAt(tool.t, Math.min(t, placed))];
  return { p: at, where: t >= placed ? 'placed' : 'held' };
}

/** The belt's stretch to draw: the chord of the ball of reach (radius R about the origin)
 * along the part's line, joined with where the part is over the trajectory's time span. */
function stretch(b, R, t0, t1) {
  const speed = Math.hypot(...b.velocity);
  const u = speed > 0 ? b.velocity.map((x) => x / speed) : [1, 0, 0];
  const s = (t) => dot(add(b.p, b.velocity, t - b.t0), u);  // along the line, from its foot
  const foot = add(b.p, u, -dot(b.p, u));  // the line's point nearest the origin
  const d2 = dot(foot, foot);
  const ends = [s(t0), s(t1)];
  if (d2 < R * R) ends.push(-Math.sqrt(R * R - d2), Math.sqrt(R * R - d2));
  return { a: add(foot, u, Math.min(...ends)), b: add(foot, u, Math.max(...ends)), u };
}

/** The 2-D projection: drop the axis the belts move least along (z on a tie: a horizontal
 * belt is seen from above). */
function projection(belts) {
  const along = [0, 1, 2].map((k) => Math.max(...belts.map((b) => Math.abs(b.velocity[k]) / (Math.hypot(...b.velocity) || 1))));
  let drop = 2;
  for (const k of [1, 0]) if (along[k] < along[drop] - 1e-9) drop = k;
  const keep = [0, 1, 2].filter((k) => k !== drop);
  return { keep, drop };
}

/** The sequence's answer into the belt view; hidden for an answer without a moving target. */
export function show(request, response, endpoint, ctx = {}) {
  clear();
  const belts = endpoint === 'sequence' && response?.legs ? beltsOf(request, response) : [];
  if (!belts.length) return;
  const tr = response.trajectory;
  const tool = tr && Array.isArray(tr.p) ? { t: tr.t, p: tr.p } : null;
  const d = request.design;
  const R = d.L0 / 2 + d.L1 + d.L2;
  const [ta, tb] = tr?.t?.length ? [tr.t[0], tr.t.at(-1)] : [0, 0];
  for (const b of belts) b.stretch = stretch(b, R, ta, tb);
  state = { belts, tool, R, proj: projection(belts), scene: ctx.scene || null, t: ta };
  const box = $('belt-view');
  box.hidden = false;
  box.dataset.belts = String(belts.length);
  box.dataset.meets = JSON.stringify(belts.map((b) => (b.leg ? { target: b.index, t: b.leg.meet_time, p: b.leg.meet_point } : { target: b.index, t: null, p: null })));
  $('belt-note').textContent = belts.map((b) => {
    const v = Math.hypot(...b.velocity);
    const dir = b.velocity.map((x) => fmt(x / (v || 1), 2)).join(', ');
    const met = b.leg
      ? `met at t = ${fmt(b.leg.meet_time, 3)} s at (${b.leg.meet_point.map((x) => fmt(x, 3)).join(', ')}) m in ${b.leg.working_mode}, held ${fmt(b.dwell, 2)} s`
      : 'not met';
    return `target ${b.index}: a part at ${fmt(v, 2)} m/s along (${dir}), at (${b.p.map((x) => fmt(x, 3)).join(', ')}) m at t = ${fmt(b.t0, 2)} s; ${met}.`;
  }).join(' ');
  if (state.scene) draw3d();
  watchSize();
  setTime(ta);
}

export function clear() {
  if (state?.group) {
    state.group.removeFromParent();
    state.group.traverse((o) => { o.geometry?.dispose(); o.material?.dispose(); });
    state.scene.render();
  }
  state = null;
  const box = $('belt-view');
  box.hidden = true;
  for (const k of ['belts', 'meets', 't', 'parts', 'tool', 'toolPx']) delete box.dataset[k];
  $('belt-note').textContent = '';
}

/** The view at sequence time t: the part (2-D and 3-D) where it is then, the tool at its
 * sample; the element says where, in metres and in the canvas's CSS pixels. */
export function setTime(t) {
  if (!state) return;
  state.t = t;
  const parts = state.belts.map((b) => ({ target: b.index, ...partAt(b, t, state.tool) }));
  const tool = state.tool ? state.tool.p[sampleAt(state.tool.t, t)] : null;
  const px = draw2d(parts, tool);
  const box = $('belt-view');
  box.dataset.t = String(t);
  box.dataset.parts = JSON.stringify(parts.map((p, i) => ({ ...p, px: px.parts[i] })));
  box.dataset.tool = tool ? JSON.stringify(tool) : '';
  box.dataset.toolPx = px.tool ? JSON.stringify(px.tool) : '';
  if (state.group) {
    parts.forEach((p, i) => state.cubes[i].position.set(...p.p));
    state.scene.render();
  }
}

// ------------------------------------------------------------------ 2-D
/** Draw the belts, the tool's path, the meeting points, the parts and the tool on the
 * canvas; the CSS pixels where each part and the tool are drawn. */
function draw2d(parts, tool) {
  const canvas = $('belt-canvas');
  const w = canvas.clientWidth || 300, h = canvas.clientHeight || 220;
  const dpr = window.devicePixelRatio || 1;
  if (canvas.width !== Math.round(w * dpr) || canvas.height !== Math.round(h * dpr)) {
    canvas.width = Math.round(w * dpr);
    canvas.height = Math.round(h * dpr);
  }
  const c = canvas.getContext('2d');
  c.setTransform(dpr, 0, 0, dpr, 0, 0);
  c.clearRect(0, 0, w, h);
  const { keep: [ka, kb], drop } = state.proj;
  // the frame: every belt's stretch (within the ball of reach) and the tool's path, equal
  // scales on both axes, at least 0.4 m across
  const pts = [...state.belts.flatMap((b) => [b.stretch.a, b.stretch.b]), ...(state.tool?.p || [])];
  const lo = [0, 1].map((i) => Math.min(...pts.map((p) => p[[ka, kb][i]])));
  const hi = [0, 1].map((i) => Math.max(...pts.map((p) => p[[ka, kb][i]])));
  for (const i of [0, 1]) {
    const grow = Math.max(0, 0.4 - (hi[i] - lo[i])) / 2;
    lo[i] -= grow; hi[i] += grow;
  }
  const pad = 22;
  const s = Math.min((w - 2 * pad) / (hi[0] - lo[0]), (h - 2 * pad) / (hi[1] - lo[1]));
  const ox = w / 2 - (s * (lo[0] + hi[0])) / 2, oy = h / 2 + (s * (lo[1] + hi[1])) / 2;
  const at = (p) => [ox + s * p[ka], oy - s * p[kb]];
  // the ball of reach, seen along the dropped axis; the axes' names
  c.strokeStyle = COLORS.reach;
  c.lineWidth = 1;
  c.setLineDash([4, 4]);
  c.beginPath(); c.arc(ox, oy, s * state.R, 0, 2 * Math.PI); c.stroke();
  c.setLineDash([]);
  c.fillStyle = '#5b6575';
  c.font = '11px system-ui, sans-serif';
  c.fillText(`${AXES[ka]} →   ${AXES[kb]} ↑   (seen along ${AXES[drop]})`, 6, h - 6);
  // the belts: a band along each stretch, an arrow for the direction
  for (const b of state.belts) {
    const [x1, y1] = at(b.stretch.a), [x2, y2] = at(b.stretch.b);
    c.strokeStyle = COLORS.belt;
    c.lineWidth = BELT_PX;
    c.lineCap = 'butt';
    c.beginPath(); c.moveTo(x1, y1); c.lineTo(x2, y2); c.stroke();
    const len = Math.hypot(x2 - x1, y2 - y1);
    if (len > 30) {
      const ux = (x2 - x1) / len, uy = (y2 - y1) / len;
      const mx = x2 - 8 * ux, my = y2 - 8 * uy;
      c.fillStyle = '#7a5b00';
      c.beginPath(); c.moveTo(mx + 6 * ux, my + 6 * uy); c.lineTo(mx - 6 * ux - 4 * uy, my - 6 * uy + 4 * ux); c.lineTo(mx - 6 * ux + 4 * uy, my - 6 * uy - 4 * ux); c.fill();
    }
  }
  // the tool's path
  if (state.tool) {
    c.strokeStyle = COLORS.path;
    c.lineWidth = 1.5;
    c.beginPath();
    state.tool.p.forEach((p, i) => { const [x, y] = at(p); if (i) c.lineTo(x, y); else c.moveTo(x, y); });
    c.stroke();
  }
  // the meeting points: a ring and the time
  for (const b of state.belts) {
    if (!b.leg?.meet_point) continue;
    const [x, y] = at(b.leg.meet_point);
    c.strokeStyle = COLORS.meet;
    c.lineWidth = 2;
    c.beginPath(); c.arc(x, y, 10, 0, 2 * Math.PI); c.stroke();
    c.fillStyle = COLORS.meet;
    const text = `meet ${fmt(b.leg.meet_time, 2)} s`;
    c.fillText(text, Math.min(x + 13, w - c.measureText(text).width - 4), Math.max(y - 14, 12));
  }
  // the parts (squares) and the tool (a disc) on top
  const partPx = parts.map((p) => {
    const [x, y] = at(p.p);
    c.fillStyle = COLORS.part;
    c.fillRect(x - PART_PX / 2, y - PART_PX / 2, PART_PX, PART_PX);
    return [x, y];
  });
  let toolPx = null;
  if (tool) {
    toolPx = at(tool);
    c.fillStyle = COLORS.tool;
    c.beginPath(); c.arc(toolPx[0], toolPx[1], 3.5, 0, 2 * Math.PI); c.fill();
  }
  return { parts: partPx, tool: toolPx };
}

/** Redraw at the canvas's new size (a resized window, a hidden panel shown). */
let watching = false;
function watchSize() {
  if (watching) return;
  watching = true;
  new ResizeObserver(() => { if (state) setTime(state.t); }).observe($('belt-canvas'));
}

// ------------------------------------------------------------------ 3-D
/** The belts (tubes), the meeting points (wire balls) and the parts (cubes) in the scene. */
function draw3d() {
  const group = new THREE.Group();
  const basic = (color, extra = {}) => new THREE.MeshBasicMaterial({ color: new THREE.Color(color), ...extra });
  state.cubes = state.belts.map((b) => {
    const { a, b: e } = b.stretch;
    const curve = new THREE.LineCurve3(new THREE.Vector3(...a), new THREE.Vector3(...e));
    group.add(new THREE.Mesh(new THREE.TubeGeometry(curve, 8, 0.008, 8, false), basic(COLORS.belt)));
    if (b.leg?.meet_point) {
      const m = new THREE.Mesh(new THREE.SphereGeometry(0.022, 16, 10), basic(COLORS.meet, { wireframe: true }));
      m.position.set(...b.leg.meet_point);
      group.add(m);
    }
    const cube = new THREE.Mesh(new THREE.BoxGeometry(0.05, 0.05, 0.05), basic(COLORS.part));
    group.add(cube);
    return cube;
  });
  state.group = group;
  state.scene.scene.add(group);
}
