// Named scenes on the page: the picker lists GET /v1/scenes; choosing one puts its name in
// the request's `scene` field and draws its obstacles (GET /v1/scenes/{name}); "save as
// scene" PUTs the form's obstacles under the name typed (checked as typed by the service's
// own rule, the pattern of the PUT's path); "delete" forgets the chosen one. The service's
// messages are shown next to the field they concern, in its words.
import { ApiError, deleteJSON, getJSON, putJSON } from './api.js';
import * as checks from './checks.js';
import * as form from './form.js';

const $ = (id) => document.getElementById(id);
const picker = () => document.querySelector('select[name=scene]');
const path = (name) => `/v1/scenes/${encodeURIComponent(name)}`;
let onScene = () => {};
const many = (n, word) => `${n.toLocaleString('en')} ${word}${n === 1 ? '' : 's'}`;
let asked = 0;

/** The service's list of scenes into the picker (the chosen one kept if it is still there). */
export async function refresh() {
  const { scenes } = await getJSON('/v1/scenes');
  const select = picker();
  const keep = select.value;
  select.replaceChildren(new Option('(none)', ''), ...scenes.map((s) => {
    const o = new Option(`${s.name} (${many(s.obstacles, 'obstacle')}${s.points ? `, ${many(s.points, 'point')}` : ''})`, s.name);
    o.title = `version ${s.version}, stored ${new Date(1000 * s.updated_at).toISOString()}`;
    return o;
  }));
  select.value = scenes.some((s) => s.name === keep) ? keep : '';
  select.dataset.count = String(scenes.length);
  return scenes;
}

/** The picker changed: draw the chosen scene's obstacles (none for "(none)"). */
export async function chosen() {
  const name = picker().value;
  const seq = ++asked;
  form.clearAt('scene');
  $('scene-delete').disabled = !name;
  $('scene-info').textContent = name ? 'loading the scene…' : '';
  picker().dataset.state = name ? 'loading' : 'none';
  if (!name) { onScene(null); return; }
  try {
    const s = await getJSON(path(name));
    if (seq !== asked) return;
    onScene(s.scene.obstacles || []);
    picker().dataset.state = 'loaded';
    $('scene-info').textContent = `${s.name}, version ${s.version}: ${many(s.obstacles, 'obstacle')}`
      + `${s.points ? ` (${many(s.points, 'cloud point')})` : ''}, drawn fainter; plans name it as "scene"`
      + `${s.scene.design ? '; it has a design of its own, used only by requests that send none (this page sends the form\'s)' : ''}.`;
  } catch (err) {
    if (seq !== asked) return;
    onScene(null);
    picker().dataset.state = 'failed';
    $('scene-info').textContent = '';
    form.sayAt('scene', err.message);
  }
}

/** Check the name as typed, by the service's rule. */
export function nameTyped() {
  form.clearAt('scene-name');
  const msg = checks.sceneName($('scene-name').value);
  const box = $('scene-name');
  if (msg && box.value) { form.sayAt('scene-name', msg); box.setAttribute('aria-invalid', 'true'); } else box.removeAttribute('aria-invalid');
  return msg;
}

/** PUT the form's obstacles as the scene named; then it is the chosen scene and the form's
 * own obstacles are emptied (they are in the scene now: a plan sends the name, not them). */
export async function save() {
  const name = $('scene-name').value;
  form.clearAt('scene-name');
  if (!name) { form.sayAt('scene-name', 'a name is needed'); return null; }
  const obstacles = form.request.plan().obstacles;
  $('scene-save').disabled = true;
  try {
    const info = await putJSON(path(name), { obstacles });
    await refresh();
    picker().value = info.name;
    form.setObstacles([]);
    await chosen();
    $('scene-info').textContent = `saved: ${$('scene-info').textContent}`;
    return info;
  } catch (err) {
    say(err);
    return null;
  } finally {
    $('scene-save').disabled = false;
  }
}

/** DELETE the chosen scene; the picker back to "(none)". */
export async function remove() {
  const name = picker().value;
  if (!name) return;
  try {
    await deleteJSON(path(name));
  } catch (err) {
    form.sayAt('scene', err.message);
  }
  await refresh();
  picker().value = '';
  await chosen();
}

/** A refused PUT: the path's name next to the name field, the body's fields next to theirs
 * (an obstacle's), anything else (413: too large) next to the name field. */
function say(err) {
  if (!(err instanceof ApiError) || !err.detail.length) { form.sayAt('scene-name', err.message); return; }
  const own = err.detail.filter((d) => d.loc?.[0] === 'path' || !d.loc?.length || d.loc.length === 1);
  const body = err.detail.filter((d) => !own.includes(d));
  if (body.length) form.showErrors(body);
  for (const d of own) form.sayAt('scene-name', d.msg);
}

/** Wire the fieldset; `drawn(obstacles | null)` draws the chosen scene's obstacles. */
export function init({ drawn }) {
  onScene = drawn;
  picker().addEventListener('change', chosen);
  $('scene-name').addEventListener('input', nameTyped);
  $('scene-save').addEventListener('click', save);
  $('scene-delete').addEventListener('click', remove);
}
