// The request form: values <-> a /v1/plan request body, the obstacle list, presets,
// examples, and the service's 422 messages shown next to the field that caused them.
// The service is the one validator: a field that is not a number is sent as typed, so the
// answer names it (detail[].loc) in the service's own words.

const form = document.getElementById('request-form');
const obstacleList = document.getElementById('obstacles');

/** Examples on the default design (start in working mode +-+). */
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
];

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
}

/** The /v1/plan request body the form holds. */
export function request() {
  const goal = goalKind() === 'q'
    ? { q: vector('goal.q'), assembly_mode: input('goal.assembly_mode').value }
    : { p: vector('goal.p'), working_mode: input('goal.working_mode').value };
  return {
    design: design(),
    start: { q: vector('start.q'), assembly_mode: input('start.assembly_mode').value },
    goal,
    obstacles: obstacles.map((o) => structuredClone(o)),
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
    limits: drop({ velocity: optionalVector('limits.velocity'), acceleration: optionalVector('limits.acceleration') }),
  };
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
}

/** Put an example's start, goal and obstacles into the form. */
export function setExample(ex) {
  ex.start.q.forEach((x, i) => setValue(`start.q.${i}`, x));
  setValue('start.assembly_mode', ex.start.assembly_mode);
  const kind = 'q' in ex.goal ? 'q' : 'p';
  form.querySelector(`input[name=goal-kind][value=${kind}]`).checked = true;
  ex.goal[kind].forEach((x, i) => setValue(`goal.${kind}.${i}`, x));
  if (kind === 'q') setValue('goal.assembly_mode', ex.goal.assembly_mode);
  else setValue('goal.working_mode', ex.goal.working_mode);
  showGoalKind();
  obstacles = ex.obstacles.map((o) => structuredClone(o));
  renderObstacles();
}

// ------------------------------------------------------------------ obstacles
function vecInputs(i, key, values) {
  return `<div class="field" data-loc="obstacles.${i}.${key}">${key} m
    <div class="vec">${values.map((v, k) => `<input type="number" step="any" data-o="${i}" data-key="${key}" data-k="${k}" data-loc="obstacles.${i}.${key}.${k}" value="${v}">`).join('')}</div></div>`;
}

function renderObstacles() {
  obstacleList.innerHTML = obstacles.map((o, i) => `
    <div class="obstacle" data-loc="obstacles.${i}">
      <div class="head"><span>${i + 1}. ${o.type}</span><button type="button" data-remove="${i}" title="delete">×</button></div>
      ${vecInputs(i, 'center', o.center)}
      ${o.type === 'sphere'
        ? `<label class="field" data-loc="obstacles.${i}.radius">radius m<input type="number" step="any" data-o="${i}" data-key="radius" value="${o.radius}"></label>`
        : vecInputs(i, 'size', o.size)}
    </div>`).join('') || '<div class="note">none</div>';
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
document.getElementById('add-box').addEventListener('click', () => {
  obstacles.push({ type: 'box', center: [0.4, 0.0, -0.3], size: [0.1, 0.1, 0.1], quaternion: [1, 0, 0, 0] });
  renderObstacles();
});

// ------------------------------------------------------------------ errors next to fields
/** The form's name for a 422 loc: "body" dropped, union tags (goal q|p, obstacle type) too. */
export function locPath(loc) {
  const path = loc[0] === 'body' ? loc.slice(1) : loc.slice();
  if (path[0] === 'goal' && path.length >= 3 && (path[1] === 'q' || path[1] === 'p')) path.splice(1, 1);
  if (path[0] === 'obstacles' && ['sphere', 'box', 'capsule'].includes(path[2])) path.splice(2, 1);
  return path.map(String);
}

export function clearErrors() {
  form.querySelectorAll('.field-error:not(.general)').forEach((e) => e.remove());
  form.querySelectorAll('[aria-invalid]').forEach((e) => e.removeAttribute('aria-invalid'));
  const general = document.getElementById('general-error');
  general.hidden = true;
  general.textContent = '';
}

/** Show each error of a 422 detail list next to the most precise field its loc names. */
export function showErrors(detail) {
  clearErrors();
  for (const item of detail) {
    const path = locPath(item.loc || []);
    let target = null, exact = null;
    for (let n = path.length; n > 0 && !target; n--) {
      const loc = path.slice(0, n).join('.');
      exact = form.querySelector(`[name="${loc}"], input[data-loc="${loc}"]`);
      target = form.querySelector(`.field[data-loc="${loc}"], fieldset[data-loc="${loc}"], .obstacle[data-loc="${loc}"], label[data-loc="${loc}"]`)
        || (exact && exact.closest('[data-loc]'));
    }
    const text = `${path.join('.') || 'request'}: ${item.msg}`;
    if (!target) {
      const general = document.getElementById('general-error');
      general.hidden = false;
      general.textContent += (general.textContent ? '\n' : '') + text;
      continue;
    }
    const el = document.createElement('div');
    el.className = 'field-error';
    el.dataset.testid = 'field-error';
    el.dataset.loc = path.join('.');
    el.textContent = text;
    target.appendChild(el);
    (exact || target.querySelector('input, select'))?.setAttribute('aria-invalid', 'true');
    target.closest('details')?.setAttribute('open', '');
  }
}

/** Wire the form: examples, goal kind, change notifications. */
export function init({ changed }) {
  onChange = changed;
  const select = document.getElementById('example');
  select.innerHTML = EXAMPLES.map((e, i) => `<option value="${i}">${e.name}</option>`).join('');
  select.addEventListener('change', () => setExample(EXAMPLES[Number(select.value)]));
  form.querySelectorAll('input[name=goal-kind]').forEach((r) => r.addEventListener('change', () => { showGoalKind(); changed(); }));
  form.addEventListener('input', (ev) => { if (!ev.target.dataset.key) changed(ev.target.name || ''); });
  form.addEventListener('change', (ev) => { if (ev.target.tagName === 'SELECT') changed(ev.target.name || ''); });
  setExample(EXAMPLES[0]);
}
