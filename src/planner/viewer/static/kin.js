// Kinematics of the five-bar A-C-P-D-B turning about AB, in the paper's frame
// (docs/conventions.md): A = (0, -L0/2, 0), B = (0, L0/2, 0); the plane turns about +y; in-plane
// coordinates (u along AB, w along e(theta1) = (cos t1, 0, -sin t1)); P = (w cos t1, u, -w sin t1).
//
// Decision: the page computes C, D, P, kappa(A), the serial margin and the modes itself,
// from each trajectory sample's q, with the closed forms below (the same as the service's
// forward kernel: P is the intersection of the circles of radius L2 about C and D, on the
// side given by the assembly mode). It costs microseconds per sample, needs no request per
// animation frame, and works at any sample. The tests check these points against the
// trajectory's own P (trajectory.p, computed by the service): see fkCheck().

const sign = (x) => (x > 0 ? '+' : x < 0 ? '-' : '0');

/** Joint centres and measures of q = [t1, t2, t3] in assembly mode asm ('+' | '-'), or null. */
export function posture(design, q, asm) {
  const { L0, L1, L2 } = design;
  const [t1, t2, t3] = q;
  const cu = -L0 / 2 + L1 * Math.cos(t2), cw = L1 * Math.sin(t2);
  const du = L0 / 2 + L1 * Math.cos(t3), dw = L1 * Math.sin(t3);
  const eu = du - cu, ew = dw - cw, d2 = eu * eu + ew * ew;
  if (d2 === 0 || d2 > 4 * L2 * L2 * (1 + 1e-12)) return null;
  const h2 = L2 * L2 - d2 / 4;
  const s = (asm === '-' ? -1 : 1) * (h2 > 0 ? Math.sqrt(h2 / d2) : 0);
  const pu = (cu + du) / 2 - s * ew, pw = (cw + dw) / 2 + s * eu;
  const t4 = Math.atan2(pw - cw, pu - cu), t5 = Math.atan2(pw - dw, pu - du);
  const c1 = Math.cos(t1), s1 = Math.sin(t1);
  const to3 = (u, w) => [w * c1, u, -w * s1];
  const c = Math.cos(t4 - t5);
  const kappa = 1 - Math.abs(c) > 0 ? Math.sqrt((1 + Math.abs(c)) / (1 - Math.abs(c))) : Infinity;
  const sA = Math.sin(t4 - t2), sB = Math.sin(t5 - t3);
  const serial = Math.min(Math.abs(sA), Math.abs(sB), Math.abs(pw) / (L1 + L2));
  return {
    A: [0, -L0 / 2, 0], B: [0, L0 / 2, 0], C: to3(cu, cw), D: to3(du, dw), P: to3(pu, pw),
    u: pu, w: pw, t4, t5, kappa, serial,
    workingMode: sign(pw) + sign(sA) + sign(sB),
    assemblyMode: sign(Math.sin(t5 - t4)),
  };
}

/** The in-plane unit vector e(theta1) normal to AB. */
export const planeDirection = (t1) => [Math.cos(t1), 0, -Math.sin(t1)];

/** Postures of every trajectory sample. */
export function along(design, qs, asm) {
  return qs.map((q) => posture(design, q, asm));
}

/** Largest distance between the page's P and the service's trajectory.p (m), or null. */
export function fkCheck(postures, ps) {
  if (!ps) return null;
  let worst = 0;
  postures.forEach((x, i) => {
    if (!x) { worst = Infinity; return; }
    worst = Math.max(worst, Math.hypot(x.P[0] - ps[i][0], x.P[1] - ps[i][1], x.P[2] - ps[i][2]));
  });
  return worst;
}

/** Sample index of each transit: nearest in time to its `time` when the answer gives one (a
 * sequence's `legs[].transit_times`), else nearest in joint space to its posture; a transit
 * with a `span` [t0, t1] (a sequence's leg) is looked for among the samples within it. */
export function transitSamples(qs, transits, ts = null) {
  return transits.map((tr) => {
    let best = 0, bestD = Infinity;
    if (ts && Number.isFinite(tr.time)) {
      ts.forEach((t, i) => {
        if (Math.abs(t - tr.time) < bestD) { bestD = Math.abs(t - tr.time); best = i; }
      });
      return best;
    }
    const [t0, t1] = tr.span && ts ? tr.span : [-Infinity, Infinity];
    qs.forEach((q, i) => {
      if (ts && (ts[i] < t0 - 1e-9 || ts[i] > t1 + 1e-9)) return;
      const d = Math.hypot(q[0] - tr.q[0], q[1] - tr.q[1], q[2] - tr.q[2]);
      if (d < bestD) { bestD = d; best = i; }
    });
    return best;
  });
}

/** Where theta2 or theta3 stands at one of its literal limits, for the postures of working
 * mode `mode` in assembly mode `asm`: pieces of circles in the plane (u, w), for the
 * workspace section. A straight tool path keeps its working mode, so it stops there (a
 * joint cannot pass its limit, and with limits of -pi and pi the joint would have to turn
 * through the one posture both name), while the section's cells either side are reached.
 * theta2 = a puts C at A + L1 (cos a, sin a) and P on the circle of radius L2 about C; the
 * other leg's elbow D is then where the circles (B, L1) and (P, L2) meet. Returns
 * [{joint: 2 | 3, values: [rad], u: [], w: []}], NaN between pieces. */
export function limitWalls(design, mode, asm, n = 1440) {
  const { L0, L1, L2 } = design;
  const walls = [];
  for (const j of [1, 2]) {
    const lo = design.joint_min[j], hi = design.joint_max[j];
    // a range of a whole turn: its two ends are one posture, drawn once
    const values = Math.abs(hi - lo - 2 * Math.PI) < 1e-9 ? [hi] : [lo, hi];
    for (const a of values) {
      const here = [j === 1 ? -L0 / 2 : L0 / 2, 0], there = [j === 1 ? L0 / 2 : -L0 / 2, 0];
      const c = [here[0] + L1 * Math.cos(a), L1 * Math.sin(a)];
      const u = [], w = [];
      for (let k = 0; k <= n; k++) {
        const phi = (2 * Math.PI * k) / n;
        const p = [c[0] + L2 * Math.cos(phi), c[1] + L2 * Math.sin(phi)];
        const on = otherAngles(there, p, L1, L2).some((b) => {
          const q = j === 1 ? [0, a, b] : [0, b, a];
          const lo2 = design.joint_min[3 - j], hi2 = design.joint_max[3 - j];
          if (!(b >= lo2 - 1e-12 && b <= hi2 + 1e-12)) return false;
          const x = posture(design, q, asm);
          return x && Math.hypot(x.u - p[0], x.w - p[1]) < 1e-9 && x.workingMode === mode && x.assemblyMode === asm;
        });
        u.push(on ? p[0] : NaN);
        w.push(on ? p[1] : NaN);
      }
      if (u.some(Number.isFinite)) walls.push({ joint: j + 1, values: values.length === 1 ? [lo, hi] : [a], u, w });
    }
  }
  return walls;
}

/** The angles b (in [-pi, pi]) of the elbow E = pivot + L1 (cos b, sin b) with |P - E| = L2. */
function otherAngles(pivot, p, L1, L2) {
  const du = p[0] - pivot[0], dw = p[1] - pivot[1], d = Math.hypot(du, dw);
  if (d === 0 || d > L1 + L2 || d < Math.abs(L1 - L2)) return [];
  const base = Math.atan2(dw, du), cos = (L1 * L1 + d * d - L2 * L2) / (2 * L1 * d);
  const off = Math.acos(Math.max(-1, Math.min(1, cos)));
  return [base + off, base - off].map((b) => Math.atan2(Math.sin(b), Math.cos(b)));
}
