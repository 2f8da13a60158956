// Calibration (POST /v1/calibrate, docs/calibration.md): a panel with its own request, not a
// view of the plan's answer. A measurements file is loaded into the body box (or the body is
// pasted there): the same body as `planner calibrate FILE`, {"design"?, "measurements":
// [{"q", "p", ...}], "identify"?, "frame"?}. **Calibrate** sends it as it stands and shows
// the identified parameters (each with its standard deviation, or held: not asked, or named
// unidentified), the design, the offsets, the tracker's frame, the condition number, and the
// residual of each measurement as a bar in mm against the RMS and the maximum
// (`calibration-residuals`). **Use this design** puts the identified lengths into the form's
// design (as a preset does); the offsets and the frame are the controller's and the
// tracker's business, not the design's, and stay in the panel.

import { ApiError, postJSON } from './api.js';

const $ = (id) => document.getElementById(id);
let shown = null;  // {body, answer}: what the panel shows (read by the tests)
let asked = 0;
let useDesign = () => {};

/** The identified model, one row per parameter: [name, value, unit]. */
function parameters(answer) {
  const d = answer.design;
  const legs = answer.leg_lengths;
  const lengths = legs ? [['L0', d.L0], ...Object.entries(legs)] : [['L0', d.L0], ['L1', d.L1], ['L2', d.L2]];
  return [
    ...lengths.map(([n, v]) => [n, v, 'm']),
    ...answer.offsets.map((v, k) => [`offsets[${k}]`, v, 'rad']),
    ...answer.frame.position.map((v, k) => [`frame.position[${k}]`, v, 'm']),
    ...answer.frame.rotation.map((v, k) => [`frame.rotation[${k}]`, v, 'rad']),
  ];
}

function cell(tr, text, cls = '') {
  const td = document.createElement('td');
  td.textContent = text;
  if (cls) td.className = cls;
  tr.appendChild(td);
}

function renderParameters(answer) {
  const rows = parameters(answer).map(([name, value, unit]) => {
    const tr = document.createElement('tr');
    tr.dataset.name = name;
    tr.dataset.value = String(value);
    const std = answer.std[name];
    const unidentified = answer.unidentified.includes(name);
    tr.classList.toggle('unidentified', unidentified);
    cell(tr, name);
    cell(tr, `${value.toFixed(unit === 'm' ? 6 : 7)} ${unit}`);
    cell(tr, unidentified ? 'unidentified: held at nominal' : typeof std === 'number' ? `± ${std.toExponential(2)}` : 'held (not asked)');
    return tr;
  });
  $('calibration-parameters').tBodies[0].replaceChildren(...rows);
  const none = answer.unidentified.length === 0;
  $('calibration-unidentified').textContent = none ? 'none' : answer.unidentified.join(', ');
  $('calibration-unidentified').dataset.value = JSON.stringify(answer.unidentified);
  $('calibration-condition').textContent = answer.condition_number.toPrecision(4);
  const { inertia, ...design } = answer.design;
  $('calibration-design').textContent = JSON.stringify(design);
}

/** One bar per measurement, its length its residual on a scale to the largest; the RMS as
 * a line across the bars. */
function renderResiduals(answer) {
  const box = $('calibration-residuals');
  const res = answer.residuals_m.map((r) => 1000 * r);
  const top = Math.max(...res, 1e-12);
  const rms = 1000 * answer.residual_rms_m;
  const max = 1000 * answer.residual_max_m;
  box.dataset.count = String(res.length);
  box.dataset.rmsMm = String(rms);
  box.dataset.maxMm = String(max);
  $('calibration-rms').textContent = `${rms.toPrecision(3)} mm`;
  $('calibration-max').textContent = `${max.toPrecision(3)} mm`;
  const bars = $('calibration-bars');
  bars.style.setProperty('--rms', `${(100 * rms) / top}%`);
  bars.replaceChildren(...res.map((r, k) => {
    const row = document.createElement('div');
    row.className = 'residual';
    row.title = `measurement ${k}: q ${shown.body.measurements[k].q.join(' ')}, branch ${answer.assembly_modes[k]}`;
    const name = document.createElement('span');
    name.textContent = String(k);
    const track = document.createElement('span');
    track.className = 'track';
    const bar = document.createElement('span');
    bar.className = 'bar';
    bar.dataset.testid = 'residual-bar';
    bar.dataset.mm = String(r);
    bar.style.width = `${(100 * r) / top}%`;
    track.appendChild(bar);
    const value = document.createElement('span');
    value.textContent = `${r.toPrecision(3)} mm`;
    row.append(name, track, value);
    return row;
  }));
}

/** The body as typed: an object, or a message saying why not. */
function bodyOf(text) {
  let body;
  try { body = JSON.parse(text); } catch (err) { return { error: `not JSON: ${err.message}` }; }
  if (!body || typeof body !== 'object' || Array.isArray(body)) {
    return { error: 'the body is one JSON object: {"measurements": [{"q": [3], "p": [3]}, ...], ...}' };
  }
  return { body };
}

function say(text) {
  $('calibration-error').hidden = !text;
  $('calibration-error').textContent = text;
}

async function calibrate() {
  const { body, error } = bodyOf($('calibration-body').value);
  $('calibration-result').hidden = true;
  shown = null;
  say(error || '');
  if (error) return;
  const mine = ++asked;
  $('calibration-run').disabled = true;
  $('calibration-note').textContent = 'calibrating…';
  try {
    const answer = await postJSON('/v1/calibrate', body);
    if (mine !== asked) return;
    shown = { body, answer };
    renderParameters(answer);
    renderResiduals(answer);
    $('calibration-result').hidden = false;
  } catch (err) {
    if (mine !== asked) return;
    say(err instanceof ApiError && err.detail.length
      ? err.detail.map((d) => `${(d.loc || []).join('.')}: ${d.msg}`).join('\n') : err.message);
  } finally {
    if (mine === asked) {
      $('calibration-run').disabled = false;
      $('calibration-note').textContent = '';
    }
  }
}

/** A file chosen: its text into the body box (to read, edit and send). */
async function load(file) {
  if (!file) return;
  $('calibration-body').value = await file.text();
  say('');
}

/** What the panel shows ({body, answer}), or null. */
export const calibrationData = () => shown;

/** The panel as the page first had it (start over). */
export function clear() {
  asked++;
  shown = null;
  $('calibration-file').value = '';
  $('calibration-body').value = '';
  $('calibration-result').hidden = true;
  $('calibration-run').disabled = false;
  $('calibration-note').textContent = '';
  say('');
}

/** `use(design)`: put a design into the form (app.js, as a preset). */
export function init({ use }) {
  useDesign = use;
  $('calibration-use').addEventListener('click', () => { if (shown) useDesign(shown.answer.design); });
  $('calibration-run').addEventListener('click', calibrate);
  $('calibration-file').addEventListener('change', (ev) => load(ev.target.files[0]));
}
