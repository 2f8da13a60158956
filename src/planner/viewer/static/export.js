// The request as a curl command or a Python client call, and the plan as JSON or CSV.

/** A JSON value written as a Python literal. */
function py(value, indent = '') {
  const inner = indent + '    ';
  if (value === null || value === undefined) return 'None';
  if (value === true) return 'True';
  if (value === false) return 'False';
  if (typeof value === 'number') return JSON.stringify(value);
  if (typeof value === 'string') return JSON.stringify(value);
  if (Array.isArray(value)) {
    if (value.every((x) => typeof x !== 'object' || x === null)) return `[${value.map((x) => py(x)).join(', ')}]`;
    return `[\n${value.map((x) => inner + py(x, inner)).join(',\n')},\n${indent}]`;
  }
  const entries = Object.entries(value);
  if (!entries.length) return '{}';
  return `{\n${entries.map(([k, v]) => `${inner}${JSON.stringify(k)}: ${py(v, inner)}`).join(',\n')},\n${indent}}`;
}

const shellQuote = (s) => `'${s.replace(/'/g, `'\\''`)}'`;

/** A curl command for POST /v1/plan, /v1/cartesian or /v1/sequence (the key, if any, from $PLANNER_API_KEY). */
export function curl(origin, body, withKey, endpoint = 'plan') {
  const key = withKey ? ' \\\n  -H "X-API-Key: $PLANNER_API_KEY"' : '';
  return `curl -sS -X POST ${origin}/v1/${endpoint} \\\n  -H 'Content-Type: application/json'${key} \\\n  -d ${shellQuote(JSON.stringify(body))}`;
}

/** A Python script calling planner.client.PlannerClient.plan (or .cartesian, .sequence) with the same
 * request. */
export function python(origin, body, withKey, endpoint = 'plan') {
  const key = withKey ? ', api_key=os.environ["PLANNER_API_KEY"]' : '';
  return [
    ...(withKey ? ['import os', ''] : []),
    'from planner.client import PlannerClient',
    '',
    `request = ${py(body)}`,
    '',
    `with PlannerClient(${JSON.stringify(origin)}, timeout=60${key}) as client:`,
    `    result = client.${endpoint}(request)`,
    'print(result.status, result.message)',
    '',
  ].join('\n');
}

/** The first line of a CSV file: planner.timing.export.CSV_UNITS. */
export const CSV_UNITS = '# units: t s; theta rad; dtheta rad/s; ddtheta rad/s^2; dddtheta rad/s^3; tau N m';
const JOINTS = ['theta1', 'theta2', 'theta3'];

/** A float as Python's f"{x:.17g}" writes it (17 significant digits, trailing zeros dropped,
 * an exponent below 1e-4 or from 1e17), so the page's CSV is the library's byte for byte. */
export function g17(x) {
  if (x === 0) return Object.is(x, -0) ? '-0' : '0';
  if (!Number.isFinite(x)) return Number.isNaN(x) ? 'nan' : x > 0 ? 'inf' : '-inf';
  const [mant, ex] = x.toExponential(16).split('e');
  const e = Number(ex);
  const strip = (s) => (s.includes('.') ? s.replace(/0+$/, '').replace(/\.$/, '') : s);
  if (e < -4 || e >= 17) return `${strip(mant)}e${e < 0 ? '-' : '+'}${String(Math.abs(e)).padStart(2, '0')}`;
  return strip(x.toFixed(16 - e));
}

/** The trajectory as CSV, in the library's format (planner.timing.export.write_csv, which the
 * CLI and the client write too): the units line, the header
 * t,theta1..3,dtheta1..3,ddtheta1..3 (and dddtheta1..3 with ruckig's jerks, tau1..3 with the
 * actuator torques), one row per sample. */
export function csv(traj) {
  const jerk = Array.isArray(traj.jerk) ? traj.jerk : null;
  const tau = Array.isArray(traj.tau) ? traj.tau : null;
  const head = ['t', ...JOINTS, ...JOINTS.map((n) => `d${n}`), ...JOINTS.map((n) => `dd${n}`),
    ...(jerk ? JOINTS.map((n) => `ddd${n}`) : []), ...(tau ? ['tau1', 'tau2', 'tau3'] : [])].join(',');
  const rows = traj.t.map((t, i) => [t, ...traj.q[i], ...traj.qd[i], ...traj.qdd[i],
    ...(jerk ? jerk[i] : []), ...(tau ? tau[i] : [])].map(g17).join(','));
  return [CSV_UNITS, head, ...rows].join('\n') + '\n';
}

export function download(name, text, type) {
  const a = document.createElement('a');
  a.href = URL.createObjectURL(new Blob([text], { type }));
  a.download = name;
  document.body.appendChild(a);
  a.click();
  a.remove();
  setTimeout(() => URL.revokeObjectURL(a.href), 1000);
}
