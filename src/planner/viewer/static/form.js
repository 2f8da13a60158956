// The request form: values <-> a /v1/plan request body, the obstacle list, presets,
// examples, and the service's 422 messages shown next to the field that caused them.
// The service is the one validator: a field that is not a number is sent as typed, so the
// answer names it (detail[].loc) in the service's own words; checks.js says the same sooner,
// as each field is typed, from the service's own schema.
import * as checks from './checks.js';
import { posture } from './kin.js';
import * as cloud from './cloud.js';

const form = document.getElementById('request-form');
const obstacleList = document.getElementById('obstacles');

/** Examples on the default design (start in working mode +-+): choosing one sets the design
 * back to the service's default and every start, goal and obstacle field, hidden ones too. */
export const EXAMPLES = [
  {
    name: 'Around a sphere (default)',
    start: { q: [0.0, 2.0, 1.0], assembly_mode: '+' },
    goal: { q: [0.9, 1.7, 0.6], assembly_mode: '+' },
    obstacles: [{ type: 'sphere', center: [0.59, 0.08, -0.29], radius: 0.06 }],
  },
  {
    name: 'Mode change: +-+ to ++- (two transits)',
    start: { q: [0.0, 2.0, 1.0], assembly_mode: '+' },
    goal: { p: [-0.25, 0.07, -0.38], working_mode: '++-' },
    obstacles: [],
  },
  {
    name: 'Mode change: +-+ to +++ (one transit)',
    start: { q: [0.0, 2.0, 1.0], assembly_mode: '+' },
    goal: { p: [-0.25, 0.07, -0.38], working_mode: '+++' },
    obstacles: [{ type: 'box', center: [0.0, -0.45, 0.45], size: [0.1, 0.1, 0.1], quaternion: [1, 0, 0, 0] }],
  },
  {
    name: 'Straight path: a square, then out of reach',
    start: { q: [0.0, 2.0, 1.0], assembly_mode: '+' },
    waypoints: [[0.5, 0.1, 0.0], [0.5, 0.1, -0.1], [0.5, 0.0, -0.1], [1.5, 0.0, -0.1]],
    obstacles: [],
  },
  {
    name: 'Sequence: pick and place (cycle)',
    start: { q: [0.90975, 2.76741, 1.04726], assembly_mode: '+' },
    targets: ['0.35 -0.1 -0.4 pass', '0.35 0.2 -0.4 pass', '0.35 0.2 -0.45'],
    blend: 0.04,
    cycle: true,
    obstacles: [],
  },
  {
    // examples/07_conveyor.py's first part: the belt along x at 0.5 m/s, the bin a stop
    name: 'Pick from a belt (0.5 m/s), place at a bin',
    start: { q: [1.98902066, 1.68682059, -0.4043776], assembly_mode: '+' },  // P at the bin
    targets: ['-0.75 0 -0.45 belt 0.5 0 0 t0 0 dwell 0.1', '-0.2 0.25 -0.45'],
    obstacles: [],
  },
];

/** The working mode labels a Cartesian target accepts. */
export const WORKING_MODES = ['any', '+++', '++-', '+-+', '+--', '-++', '-+-', '--+', '---'];

let obstacles = [];
let onChange = () => {};

const input = (name) => form.elements.namedItem(name);

function setValue(name, value) {
  const el = input(name);
  if (!el) return;
  if (el.type === 'checkbox') el.checked = Boolean(value);
  else el.value = value ?? '';
}

/** A number field's value: a number, the text as typed when it is not one, or undefined. */
function number(el) {
  const raw = el.value.trim();
  if (raw === '') return el.validity && el.validity.badInput ? 'not a number' : undefined;
  const x = Number(raw);
  return Number.isFinite(x) ? x : raw;
}

const read = (name) => number(input(name));
const vector = (name) => [0, 1, 2].map((i) => read(`${name}.${i}`));
const optionalVector = (name) => {
  const v = vector(name);
  return v.every((x) => x === undefined) ? undefined : v.map((x) => (x === undefined ? '' : x));
};
const drop = (obj) => Object.fromEntries(Object.entries(obj).filter(([, v]) => v !== undefined));

export const goalKind = () => form.querySelector('input[name=goal-kind]:checked').value;

function showGoalKind() {
  const kind = goalKind();
  document.getElementById('goal-q').hidden = kind !== 'q';
  document.getElementById('goal-p').hidden = kind !== 'p';
  document.getElementById('goal-path').hidden = kind !== 'path';
  document.getElementById('goal-seq').hidden = kind !== 'seq';
  document.getElementById('plan-button').textContent = { path: 'Plan straight path', seq: 'Plan sequence' }[kind] || 'Plan';
}

/** The endpoint the form's request goes to: 'plan' (/v1/plan), 'cartesian' (/v1/cartesian)
 * or 'sequence' (/v1/sequence). */
export const endpoint = () => ({ path: 'cartesian', seq: 'sequence' }[goalKind()] || 'plan');

/** A part on a belt in a target's words: "belt vx vy vz" (m/s), "t0 s" (when the part is
 * at x y z), "dwell s", taken out of `words`; {velocity, t0, dwell}, each undefined when
 * absent (numbers, or the text typed). */
function beltWords(words) {
  const num = (x) => (x === undefined ? '' : Number.isFinite(Number(x)) ? Number(x) : x);
  const out = {};
  for (const [key, n] of [['belt', 3], ['t0', 1], ['dwell', 1]]) {
    const k = words.findIndex((w) => w.toLowerCase() === key);
    if (k < 0) continue;
    const values = words.splice(k, n + 1).slice(1);
    while (values.length < n) values.push(undefined);
    out[key] = n === 3 ? values.map(num) : num(values[0]);
  }
  return { velocity: out.belt, t0: out.t0, dwell: out.dwell };
}

/** The sequence's targets as typed, one a line: "x y z" (a Cartesian target, working mode
 * any) or "q t1 t2 t3" (a joint posture in the start's assembly mode), "pass" at the end for
 * a target passed at speed, with the form's blend or the number after "pass" (in the form's
 * unit: rad goes out as `blend`, mm as `blend_radius` in m); "x y z belt vx vy vz t0 s
 * dwell s" a part on a belt (goal.velocity, goal.t0, dwell: docs/conveyor.md). */
export function targets() {
  const asm = input('start.assembly_mode').value;
  const mm = input('blend-unit').value === 'mm';
  const blendOf = (x) => {
    if (x === undefined || typeof x !== 'number') return x;
    return mm ? x / 1000 : x;
  };
  const given = read('blend');
  return input('targets').value.split('\n').map((l) => l.trim()).filter((l) => l).map((line) => {
    const words = line.split(/[\s,;]+/);
    const { velocity, t0, dwell } = beltWords(words);
    let own;
    if (words.length >= 2 && words.at(-2).toLowerCase() === 'pass') {
      const x = words.pop();
      own = Number.isFinite(Number(x)) ? Number(x) : x;
    }
    const pass = words.at(-1).toLowerCase() === 'pass';
    if (pass || words.at(-1).toLowerCase() === 'stop') words.pop();
    const joint = words[0]?.toLowerCase() === 'q';
    if (joint) words.shift();
    const xs = words.map((x) => (Number.isFinite(Number(x)) ? Number(x) : x));
    const goal = drop({ ...(joint ? { q: xs, assembly_mode: asm } : { p: xs, working_mode: 'any' }), velocity, t0 });
    const blend = pass ? blendOf(own ?? given) : undefined;
    return drop({ goal, stop: !pass, [mm ? 'blend_radius' : 'blend']: blend, dwell });
  });
}

/** The straight path's waypoints as typed: one "x y z" per line (numbers, or the text typed). */
export function waypoints() {
  return input('waypoints').value.split('\n').map((l) => l.trim()).filter((l) => l)
    .map((l) => l.split(/[\s,;]+/).map((x) => (Number.isFinite(Number(x)) ? Number(x) : x)));
}

export function setWaypoints(points) {
  input('waypoints').value = points.map((p) => p.map((x) => +x.toFixed(4)).join(' ')).join('\n');
}

/** Append a waypoint (e.g. picked on the workspace section) and say so. */
export function addWaypoint(p) {
  setWaypoints([...waypoints().filter((w) => w.length === 3 && w.every((x) => typeof x === 'number')), p]);
  typed(input('waypoints'));
  onChange('waypoints');
}

/** The request body the form holds, for its endpoint (see endpoint()). */
export function request() {
  const ep = endpoint();
  return ep === 'cartesian' ? cartesianRequest() : ep === 'sequence' ? sequenceRequest() : request.plan();
}

/** The /v1/plan request body (whatever the goal kind shown, a joint or Cartesian goal). */
request.plan = function planRequest() {
  const goal = goalKind() === 'q'
    ? { q: vector('goal.q'), assembly_mode: input('goal.assembly_mode').value }
    : { p: vector('goal.p'), working_mode: input('goal.working_mode').value };
  const payload = read('design.inertia.payload.mass');
  return {
    design: payload === undefined ? design() : { ...design(), inertia: { payload: { mass: payload } } },
    start: { q: vector('start.q'), assembly_mode: input('start.assembly_mode').value },
    goal,
    obstacles: obstacles.map(copyObstacle),
    ...(sceneName() ? { scene: sceneName() } : {}),
    margins: drop({
      kappa_max: read('margins.kappa_max'), serial_min: read('margins.serial_min'),
      clearance: read('margins.clearance'),
    }),
    planner: drop({
      name: input('planner.name').value, time_budget_s: read('planner.time_budget_s'),
      seed: read('planner.seed'), simplify: input('planner.simplify').checked,
      stop_at_transits: input('planner.stop_at_transits').checked,
    }),
    timing: drop({ method: input('timing.method').value, sample_rate_hz: read('timing.sample_rate_hz') }),
    limits: drop({
      velocity: optionalVector('limits.velocity'), acceleration: optionalVector('limits.acceleration'),
      torque: optionalVector('limits.torque'),
    }),
    ...(input('gravity').checked ? {} : { gravity: [0, 0, 0] }),
  };
};

/** The /v1/sequence request body: the plan's fields but the goal, the targets and cycle. */
function sequenceRequest() {
  const { goal, ...r } = request.plan();
  return { ...r, targets: targets(), cycle: input('cycle').checked };
}

/** The /v1/cartesian request body: the plan's fields that a straight path takes. */
function cartesianRequest() {
  const r = request.plan();
  return drop({
    design: r.design, start: r.start, waypoints: waypoints(),
    path_tolerance: read('path_tolerance'),
    obstacles: r.obstacles, scene: r.scene, margins: r.margins, timing: r.timing, limits: r.limits,
    gravity: r.gravity,
  });
}

/** The design part of the form. */
export function design() {
  return drop({
    L0: read('design.L0'), L1: read('design.L1'), L2: read('design.L2'),
    link_radius: read('design.link_radius'),
    joint_min: vector('design.joint_min'), joint_max: vector('design.joint_max'),
  });
}

export function setDesign(d) {
  for (const k of ['L0', 'L1', 'L2', 'link_radius']) setValue(`design.${k}`, d[k]);
  for (const k of ['joint_min', 'joint_max']) d[k].forEach((x, i) => setValue(`design.${k}.${i}`, x));
  recheck();
}

/** Put an example into the form: its design (`d`, the service's default), start, goal and
 * obstacles, and every field a goal kind not shown would use, so none keeps a value from
 * before: a joint goal also fills the Cartesian point with its P (working mode "any") and the
 * straight path with that point; a Cartesian goal leaves the joint goal empty (to be typed). */
export function setExample(ex, d) {
  if (d) setDesign(d);
  ex.start.q.forEach((x, i) => setValue(`start.q.${i}`, x));
  setValue('start.assembly_mode', ex.start.assembly_mode);
  const kind = ex.targets ? 'seq' : ex.waypoints ? 'path' : 'q' in ex.goal ? 'q' : 'p';
  form.querySelector(`input[name=goal-kind][value=${kind}]`).checked = true;
  const g = ex.goal || {};
  const dd = d || design();
  const x = g.q && [dd.L0, dd.L1, dd.L2].every((v) => typeof v === 'number') ? posture(dd, g.q, g.assembly_mode) : null;
  const p = g.p || x?.P || ex.waypoints?.at(-1) || null;
  [0, 1, 2].forEach((i) => setValue(`goal.q.${i}`, g.q ? g.q[i] : ''));
  setValue('goal.assembly_mode', g.assembly_mode || ex.start.assembly_mode);
  [0, 1, 2].forEach((i) => setValue(`goal.p.${i}`, p ? +p[i].toFixed(6) : ''));
  setValue('goal.working_mode', g.working_mode || 'any');
  setWaypoints(ex.waypoints || (p ? [p] : []));
  setValue('path_tolerance', '');
  input('targets').value = ex.targets ? ex.targets.join('\n') : p ? p.map((v) => +v.toFixed(6)).join(' ') : '';
  setValue('blend', ex.blend ?? '');
  setValue('blend-unit', ex.blendUnit || 'rad');
  input('cycle').checked = Boolean(ex.cycle);
  showGoalKind();
  obstacles = ex.obstacles.map((o) => structuredClone(o));
  renderObstacles();
  recheck();
}

// ------------------------------------------------------------------ obstacles
/** A request's copy of an obstacle; a cloud's points array is shared, not copied (the page
 * never edits points, and copying 100,000 of them at every keystroke would stall it). */
const copyObstacle = (o) => (o.type === 'points' ? { ...o } : structuredClone(o));

/** The form's obstacles, as they are (read only: for drawing). */
export const currentObstacles = () => obstacles;

/** The named scene chosen ('' for none). */
export const sceneName = () => input('scene')?.value || '';

/** Replace the obstacles (e.g. after they were saved as a scene). */
export function setObstacles(list) {
  obstacles = list.map(copyObstacle);
  renderObstacles();
}

/** The file each cloud came from, by its points array (not a field: the request carries none). */
const sources = new WeakMap();

function cloudItem(o, i) {
  return `<div class="obstacle cloud" data-loc="obstacles.${i}" data-testid="cloud-item" data-count="${o.points.length}">
      <div class="head"><span>${i + 1}. point cloud${sources.has(o.points) ? ` from ${escapeHTML(sources.get(o.points))}` : ''}</span><button type="button" data-remove="${i}" title="delete">×</button></div>
      <div class="note" data-loc="obstacles.${i}.points">${cloud.summary(o)}</div>
      <label class="field" data-loc="obstacles.${i}.radius">radius of every point m<input type="number" step="any" data-o="${i}" data-key="radius" value="${o.radius}"></label>
    </div>`;
}

const escapeHTML = (t) => String(t).replace(/[&<>"']/g, (c) => `&#${c.charCodeAt(0)};`);

function vecInputs(i, key, values) {
  return `<div class="field" data-loc="obstacles.${i}.${key}">${key} m
    <div class="vec">${values.map((v, k) => `<input type="number" step="any" data-o="${i}" data-key="${key}" data-k="${k}" data-loc="obstacles.${i}.${key}.${k}" value="${v}">`).join('')}</div></div>`;
}

function renderObstacles() {
  const radius = (i, o) => `<label class="field" data-loc="obstacles.${i}.radius">radius m<input type="number" step="any" data-o="${i}" data-key="radius" value="${o.radius}"></label>`;
  obstacleList.innerHTML = obstacles.map((o, i) => (o.type === 'points' && Array.isArray(o.points) ? cloudItem(o, i) : `
    <div class="obstacle" data-loc="obstacles.${i}">
      <div class="head"><span>${i + 1}. ${escapeHTML(o.type)}</span><button type="button" data-remove="${i}" title="delete">×</button></div>
      ${o.type === 'capsule' ? `${vecInputs(i, 'a', o.a || [])}${vecInputs(i, 'b', o.b || [])}${radius(i, o)}`
        : `${vecInputs(i, 'center', o.center || [])}${o.type === 'sphere' ? radius(i, o) : vecInputs(i, 'size', o.size || [])}`}
    </div>`)).join('') || '<div class="note">none</div>';
  recheck();
  onChange();
}

obstacleList.addEventListener('input', (ev) => {
  const el = ev.target;
  if (!el.dataset.key) return;
  const o = obstacles[Number(el.dataset.o)];
  const value = number(el);
  if (el.dataset.k !== undefined) o[el.dataset.key][Number(el.dataset.k)] = value ?? '';
  else o[el.dataset.key] = value ?? '';
  onChange();
});
obstacleList.addEventListener('click', (ev) => {
  const i = ev.target.dataset.remove;
  if (i === undefined) return;
  obstacles.splice(Number(i), 1);
  renderObstacles();
});
document.getElementById('add-sphere').addEventListener('click', () => {
  obstacles.push({ type: 'sphere', center: [0.4, 0.0, 0.3], radius: 0.05 });
  renderObstacles();
});
/** A file of obstacles (a point cloud's x y z rows, or JSON) added to the list; what cannot
 * be read is said next to the file field, with its line. */
document.getElementById('cloud-file').addEventListener('change', async (ev) => {
  const file = ev.target.files[0];
  clearAt('cloud-file');
  if (!file) return;
  const r = number(document.getElementById('cloud-radius'));
  try {
    const list = cloud.parse(await file.text(), file.name, r);
    for (const o of list) if (o.type === 'points' && Array.isArray(o.points)) sources.set(o.points, file.name);
    obstacles.push(...list);
    const form = document.getElementById('request-form');
    form.dataset.cloudLoads = String(Number(form.dataset.cloudLoads || 0) + 1);
    renderObstacles();
  } catch (err) {
    if (!(err instanceof cloud.CloudError)) throw err;
    sayAt('cloud-file', `${file.name}: ${err.message}`);
  } finally {
    ev.target.value = '';  // the same file may be chosen again
  }
});
document.getElementById('add-box').addEventListener('click', () => {
  obstacles.push({ type: 'box', center: [0.4, 0.0, -0.3], size: [0.1, 0.1, 0.1], quaternion: [1, 0, 0, 0] });
  renderObstacles();
});

// ------------------------------------------------------------------ errors next to fields
/** The form's name for a 422 loc: "body" dropped, union tags (goal q|p, obstacle type) too. */
export function locPath(loc) {
  const path = loc[0] === 'body' ? loc.slice(1) : loc.slice();
  if (path[0] === 'goal' && path.length >= 3 && (path[1] === 'q' || path[1] === 'p')) path.splice(1, 1);
  if (path[0] === 'obstacles' && ['sphere', 'box', 'capsule', 'points'].includes(path[2])) path.splice(2, 1);
  return path.map(String);
}

/** Remove the service's messages (before a new request; the typed checks stay). */
export function clearErrors() {
  form.querySelectorAll('.field-error:not(.general)[data-source=service]').forEach((e) => e.remove());
  form.querySelectorAll('[data-invalid=service]').forEach((e) => { e.removeAttribute('aria-invalid'); delete e.dataset.invalid; });
  const general = document.getElementById('general-error');
  general.hidden = true;
  general.textContent = '';
}

/** The field element a loc (list of strings) points at, and its input. */
function targetOf(path) {
  let target = null, exact = null;
  for (let n = path.length; n > 0 && !target; n--) {
    const loc = path.slice(0, n).join('.');
    exact = form.querySelector(`[name="${loc}"], input[data-loc="${loc}"]`);
    target = form.querySelector(`.field[data-loc="${loc}"], fieldset[data-loc="${loc}"], .obstacle[data-loc="${loc}"], label[data-loc="${loc}"]`)
      || (exact && exact.closest('[data-loc]'));
  }
  return { target, exact };
}

function showError(path, msg, source) {
  const text = `${path.join('.') || 'request'}: ${msg}`;
  const { target, exact } = targetOf(path);
  if (!target) {
    const general = document.getElementById('general-error');
    general.hidden = false;
    general.textContent += (general.textContent ? '\n' : '') + text;
    return;
  }
  const el = document.createElement('div');
  el.className = 'field-error';
  el.dataset.testid = 'field-error';
  el.dataset.loc = path.join('.');
  el.dataset.source = source;
  el.textContent = text;
  target.appendChild(el);
  const box = exact || target.querySelector('input, select, textarea');
  if (box && box.dataset.invalid !== 'typed') { box.setAttribute('aria-invalid', 'true'); box.dataset.invalid = source; }
  target.closest('details')?.setAttribute('open', '');
}

/** Say `msg` next to the field of `loc` (e.g. "scene-name"), as the service's. */
export function sayAt(loc, msg) {
  clearAt(loc);
  showError(loc.split('.'), msg, 'service');
}

/** Take the messages next to the field of `loc` away. */
export function clearAt(loc) {
  form.querySelectorAll(`.field-error[data-loc="${loc}"]`).forEach((e) => e.remove());
}

/** Show each error of a 422 detail list next to the most precise field its loc names. */
export function showErrors(detail) {
  clearErrors();
  for (const item of detail) {
    const path = locPath(item.loc || []);
    // the service's word replaces the typed check's at the same field (they say the same)
    form.querySelectorAll(`.field-error[data-source=typed][data-loc="${path.join('.')}"]`).forEach((e) => e.remove());
    showError(path, item.msg, 'service');
  }
}

// ------------------------------------------------------------------ checked as typed
/** The loc of a number field of the form ("design.L1", "obstacles.0.center.2"), or null. */
function locOf(el) {
  if (el.dataset.key === 'radius') return `obstacles.${el.dataset.o}.radius`;
  if (el.dataset.loc) return el.dataset.loc;
  return el.name && el.type === 'number' ? el.name : null;
}

const REQUIRED = /^(design\.(L0|L1|L2|link_radius|joint_m(in|ax)\.\d)|start\.q\.\d|goal\.[qp]\.\d|obstacles\..*)$/;

function typedMessage(el) {
  if (el.name === 'waypoints') return waypointMessage();
  if (el.name === 'targets') return targetsMessage();
  const loc = locOf(el);
  if (!loc || el.closest('[hidden]')) return '';
  const ep = endpoint();
  const hint = (p) => (p === 'goal' ? goalKind() : /^obstacles\.\d+$/.test(p) ? obstacles[Number(p.split('.')[1])]?.type : null);
  return checks.check(ep === 'cartesian' && loc.startsWith('goal.') ? 'plan' : ep, loc, number(el), { required: REQUIRED.test(loc), hint });
}

function waypointMessage() {
  if (goalKind() !== 'path') return '';
  const points = waypoints();
  if (!points.length) return 'at least one waypoint: one "x y z" per line (m)';
  for (const [i, w] of points.entries()) {
    if (w.length !== 3 || w.some((x) => typeof x !== 'number')) return `line ${i + 1}: three numbers x y z (m)`;
    for (const [k, x] of w.entries()) {
      const m = checks.check('cartesian', `waypoints.${i}.${k}`, x);
      if (m) return `line ${i + 1}: ${m}`;
    }
  }
  return '';
}

function targetsMessage() {
  if (goalKind() !== 'seq') return '';
  const ts = targets();
  if (!ts.length) return 'at least one target: one "x y z" (m) or "q θ1 θ2 θ3" (rad) per line';
  for (const [i, t] of ts.entries()) {
    const xs = t.goal.q || t.goal.p;
    if (xs.length !== 3 || xs.some((x) => typeof x !== 'number')) {
      return `line ${i + 1}: three numbers, x y z (m) or q θ1 θ2 θ3 (rad), then "pass" or nothing`;
    }
    const field = t.goal.q ? 'q' : 'p';
    for (const [k, x] of xs.entries()) {
      const m = checks.check('sequence', `targets.${i}.goal.${field}.${k}`, x, { hint: (p) => (p.endsWith('.goal') ? field : null) });
      if (m) return `line ${i + 1}: ${m}`;
    }
    const v = t.goal.velocity;
    if (v && (v.length !== 3 || v.some((x) => typeof x !== 'number'))) return `line ${i + 1}: belt vx vy vz: three numbers (m/s)`;
    if ('t0' in t.goal && typeof t.goal.t0 !== 'number') return `line ${i + 1}: t0: a number (s)`;
    for (const key of ['blend', 'blend_radius', 'dwell']) {
      const m = key in t ? checks.check('sequence', `targets.${i}.${key}`, t[key]) : '';
      if (m) return `line ${i + 1}: ${key} ${m}`;
    }
  }
  return '';
}

/** Check one field as typed: its message next to it, or none. */
export function typed(el) {
  const loc = el.name === 'waypoints' || el.name === 'targets' ? el.name : locOf(el);
  if (!loc) return;
  const { target } = targetOf(loc.split('.'));
  target?.querySelectorAll(`.field-error[data-source=typed][data-loc="${loc}"]`).forEach((e) => e.remove());
  if (el.dataset.invalid === 'typed') { el.removeAttribute('aria-invalid'); delete el.dataset.invalid; }
  const msg = typedMessage(el);
  if (msg) {
    showError(loc.split('.'), msg, 'typed');
    el.setAttribute('aria-invalid', 'true');
    el.dataset.invalid = 'typed';
  }
}

/** Check every field again (after an example, a preset or a goal kind changed them). */
export function recheck() {
  if (!checks.loaded()) return;
  form.querySelectorAll('input[type=number], textarea[name=waypoints], textarea[name=targets]').forEach(typed);
}

/** The schema the checks read, then every field checked. */
export async function loadChecks(getJSON) {
  await checks.load(getJSON);
  form.dataset.checks = 'loaded';
  recheck();
}

/** Wire the form: examples, goal kind, change notifications. */
export function init({ changed, exampleChosen }) {
  onChange = changed;
  const select = document.getElementById('example');
  select.innerHTML = EXAMPLES.map((e, i) => `<option value="${i}">${e.name}</option>`).join('');
  select.addEventListener('change', () => exampleChosen(EXAMPLES[Number(select.value)]));
  form.querySelectorAll('input[name=goal-kind]').forEach((r) => r.addEventListener('change', () => { showGoalKind(); recheck(); changed('goal-kind'); }));
  form.addEventListener('input', (ev) => {
    typed(ev.target);
    if (ev.target.name === 'blend' || ev.target.name === 'blend-unit') typed(input('targets'));  // the targets' blends
    if (!ev.target.dataset.key) changed(ev.target.name || '');
  });
  form.addEventListener('change', (ev) => { if (ev.target.tagName === 'SELECT') changed(ev.target.name || ''); });
  setExample(EXAMPLES[0]);
}
