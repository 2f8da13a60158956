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

/** A curl command for POST /v1/plan (the key, if any, from $PLANNER_API_KEY). */
export function curl(origin, body, withKey) {
  const key = withKey ? ' \\\n  -H "X-API-Key: $PLANNER_API_KEY"' : '';
  return `curl -sS -X POST ${origin}/v1/plan \\\n  -H 'Content-Type: application/json'${key} \\\n  -d ${shellQuote(JSON.stringify(body))}`;
}

/** A Python script calling planner.client.PlannerClient.plan with the same request. */
export function python(origin, body, withKey) {
  const key = withKey ? ', api_key=os.environ["PLANNER_API_KEY"]' : '';
  return [
    ...(withKey ? ['import os', ''] : []),
    'from planner.client import PlannerClient',
    '',
    `request = ${py(body)}`,
    '',
    `with PlannerClient(${JSON.stringify(origin)}, timeout=60${key}) as client:`,
    '    result = client.plan(request)',
    'print(result.status, result.message)',
    '',
  ].join('\n');
}

/** The trajectory as CSV: t, q, qd, qdd (one row per sample). */
export function csv(traj) {
  const head = ['t', 'q1', 'q2', 'q3', 'qd1', 'qd2', 'qd3', 'qdd1', 'qdd2', 'qdd3'].join(',');
  const rows = traj.t.map((t, i) => [t, ...traj.q[i], ...traj.qd[i], ...traj.qdd[i]].join(','));
  return [head, ...rows].join('\n') + '\n';
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
