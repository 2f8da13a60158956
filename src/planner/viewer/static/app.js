// The viewer's wiring: form -> POST /v1/plan -> scene, timeline, plots and section.
import { ApiError, getBlob, getJSON, postJSON, setApiKey } from './api.js';
import * as form from './form.js';
import { along, fkCheck, posture, transitSamples } from './kin.js';
import { Scene } from './scene.js';
import * as plots from './plots.js';
import * as section from './section.js';
import * as exporter from './export.js';

const $ = (id) => document.getElementById(id);
const scene = new Scene($('scene'));
const timeline = $('timeline');
const DEFAULT_MARGINS = { kappa_max: 10, serial_min: 0.05 };

let presets = [];
let lastPlan = null;  // the last answer (and its request), for the downloads
let shown = null;     // the plan on screen: {request, response, t, q, postures, segmentOf, ...}
let playing = false;
let tNow = 0;
let lastFrame = null;
let designKey = '';
let analysisSeq = 0;

// ------------------------------------------------------------------ status and messages
function setStatus(text, kind, message = '') {
  const s = $('status');
  s.textContent = text;
  s.className = kind;
  $('message').textContent = message;
  $('message').title = message;
}

const fmt = (x, d = 3) => (x === null || x === undefined ? '—' : Number.isFinite(x) ? x.toFixed(d) : '∞');
const allNumbers = (d) => [d.L0, d.L1, d.L2, d.link_radius, ...(d.joint_min || []), ...(d.joint_max || [])]
  .every((x) => typeof x === 'number');

// ------------------------------------------------------------------ design, preview, analysis
function currentDesign() {
  const d = form.design();
  return allNumbers(d) && d.L1 > 0 && d.L2 > 0 ? d : null;
}

function preview() {
  const d = currentDesign();
  if (!d) return;
  const req = form.request();
  scene.setObstacles(req.obstacles);
  if (shown) return;
  const x = req.start.q.every((v) => typeof v === 'number') && posture(d, req.start.q, req.start.assembly_mode);
  if (x) {
    scene.setPosture(x, req.start.q[0]);
    showReadouts(x);
  }
  const g = req.goal;
  const gx = g.q ? g.q.every((v) => typeof v === 'number') && posture(d, g.q, g.assembly_mode) : null;
  const goalP = g.p && g.p.every((v) => typeof v === 'number') ? g.p : gx ? gx.P : null;
  scene.setPath([], [], [], [], goalP);
}

let analysisTimer = null;
function designChanged() {
  const d = currentDesign();
  if (!d) return;
  const key = JSON.stringify(d);
  const match = presets.find((p) => JSON.stringify(p.design) === key);
  $('preset').value = match ? match.name : '';
  if (key === designKey) return;
  designKey = key;
  scene.setDesign(d);
  clearTimeout(analysisTimer);
  analysisTimer = setTimeout(() => analyse(d), 300);
}

/** The design's workspace section and isoconditioning figure (analysis endpoints). */
async function analyse(d) {
  const seq = ++analysisSeq;
  const margins = form.request().margins;
  const kappaMax = typeof margins.kappa_max === 'number' && margins.kappa_max > 1 ? margins.kappa_max : DEFAULT_MARGINS.kappa_max;
  $('section-note').dataset.state = 'loading';
  const img = $('iso-figure');
  img.dataset.state = 'loading';
  const query = new URLSearchParams({ L0: d.L0, L1: d.L1, L2: d.L2 });
  const work = postJSON('/v1/workspace', {
    design: d, rel_se: 0.05, kappa_max: kappaMax, sections: { resolution: 64, joint: false },
  }).then((ws) => {
    if (seq !== analysisSeq) return;
    section.setSection(ws.cartesian_section, kappaMax);
    if (shown) section.setPath(shown.sectionPath);
    $('section-note').dataset.state = 'loaded';
    $('section-note').textContent = `Volume ${fmt(ws.volume)} m³ (closed form), ${fmt(ws.sampled_volume.value)} m³ within the joint limits; `
      + `well-conditioned (κ ≤ ${kappaMax}) ${fmt(100 * ws.well_conditioned_fraction.value, 0)} %; GCI ${fmt(ws.gci.value)}. `
      + 'Colour: the smallest κ(A) over the working modes reaching the cell (teal: isotropic, yellow: κ max, orange: above); '
      + 'faded: not reached in the current working mode. Line: the path of P in the linkage plane (u, w), which does not depend on θ1; numbered dots: the transits.';
  });
  const fig = getBlob(`/v1/figures/isoconditioning.png?${query}`).then((blob) => {
    if (seq !== analysisSeq) return;
    if (img.src.startsWith('blob:')) URL.revokeObjectURL(img.src);
    img.src = URL.createObjectURL(blob);
    img.alt = `isoconditioning map of L0 = ${d.L0}, L1 = ${d.L1}, L2 = ${d.L2} (the service's figure)`;
    img.dataset.state = 'loaded';
  });
  for (const [job, el] of [[work, $('section-note')], [fig, img]]) {
    job.catch((err) => {
      if (seq !== analysisSeq) return;
      el.dataset.state = 'failed';
      if (el === img) img.alt = `isoconditioning map unavailable: ${err.message}`;
      else el.textContent = `Workspace section unavailable: ${err.message}`;
      if (err instanceof ApiError && err.status === 422) form.showErrors(err.detail);
    });
  }
}

async function loadPresets() {
  const select = $('preset');
  try {
    presets = (await getJSON('/v1/designs')).presets;
  } catch (err) {
    const hint = err instanceof ApiError && err.status === 401
      ? 'The service needs an API key: type it into the API key field (Service).' : `presets unavailable: ${err.message}`;
    setStatus('not planned', '', hint);
    return;
  }
  for (const p of presets) {
    const o = document.createElement('option');
    o.value = p.name;
    o.textContent = p.name;
    o.title = p.description;
    select.appendChild(o);
  }
  form.setDesign(presets[0].design);  // "default" comes first
  designChanged();  // analysed again only if the service's default differs from the page's
  preview();
}

$('preset').addEventListener('change', () => {
  const p = presets.find((x) => x.name === $('preset').value);
  if (!p) return;
  if (shown) clearPlan();
  form.setDesign(p.design);
  designChanged();
  preview();
});

// ------------------------------------------------------------------ plan
async function plan(ev) {
  ev?.preventDefault();
  form.clearErrors();
  stop();
  const request = form.request();
  setStatus('planning…', 'busy');
  $('plan-button').disabled = true;
  try {
    const response = await postJSON('/v1/plan', request);
    const kind = response.status === 'solved' ? 'solved' : 'failed';
    setStatus(response.status, kind, response.message);
    showPlan(request, response);
  } catch (err) {
    if (err instanceof ApiError && err.status === 422) {
      setStatus('invalid request', 'failed', 'The service refused the request: see the messages next to the fields.');
      form.showErrors(err.detail);
    } else {
      setStatus(err instanceof ApiError ? `error ${err.status}` : 'error', 'failed', err.message);
    }
  } finally {
    $('plan-button').disabled = false;
  }
}

/** The trajectory, or the untimed path (timing "none") at one waypoint per second. */
function samples(response) {
  const tr = response.trajectory;
  if (tr) return tr;
  const q = response.path.waypoints;
  const zeros = q.map(() => [0, 0, 0]);
  return { t: q.map((_, i) => i), q, qd: zeros, qdd: zeros, duration: q.length - 1, p: null };
}

/** Take the plan off the screen (none came back, or the design changed). */
function clearPlan() {
  stop();
  shown = null;
  timeline.disabled = true;
  timeline.max = '0';
  timeline.value = '0';
  $('play').disabled = true;
  $('time').textContent = '0.00';
  $('duration').textContent = '0.00';
  renderTransits([], []);
  plots.clear();
  section.setPath(null);
}

function showPlan(request, response) {
  clearPlan();
  $('download-json').disabled = false;
  $('download-csv').disabled = !response.trajectory;
  lastPlan = { request, response };
  if (!response.path) {
    preview();
    return;
  }
  const d = request.design;
  const asm = request.start.assembly_mode;
  const traj = samples(response);
  const postures = along(d, traj.q, asm);
  const fkError = fkCheck(postures, traj.p);
  $('scene').dataset.fkError = fkError === null ? '' : String(fkError);
  const segs = response.path.segments;
  const trs = response.path.transits;
  const ks = transitSamples(traj.q, trs);
  const segmentOf = traj.t.map((_, i) => ks.filter((k) => k < i).length);
  const modes = segs.map((s) => s.working_mode);
  const transits = trs.map((tr, i) => ({ ...tr, sample: ks[i], t: traj.t[ks[i]], p: postures[ks[i]]?.P, from: modes[i], to: modes[i + 1] }));
  const margins = { ...DEFAULT_MARGINS, ...request.margins };
  shown = {
    request, response, traj, postures, segmentOf, modes, transits,
    sectionPath: { u: postures.map((x) => x?.u ?? NaN), w: postures.map((x) => x?.w ?? NaN), segmentOf, modes, transits },
  };
  scene.setDesign(d);
  designKey = JSON.stringify(d);
  scene.setObstacles(request.obstacles);
  scene.setPath(postures.map((x) => x.P), segmentOf, modes, transits, request.goal.p || postures.at(-1).P);
  section.setPath(shown.sectionPath);
  plots.show({
    t: traj.t, q: traj.q, qd: traj.qd, qdd: traj.qdd,
    kappa: postures.map((x) => x.kappa), serial: postures.map((x) => x.serial),
    margins, transitTimes: transits, onSeek: seek,
  });
  timeline.max = String(traj.t.length - 1);
  timeline.disabled = false;
  $('play').disabled = false;
  $('duration').textContent = traj.duration.toFixed(2);
  renderTransits(transits, traj.t);
  seek(0);
  play();
}

function renderTransits(transits, t) {
  const duration = t.length ? t.at(-1) : 1;
  $('timeline-marks').replaceChildren(...transits.map((tr) => {
    const m = document.createElement('div');
    m.className = 'transit-mark';
    m.dataset.testid = 'transit-mark';
    m.style.left = `${(100 * tr.t) / (duration || 1)}%`;
    m.textContent = tr.kind;
    m.title = `${tr.kind}: sign ${tr.flipped} flips, ${tr.from} → ${tr.to}`;
    return m;
  }));
  $('transits').replaceChildren(...transits.map((tr) => {
    const li = document.createElement('li');
    li.textContent = `t = ${tr.t.toFixed(2)} s: transit ${tr.kind} (sign ${tr.flipped} flips), working mode ${tr.from} → ${tr.to}`;
    li.addEventListener('click', () => seek(tr.t));
    return li;
  }));
}

// ------------------------------------------------------------------ animation
function showReadouts(x, seg) {
  const label = x.workingMode.includes('0') && seg ? seg : x.workingMode;
  $('mode').textContent = label;
  $('assembly').textContent = x.assemblyMode;
  $('kappa-now').textContent = fmt(x.kappa, 2);
  $('serial-now').textContent = fmt(x.serial, 3);
  $('p-now').textContent = x.P.map((v) => v.toFixed(3)).join(', ');
}

function showSample(i) {
  const { traj, postures, segmentOf, modes } = shown;
  const x = postures[i];
  timeline.value = String(i);
  $('time').textContent = traj.t[i].toFixed(2);
  if (!x) return;
  scene.setPosture(x, traj.q[i][0]);
  showReadouts(x, modes[segmentOf[i]]);
  plots.setTime(traj.t[i]);
  section.setIndex(i);
}

function sampleAt(t) {
  const ts = shown.traj.t;
  let lo = 0, hi = ts.length - 1;
  while (lo < hi) {
    const mid = (lo + hi + 1) >> 1;
    if (ts[mid] <= t) lo = mid; else hi = mid - 1;
  }
  return lo;
}

function seek(t) {
  if (!shown) return;
  tNow = Math.max(0, Math.min(t, shown.traj.t.at(-1)));
  showSample(sampleAt(tNow));
}

function frame(ts) {
  if (!playing || !shown) return;
  const dt = lastFrame === null ? 0 : (ts - lastFrame) / 1000;
  lastFrame = ts;
  tNow += dt * Number($('speed').value);
  const end = shown.traj.t.at(-1);
  if (tNow >= end) { tNow = end; stop(); }
  showSample(sampleAt(tNow));
  if (playing) requestAnimationFrame(frame);
}

function play() {
  if (!shown) return;
  if (tNow >= shown.traj.t.at(-1)) tNow = 0;
  playing = true;
  lastFrame = null;
  $('play').textContent = '❚❚ pause';
  requestAnimationFrame(frame);
}

function stop() {
  playing = false;
  $('play').textContent = '▶ play';
}

$('play').addEventListener('click', () => (playing ? stop() : play()));
timeline.addEventListener('input', () => {
  stop();
  if (shown) seek(shown.traj.t[Number(timeline.value)]);
});

// ------------------------------------------------------------------ export
async function exportText(text) {
  const area = $('export-text');
  area.hidden = false;
  area.value = text;
  area.select();
  try { await navigator.clipboard.writeText(text); } catch { /* selected for copying by hand */ }
}

const withKey = () => $('api-key').value.trim() !== '';
$('copy-curl').addEventListener('click', () => exportText(exporter.curl(location.origin, form.request(), withKey())));
$('copy-python').addEventListener('click', () => exportText(exporter.python(location.origin, form.request(), withKey())));
$('download-json').addEventListener('click', () => {
  if (lastPlan) exporter.download('plan.json', JSON.stringify(lastPlan, null, 1), 'application/json');
});
$('download-csv').addEventListener('click', () => {
  if (lastPlan?.response.trajectory) exporter.download('trajectory.csv', exporter.csv(lastPlan.response.trajectory), 'text/csv');
});

// ------------------------------------------------------------------ start
$('api-key').addEventListener('change', () => {
  setApiKey($('api-key').value);
  if (!presets.length) loadPresets();
  designKey = '';
  designChanged();
});
$('request-form').addEventListener('submit', plan);
window.addEventListener('resize', () => plots.resize());

form.init({
  changed: (name = '') => {
    if (name.startsWith('design.') && shown) clearPlan();  // the plan was for another design
    if (name.startsWith('design.')) designChanged();
    preview();
  },
});
designChanged();
preview();
loadPresets();
