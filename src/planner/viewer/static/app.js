// The viewer's wiring: form -> POST /v1/plan (or /v1/cartesian for a straight tool path,
// /v1/sequence for a sequence of targets) ->
// scene, timeline, plots, the views (the sequence's legs and blends, the simulated robot),
// the workspace section and the region map; the calibration panel asks on its own.
import { ApiError, getBlob, getJSON, postJSON, setApiKey } from './api.js';
import * as form from './form.js';
import { along, fkCheck, limitWalls, posture, transitSamples } from './kin.js';
import { Scene } from './scene.js';
import * as plots from './plots.js';
import * as section from './section.js';
import * as exporter from './export.js';
import * as regions from './regions.js';
import * as scenes from './scenes.js';
import * as sequenceView from './sequence.js';
import * as simulationView from './simulation.js';
import * as calibration from './calibration.js';
import * as beltView from './belt.js';
import * as streamView from './stream.js';

const $ = (id) => document.getElementById(id);
let presetsAsked = getJSON('/v1/designs');  // asked first: the rest of the start waits on it
presetsAsked.catch(() => { /* handled where it is awaited (loadPresets) */ });
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
let exportKind = null;  // 'curl' | 'python' once the export box is shown: it follows the form
/** The views of an answer beside the scene and the plots: each module has show(request,
 * response, endpoint, {t, seek, scene}), clear() and setTime(t) (see sequence.js; `scene`:
 * the 3-D scene, for a view that also draws there, as belt.js), and resize() when it
 * draws to its width. A new view is one more entry here. */
const VIEWS = [sequenceView, simulationView, beltView];

// ------------------------------------------------------------------ status and messages
function setStatus(text, kind, message = '') {
  const s = $('status');
  s.textContent = text;
  s.className = kind;
  $('message').textContent = message;
  $('message').title = message;
}

const fmt = (x, d = 3) => (x === null || x === undefined ? '—' : Number.isFinite(x) ? x.toFixed(d) : '∞');
/** Points [x, y, z] as in-plane coordinates of the plane theta1 (u = y, w along e(theta1)). */
const inPlane = (pts, t1) => ({ u: pts.map((p) => p[1]), w: pts.map((p) => p[0] * Math.cos(t1) - p[2] * Math.sin(t1)) });
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
  const req = form.request.plan();
  scene.setObstacles(form.currentObstacles());
  if (shown) return;
  const x = req.start.q.every((v) => typeof v === 'number') && posture(d, req.start.q, req.start.assembly_mode);
  if (x) {
    scene.setPosture(x, req.start.q[0]);
    showReadouts(x);
  }
  const g = req.goal;
  const gx = g.q ? g.q.every((v) => typeof v === 'number') && posture(d, g.q, g.assembly_mode) : null;
  const goalP = g.p && g.p.every((v) => typeof v === 'number') ? g.p : gx ? gx.P : null;
  const path = form.endpoint() === 'cartesian' && x
    ? [x.P, ...form.waypoints().filter((w) => w.length === 3 && w.every((v) => typeof v === 'number'))] : null;
  scene.setPath([], [], [], [], path ? null : goalP, path);
}

function legendInit() { section.legend($('kappa-bands')); }

let analysisTimer = null;
/** The design (or, with `force`, the margins the analysis uses) changed: analyse it again. */
function designChanged(force = false) {
  const d = currentDesign();
  if (!d) return;
  const key = JSON.stringify(d) + (force ? JSON.stringify(form.request.plan().margins) : '');
  const match = presets.find((p) => JSON.stringify(p.design) === JSON.stringify(d));
  $('preset').value = match ? match.name : '';
  if (key === designKey) return;
  designKey = key;
  setState('section-box', 'loading');
  setState('regions-box', 'loading');
  regions.setTrace(null);  // an answer for another design
  scene.setDesign(d);
  clearTimeout(analysisTimer);
  analysisTimer = setTimeout(() => analyse(d), 300);
}

/** Mark a panel loading (its old content dimmed under a notice) or done. */
const setState = (id, state) => { $(id).dataset.state = state; };

/** The design's workspace section, region map and (when open) the service's isoconditioning
 * figure: each panel shows that it is loading from the moment the design changes. */
async function analyse(d) {
  const seq = ++analysisSeq;
  const margins = form.request.plan().margins;
  const kappaMax = typeof margins.kappa_max === 'number' && margins.kappa_max > 1 ? margins.kappa_max : DEFAULT_MARGINS.kappa_max;
  const serialMin = typeof margins.serial_min === 'number' && margins.serial_min > 0 && margins.serial_min < 1 ? margins.serial_min : DEFAULT_MARGINS.serial_min;
  setState('section-box', 'loading');
  $('section-note').dataset.state = 'loading';
  setState('regions-box', 'loading');
  const work = postJSON('/v1/workspace', {
    design: d, rel_se: 0.05, kappa_max: kappaMax, sections: { resolution: 64, joint: false },
  }).then((ws) => {
    if (seq !== analysisSeq) return;
    section.setSection(ws.cartesian_section, kappaMax);
    if (shown) section.setPath(shown.sectionPath);
    setState('section-box', 'loaded');
    $('section-note').dataset.state = 'loaded';
    $('section-note').textContent = `Volume ${fmt(ws.volume)} m³ (closed form), ${fmt(ws.sampled_volume.value)} m³ within the joint limits; `
      + `well-conditioned (κ ≤ ${kappaMax}) ${fmt(100 * ws.well_conditioned_fraction.value, 0)} %; GCI ${fmt(ws.gci.value)}. `
      + 'Colour: the smallest κ(A) over the working modes reaching the cell, in the bands of the paper\'s isoconditioning figure; '
      + 'faded: not reached in the current working mode. Line: the path of P in the linkage plane (u, w), which does not depend on θ1; numbered dots: the transits'
      + (form.endpoint() === 'cartesian' ? '. Click to add a waypoint (in the start\'s plane θ1); dashed brown: where θ2 or θ3 is at its limit in the start\'s working mode, which a straight path cannot cross.' : '.');
  });
  const rmap = postJSON('/v1/design/regions', {
    design: d, margins: { kappa_max: kappaMax, serial_min: serialMin }, resolution: 128, cell_regions: true,
  }).then((answer) => {
    if (seq !== analysisSeq) return;
    regions.setMap(answer, d);  // with the trace of the plan shown for this design, if any
    setState('regions-box', 'loaded');
  });
  const jobs = [[work, 'section-box', (m) => { $('section-note').textContent = `Workspace section unavailable: ${m}`; }],
    [rmap, 'regions-box', (m) => { $('regions-note').textContent = `Region map unavailable: ${m}`; }]];
  if ($('iso-details').open) jobs.push([figure(d, seq), 'iso-box', (m) => { $('iso-figure').alt = `isoconditioning figure unavailable: ${m}`; }]);
  else setState('iso-box', 'stale');
  for (const [job, id, say] of jobs) {
    job.catch((err) => {
      if (seq !== analysisSeq) return;
      setState(id, 'failed');
      if (id === 'section-box') $('section-note').dataset.state = 'failed';
      say(err.message);
      if (err instanceof ApiError && err.status === 422) form.showErrors(err.detail);
    });
  }
}

/** The service's figure 15 for design d, at its own size (shown only when asked for). */
function figure(d, seq) {
  const img = $('iso-figure');
  setState('iso-box', 'loading');
  const query = new URLSearchParams({ L0: d.L0, L1: d.L1, L2: d.L2 });
  return getBlob(`/v1/figures/isoconditioning.png?${query}`).then((blob) => {
    if (seq !== analysisSeq) return;
    if (img.src.startsWith('blob:')) URL.revokeObjectURL(img.src);
    img.src = URL.createObjectURL(blob);
    $('iso-open').href = img.src;
    $('iso-open').hidden = false;
    img.alt = `isoconditioning figure of L0 = ${d.L0}, L1 = ${d.L1}, L2 = ${d.L2} (the service's figure)`;
    setState('iso-box', 'loaded');
  });
}

$('iso-details').addEventListener('toggle', () => {
  const d = currentDesign();
  if ($('iso-details').open && d && $('iso-box').dataset.state !== 'loaded' && $('iso-box').dataset.state !== 'loading') {
    figure(d, analysisSeq).catch((err) => { setState('iso-box', 'failed'); $('iso-figure').alt = `isoconditioning figure unavailable: ${err.message}`; });
  }
});

async function loadPresets() {
  const select = $('preset');
  try {
    const asked = presetsAsked || getJSON('/v1/designs');
    presetsAsked = null;
    presets = (await asked).presets;
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
  form.loadChecks(getJSON).catch(() => { /* no schema: the service still says it on Plan */ });
  scenes.refresh().catch((err) => { $('scene-info').textContent = `scenes unavailable: ${err.message}`; });
}

/** An example: the service's default design, then its start, goal and obstacles. */
function exampleChosen(ex) {
  dropPlan();
  form.setExample(ex, presets[0]?.design);
  designChanged();
  preview();
  followExport();
}

/** Another design into the form (a preset's, a calibration's): the plan on screen goes. */
function useDesign(d) {
  dropPlan();
  form.setDesign(d);
  designChanged();
  preview();
  followExport();
}

$('preset').addEventListener('change', () => {
  const p = presets.find((x) => x.name === $('preset').value);
  if (p) useDesign(p.design);
});

// ------------------------------------------------------------------ plan
async function plan(ev) {
  ev?.preventDefault();
  form.clearErrors();
  stop();
  const request = form.request();
  const endpoint = form.endpoint();
  setStatus('planning…', 'busy');
  $('fraction-wrap').hidden = true;
  $('torque-ratio-wrap').hidden = true;
  $('cycle-wrap').hidden = true;
  $('plan-button').disabled = true;
  try {
    const response = await postJSON(`/v1/${endpoint}`, request);
    const kind = response.status === 'solved' ? 'solved' : 'failed';
    setStatus(response.status, kind, response.message);
    showFraction(endpoint, response);
    showTorqueRatio(response);
    showCycle(endpoint, response);
    showPlan(request, response, endpoint);
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

/** The largest |tau_j| / limits.torque[j] of the answer, when it was timed under torque limits. */
function showTorqueRatio(response) {
  const r = response.diagnostics?.max_torque_ratio;
  const has = typeof r === 'number';
  $('torque-ratio-wrap').hidden = !has;
  $('torque-ratio').textContent = has ? r.toFixed(4) : '—';
  $('torque-ratio').dataset.value = has ? String(r) : '';
}

/** A sequence's answer: its cycle time. */
function showCycle(endpoint, response) {
  const c = response.cycle_time;
  $('cycle-wrap').hidden = endpoint !== 'sequence';
  $('cycle-time').textContent = typeof c === 'number' ? c.toFixed(3) : '—';
  $('cycle-time').dataset.value = typeof c === 'number' ? String(c) : '';
}

/** A straight path's answer: the share achieved and, when it stopped short, why. */
function showFraction(endpoint, response) {
  $('fraction-wrap').hidden = endpoint !== 'cartesian';
  if (endpoint !== 'cartesian') return;
  $('fraction').textContent = `${(100 * response.fraction).toFixed(1)} %`;
  $('fraction').dataset.value = String(response.fraction);
  const stop = response.stop;
  $('stop-rule').textContent = stop ? `stopped by ${stop.rule}${stop.value === null || stop.value === undefined ? '' : ` (${fmt(stop.value, 4)})`}` : '';
}

/** The polyline of a straight path beyond its stop: the stopping point, then the waypoints
 * not reached (their share of the length from the start's P is above the fraction). */
function restOf(request, response, startP) {
  const stop = response.stop;
  if (!stop || response.fraction >= 1) return null;
  const pts = [startP, ...request.waypoints];
  const seg = pts.slice(1).map((p, i) => Math.hypot(p[0] - pts[i][0], p[1] - pts[i][1], p[2] - pts[i][2]));
  const total = seg.reduce((a, b) => a + b, 0);
  let acc = 0, k = 0;
  while (k < seg.length && (acc + seg[k]) / total <= stop.fraction + 1e-12) acc += seg[k++];
  return [stop.p, ...request.waypoints.slice(k)];
}

/** A sequence's answer as one path: its legs' segments and transits joined in order (each
 * transit with its leg's time span and the answer's own `transit_times` entry, which places
 * its sample when present), a run of one working
 * mode across a leg's end being one segment. */
function sequencePath(response) {
  const legs = response.legs.filter((l) => l.path);
  const first = legs[0]?.path.segments[0];
  const segments = [{ working_mode: first?.working_mode || legs[0]?.working_mode || '' }];
  const transits = [];
  legs.forEach((leg) => {
    const segs = leg.path.segments;
    leg.path.transits.forEach((tr, j) => {
      const time = leg.transit_times?.[j];
      transits.push({ ...tr, leg: response.legs.indexOf(leg), span: [leg.start_time, leg.end_time], time });
      segments.push({ working_mode: segs[j + 1]?.working_mode || '' });
    });
  });
  return { segments, transits };
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
  for (const v of VIEWS) v.clear();
  plots.clear();
  section.setPath(null);
  section.setRest(null);
  regions.setTrace(null);
}

/** The form changed so that the plan on screen no longer answers it (another design,
 * preset, example or goal kind): the plan goes, and with it what the header says of it (its
 * status, message, path achieved, torque ratio, cycle time). */
function dropPlan() {
  clearPlan();
  for (const id of ['fraction-wrap', 'torque-ratio-wrap', 'cycle-wrap']) $(id).hidden = true;
  if ($('status').textContent !== 'not planned') setStatus('not planned', '');
}

function showPlan(request, response, endpoint = 'plan') {
  clearPlan();
  $('download-json').disabled = false;
  $('download-csv').disabled = !response.trajectory;
  lastPlan = { endpoint, request, response };
  const goalQ = request.goal?.q;
  const trace = (qs) => ({
    q2: qs.map((q) => q[1]), q3: qs.map((q) => q[2]), assembly: request.start.assembly_mode,
    start: request.start.q, goal: goalQ || qs.at(-1) || null, goalAssembly: request.goal?.assembly_mode,
    proof: Boolean(response.diagnostics?.proven_infeasible),
  });
  const seekStopped = (t) => { stop(); seek(t); };
  for (const v of VIEWS) v.show(request, response, endpoint, { t: response.trajectory?.t || [], seek: seekStopped, scene });
  const path = response.path || (response.legs && response.trajectory ? sequencePath(response) : null);
  if (!path) {
    preview();
    regions.setTrace({ ...trace([]), goal: goalQ || null });
    return;
  }
  const d = request.design;
  const asm = request.start.assembly_mode;
  const traj = samples(response);
  const postures = along(d, traj.q, asm);
  const fkError = fkCheck(postures, traj.p);
  $('scene').dataset.fkError = fkError === null ? '' : String(fkError);
  const segs = path.segments;
  const trs = path.transits;
  const ks = transitSamples(traj.q, trs, traj.t);
  const segmentOf = traj.t.map((_, i) => ks.filter((k) => k < i).length);
  const modes = segs.map((s) => s.working_mode);
  const transits = trs.map((tr, i) => ({ ...tr, sample: ks[i], t: traj.t[ks[i]], p: postures[ks[i]]?.P, from: modes[i], to: modes[i + 1] }));
  const margins = { ...DEFAULT_MARGINS, ...request.margins };
  const rest = endpoint === 'cartesian' ? restOf(request, response, postures[0].P) : null;
  shown = {
    request, response, traj, postures, segmentOf, modes, transits,
    sectionPath: { u: postures.map((x) => x?.u ?? NaN), w: postures.map((x) => x?.w ?? NaN), segmentOf, modes, transits },
    regionTrace: trace(traj.q),
  };
  scene.setDesign(d);
  const { inertia, ...geometry } = d;  // the analysis does not depend on the inertia
  designKey = JSON.stringify(geometry);
  scene.setObstacles(request.obstacles);
  const goalP = request.goal?.p || request.waypoints?.at(-1) || postures.at(-1).P;
  scene.setPath(postures.map((x) => x.P), segmentOf, modes, transits, goalP, rest);
  $('scene').dataset.rest = rest ? String(rest.length) : '0';
  section.setPath(shown.sectionPath);
  section.setRest(rest && inPlane(rest, traj.q[0][0]));
  regions.setTrace(shown.regionTrace);
  plots.show({
    t: traj.t, q: traj.q, qd: traj.qd, qdd: traj.qdd, tau: traj.tau, torqueLimits: request.limits?.torque,
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
    m.title = `${tr.kind}: sign ${tr.flipped} flips, ${tr.from} → ${tr.to}${tr.leg === undefined ? '' : ` (leg ${tr.leg})`}`;
    m.dataset.t = String(tr.t);
    if (tr.leg !== undefined) m.dataset.leg = String(tr.leg);
    return m;
  }));
  $('transits').replaceChildren(...transits.map((tr) => {
    const li = document.createElement('li');
    li.textContent = `t = ${tr.t.toFixed(2)} s: ${tr.leg === undefined ? '' : `leg ${tr.leg}, `}transit ${tr.kind} (sign ${tr.flipped} flips), working mode ${tr.from} → ${tr.to}`;
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
  for (const v of VIEWS) v.setTime(traj.t[i]);
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
const exportOf = (kind) => exporter[kind](location.origin, form.request(), withKey(), form.endpoint());
$('copy-curl').addEventListener('click', () => { exportKind = 'curl'; exportText(exportOf('curl')); });
$('copy-python').addEventListener('click', () => { exportKind = 'python'; exportText(exportOf('python')); });
/** Keep the export box on the form's current request (not copied again: it is shown). */
let exportTimer = null;
function followExport() {
  if (!exportKind || $('export-text').hidden) return;
  // a request with a large cloud is megabytes of text: written once typing pauses
  const points = form.currentObstacles().reduce((n, o) => n + (o.type === 'points' ? o.points.length : 0), 0);
  clearTimeout(exportTimer);
  if (points < 20_000) $('export-text').value = exportOf(exportKind);
  else exportTimer = setTimeout(() => { $('export-text').value = exportOf(exportKind); }, 300);
}
$('download-json').addEventListener('click', () => {
  if (lastPlan) exporter.download('plan.json', JSON.stringify({ request: lastPlan.request, response: lastPlan.response }, null, 1), 'application/json');
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
let resizeTimer = null;
window.addEventListener('resize', () => {
  clearTimeout(resizeTimer);
  resizeTimer = setTimeout(() => {
    plots.resize(); section.resize(); regions.draw();
    for (const v of VIEWS) v.resize?.();
  }, 100);
});
$('clear-waypoints').addEventListener('click', () => { form.setWaypoints([]); form.recheck(); followExport(); });

/** In straight-path mode, the section draws where theta2 and theta3 stand at their literal
 * limits in the start's working mode: a straight path (which keeps it) stops there. */
let wallsKey = '';
function showWalls() {
  const d = currentDesign();
  const start = form.request.plan().start;
  const x = form.endpoint() === 'cartesian' && d && start.q.every((v) => typeof v === 'number')
    ? posture(d, start.q, start.assembly_mode) : null;
  const key = x ? JSON.stringify([d, x.workingMode, start.assembly_mode]) : '';
  if (key === wallsKey) return;
  wallsKey = key;
  section.setWalls(x ? limitWalls(d, x.workingMode, start.assembly_mode) : null);
}

/** In straight-path mode, a click on the workspace section adds a waypoint there (in the
 * linkage plane of the start's theta1). */
function pickMode() {
  const on = form.endpoint() === 'cartesian';
  showWalls();
  section.setPick(on ? (u, w) => {
    const t1 = Number(form.request.plan().start.q[0]) || 0;
    form.addWaypoint([w * Math.cos(t1), u, -w * Math.sin(t1)]);
  } : null);
}

form.init({
  changed: (name = '') => {
    if (name.startsWith('design.') || name === 'goal-kind') dropPlan();  // it answered another request
    if (name.startsWith('design.') || name.startsWith('margins.')) designChanged(name.startsWith('margins.'));
    if (name === 'goal-kind') pickMode();
    showWalls();
    preview();
    followExport();
  },
  exampleChosen,
});
scenes.init({ drawn: (list) => scene.setSceneObstacles(list) });
calibration.init({ use: useDesign });
streamView.init({
  scene,
  request: () => ({ endpoint: form.endpoint(), request: form.request() }),
  before: stop,  // the playback gives the scene's robot to the stream
});
pickMode();
legendInit();
designChanged();
preview();
loadPresets();

/** Start over: every field as the page first had it, the first example, the default design,
 * no plan on the screen. */
function startOver() {
  clearPlan();
  lastPlan = null;
  $('download-json').disabled = true;
  $('download-csv').disabled = true;
  const key = $('api-key').value;
  $('request-form').reset();
  $('api-key').value = key;
  form.clearErrors();
  exportKind = null;
  $('export-text').hidden = true;
  $('example').value = '0';
  scenes.chosen();
  calibration.clear();
  streamView.clear();
  exampleChosen(form.EXAMPLES[0]);
  pickMode();
}
$('start-over').addEventListener('click', startOver);
