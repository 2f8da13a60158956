// Fields checked as typed, by the service's own rules: the bounds of each number are read
// from the service's OpenAPI schema (/openapi.json), so the page and the service cannot
// disagree, and the messages are pydantic's words, the same as a 422 answer would give.
// The service stays the one validator (a request is always sent as typed); this only says
// sooner what it will say.

let components = {};
let roots = {};

/** Load the schema once; the request bodies of the endpoints the page calls. */
export async function load(getJSON) {
  const spec = await getJSON('/openapi.json');
  components = spec.components?.schemas || {};
  const body = (path) => spec.paths?.[path]?.post?.requestBody?.content?.['application/json']?.schema;
  roots = { plan: body('/v1/plan'), cartesian: body('/v1/cartesian'), sequence: body('/v1/sequence') };
  const put = spec.paths?.['/v1/scenes/{name}']?.put?.parameters?.find((q) => q.name === 'name');
  namePattern = put?.schema?.pattern || null;
}

let namePattern = null;

/** The message for a scene name as typed, by the rule of PUT /v1/scenes/{name}'s path (the
 * service's pattern, in pydantic's words), or '' when it holds or the rule is unknown. */
export function sceneName(name) {
  if (!name) return 'a name is needed';
  if (!namePattern) return '';
  return new RegExp(namePattern, 'u').test(name) ? '' : `String should match pattern '${namePattern}'`;
}

export const loaded = () => Boolean(roots.plan);

function deref(s) {
  let guard = 0;
  while (s && s.$ref && guard++ < 20) s = components[s.$ref.split('/').at(-1)];
  return s;
}

/** The schema of the value at `path` (strings) under `schema`; `hint(path)` picks a union
 * branch (e.g. an obstacle's type). */
function at(schema, path, hint) {
  let s = deref(schema);
  for (let n = 0; n < path.length && s; n++) {
    const seg = path[n];
    s = pick(s, path.slice(0, n), hint);
    if (s.type === 'array' || s.items || s.prefixItems) {
      s = deref(s.prefixItems?.[Number(seg)] || s.items);
    } else {
      s = deref(s.properties?.[seg]);
    }
  }
  return s ? pick(s, path, hint) : null;
}

/** One branch of anyOf/oneOf: the non-null one, or the one `hint` names by its type const. */
function pick(s, path, hint) {
  s = deref(s);
  let guard = 0;
  while (s && (s.anyOf || s.oneOf) && guard++ < 10) {
    const branches = (s.anyOf || s.oneOf).map(deref).filter((b) => b && b.type !== 'null');
    const want = hint(path);
    s = branches.find((b) => want && (b.properties?.type?.const === want || b.properties?.[want])) || branches[0];
  }
  return s;
}

/** A bound as pydantic's messages write it (Rust's float display: 0.000001, never 1e-6). */
const num = (x) => (String(x).includes('e') ? x.toFixed(20).replace(/\.?0+$/, '') : String(x));

/** Pydantic's message for a number `x` against schema `s`, or '' when it holds. */
export function numberMessage(s, x, required) {
  if (x === undefined) return required ? 'Field required' : '';
  if (typeof x !== 'number') {
    return s?.type === 'integer' ? 'Input should be a valid integer, unable to parse string as an integer'
      : 'Input should be a valid number, unable to parse string as a number';
  }
  if (!s) return '';
  if (s.type === 'integer' && !Number.isInteger(x)) return 'Input should be a valid integer, got a number with a fractional part';
  if (s.exclusiveMinimum !== undefined && !(x > s.exclusiveMinimum)) return `Input should be greater than ${num(s.exclusiveMinimum)}`;
  if (s.minimum !== undefined && !(x >= s.minimum)) return `Input should be greater than or equal to ${num(s.minimum)}`;
  if (s.exclusiveMaximum !== undefined && !(x < s.exclusiveMaximum)) return `Input should be less than ${num(s.exclusiveMaximum)}`;
  if (s.maximum !== undefined && !(x <= s.maximum)) return `Input should be less than or equal to ${num(s.maximum)}`;
  return '';
}

/** The message for the value `x` of the field at `loc` (e.g. "design.L1", "obstacles.0.radius.0")
 * of an endpoint's body ('plan' | 'cartesian' | 'sequence'), or '' when it holds (or the rule is unknown). */
export function check(endpoint, loc, x, { required = false, hint = () => null } = {}) {
  const root = roots[endpoint];
  if (!root) return '';
  const s = at(root, loc.split('.'), (p) => hint(p.join('.')));
  if (!s || (s.type !== 'number' && s.type !== 'integer')) return '';
  return numberMessage(s, x, required);
}
