// The views of a sequence's answer (POST /v1/sequence): the legs (`sequence-list`: each
// leg's target, stop or pass, working mode at arrival and time span; the leg the timeline is
// in highlighted, a click seeks to the leg's first sample) and the blends (`blend-list`: each
// passed target's blend as asked and as used, blend_radius in mm, the shrunk ones marked).
//
// A view of an answer is a module with three functions, called by app.js for every answer:
// show(request, response, endpoint, ctx) (ctx: {t, seek}), clear() and setTime(t). A new
// view (simulation, belt, calibration) is one such module, one element in index.html with
// its data-testid, and one line in app.js's list of views.

const $ = (id) => document.getElementById(id);
const fmt = (x, d) => (typeof x === 'number' && Number.isFinite(x) ? x.toFixed(d) : '—');

/** The index of the first sample at or after time `t0` (the samples' times `t`, ascending);
 * t.length - 1 when every sample is before it. */
export function firstSampleFrom(t, t0) {
  let lo = 0, hi = t.length - 1;
  while (lo < hi) {
    const mid = (lo + hi) >> 1;
    if (t[mid] >= t0) hi = mid; else lo = mid + 1;
  }
  return lo;
}

/** The sequence's answer into its views; nothing shown for any other answer. */
export function show(request, response, endpoint, { t, seek }) {
  const seq = endpoint === 'sequence' && response?.legs ? response : null;
  renderLegs(request, seq, t, seek);
  renderBlends(request, seq);
}

export function clear() {
  renderLegs(null, null);
  renderBlends(null, null);
}

/** The target as typed (`q θ1 θ2 θ3` or `x y z`; the last leg of a cycle: the start). */
function targetText(request, i) {
  if (i >= request.targets.length) return 'the start (cycle)';
  const g = request.targets[i].goal;
  return g.q ? `q ${g.q.join(' ')}` : g.p.join(' ');
}

function renderLegs(request, response, t = [], seek = () => {}) {
  const table = $('sequence-list');
  const legs = response?.legs || [];
  table.hidden = !response;
  delete table.dataset.current;
  const span = (l) => (typeof l.start_time === 'number' ? `${l.start_time.toFixed(2)}–${l.end_time.toFixed(2)}` : '—');
  table.tBodies[0].replaceChildren(...legs.map((l, k) => {
    const tr = document.createElement('tr');
    tr.dataset.leg = String(k);
    tr.dataset.start = String(l.start_time ?? '');
    tr.dataset.end = String(l.end_time ?? '');
    const target = request.targets[l.target_index];
    const stopCell = target && target.stop === false ? 'pass' : 'stop';
    for (const text of [String(k), `${l.target_index}: ${targetText(request, l.target_index)}`, stopCell, l.working_mode || '—', span(l)]) {
      const td = document.createElement('td');
      td.textContent = text;
      tr.appendChild(td);
    }
    tr.title = `${l.status}${typeof l.pass_distance === 'number' ? `; passed within ${fmt(l.pass_distance, 4)} rad` : ''}`;
    // the leg's first sample, not the sample before its start (which belongs to the leg before)
    tr.addEventListener('click', () => { if (typeof l.start_time === 'number' && t.length) seek(t[firstSampleFrom(t, l.start_time)]); });
    return tr;
  }));
}

/** Highlight the leg whose time span [start, end) holds t (the last leg: up to the end). */
export function setTime(t) {
  const table = $('sequence-list');
  const rows = [...table.tBodies[0].rows];
  if (!rows.length) return;
  const k = rows.findIndex((r) => r.dataset.start !== '' && t >= Number(r.dataset.start) && t < Number(r.dataset.end));
  const current = k >= 0 ? k : t >= Number(rows.at(-1).dataset.end) ? rows.length - 1 : -1;
  rows.forEach((r, i) => r.classList.toggle('current', i === current));
  table.dataset.current = String(current);
}

/** A blend for the eye: a blend_radius (m) in mm, a joint-space blend in rad. */
export function blendText(value, unit) {
  return unit === 'm' ? `${fmt(1000 * value, 2)} mm` : `${fmt(value, 4)} rad`;
}

/** diagnostics.blends: per passed target, asked and used (used < asked: shrunk, marked). */
function renderBlends(request, response) {
  const box = $('blend-list');
  const blends = response?.diagnostics?.blends || [];
  box.hidden = !response || !blends.length;
  const shrunk = (b) => b.used < b.asked;
  box.dataset.shrunk = String(blends.filter(shrunk).length);
  box.tBodies[0].replaceChildren(...blends.map((b) => {
    const tr = document.createElement('tr');
    tr.dataset.target = String(b.target_index);
    tr.dataset.unit = b.unit;
    tr.dataset.asked = String(b.asked);
    tr.dataset.used = String(b.used);
    const note = !shrunk(b) ? '' : b.used === 0 ? 'not used: passed exactly' : 'shrunk to fit';
    tr.classList.toggle('shrunk', shrunk(b));
    const cells = [`${b.target_index}: ${targetText(request, b.target_index)}`, blendText(b.asked, b.unit), blendText(b.used, b.unit), note];
    for (const text of cells) {
      const td = document.createElement('td');
      td.textContent = text;
      tr.appendChild(td);
    }
    return tr;
  }));
}
