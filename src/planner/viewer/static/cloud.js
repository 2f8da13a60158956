// Point clouds read from a file a user has (a depth camera's export, a sampled CAD model):
// a JSON obstacle ({"type": "points", ...} or any obstacle), a list of them, a scene body
// ({"obstacles": [...]}) or a GET /v1/scenes/{name} answer; or rows "x y z" (.xyz, .csv,
// .txt: separated by spaces, commas or semicolons; a header line, '#' comments and columns
// after the third, e.g. colours or normals, are skipped). The service stays the validator of
// the obstacles; this only reads them and names the line that cannot be read.

/** An error of a file's content, with the line (1-based) when there is one. */
export class CloudError extends Error {}

/** Obstacles from a file's text: JSON when it looks like JSON, else x y z rows made into one
 * cloud of `radius`. */
export function parse(text, name, radius) {
  const head = text.trimStart()[0];
  if (head === '{' || head === '[' || /\.json$/i.test(name)) return parseJSON(text);
  return [parseRows(text, radius)];
}

function parseJSON(text) {
  let value;
  try {
    value = JSON.parse(text);
  } catch (err) {
    throw new CloudError(`not valid JSON: ${err.message}`);
  }
  const list = Array.isArray(value) ? value
    : value?.scene?.obstacles || value?.obstacles || (value && typeof value === 'object' ? [value] : null);
  if (!Array.isArray(list) || !list.length) throw new CloudError('no obstacle in the file: an obstacle, a list of them or {"obstacles": [...]}');
  list.forEach((o, i) => {
    if (!o || typeof o !== 'object' || typeof o.type !== 'string') {
      throw new CloudError(`obstacle ${i}: an object with a "type" ("points", "sphere", "box" or "capsule")`);
    }
  });
  return list;
}

/** One cloud {type: "points", points, radius} from rows of x y z. */
export function parseRows(text, radius) {
  const points = [];
  const lines = text.split(/\r?\n/);
  let seenData = false;
  for (let i = 0; i < lines.length; i++) {
    const line = lines[i].trim();
    if (!line || line.startsWith('#') || line.startsWith('//')) continue;
    const words = line.split(/[\s,;]+/);
    const xyz = words.slice(0, 3).map(Number);
    if (words.length < 3 || xyz.some((x) => Number.isNaN(x))) {
      if (!seenData && xyz.some((x) => Number.isNaN(x))) { seenData = true; continue; }  // a header
      throw new CloudError(`line ${i + 1}: three numbers x y z (m), got "${line.slice(0, 40)}"`);
    }
    if (!xyz.every(Number.isFinite)) throw new CloudError(`line ${i + 1}: a point must be finite, got "${line.slice(0, 40)}"`);
    seenData = true;
    points.push(xyz);
  }
  if (!points.length) throw new CloudError('no point in the file: one "x y z" per line (m)');
  return { type: 'points', points, radius };
}

/** "12,345 points" with the bounds of a cloud, for its item in the obstacle list. */
export function summary(o) {
  const lo = [Infinity, Infinity, Infinity], hi = [-Infinity, -Infinity, -Infinity];
  for (const p of o.points) {
    for (let k = 0; k < 3; k++) {
      if (p[k] < lo[k]) lo[k] = p[k];
      if (p[k] > hi[k]) hi[k] = p[k];
    }
  }
  const f = (x) => (Number.isFinite(x) ? x.toFixed(3) : '?');
  return `${o.points.length.toLocaleString('en')} points, x ${f(lo[0])}…${f(hi[0])}, y ${f(lo[1])}…${f(hi[1])}, z ${f(lo[2])}…${f(hi[2])} m`;
}
