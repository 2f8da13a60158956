// The 3-D scene (three.js): the mechanism in the paper's frame (z up), its linkage plane,
// the obstacles, the path of P coloured by working mode and the transits, named.
import * as THREE from 'three';
import { OrbitControls } from 'three/addons/OrbitControls.js';
import { planeDirection } from './kin.js';

const COLORS = { base: 0x555555, leg: 0x1f77b4, link: 0xff7f0e, p: 0xd62728, plane: 0x9ecae1, obstacle: 0xd62728, transit: 0x6a1b9a };
/** One colour per working mode (the path's segments). */
export const MODE_COLORS = {
  '+++': '#2ca02c', '++-': '#17becf', '+-+': '#1f77b4', '+--': '#9467bd',
  '-++': '#8c564b', '-+-': '#e377c2', '--+': '#bcbd22', '---': '#7f7f7f',
};

const v3 = (a) => new THREE.Vector3(a[0], a[1], a[2]);
const UP = new THREE.Vector3(0, 1, 0);

/** A text label that keeps its size on screen. */
function label(text, color = '#1d2430', px = 13) {
  const canvas = document.createElement('canvas');
  const ctx = canvas.getContext('2d');
  const font = `600 ${px * 2}px system-ui, sans-serif`;
  ctx.font = font;
  canvas.width = Math.ceil(ctx.measureText(text).width) + 12;
  canvas.height = px * 2 + 10;
  ctx.font = font;
  ctx.fillStyle = 'rgba(255,255,255,0.8)';
  ctx.fillRect(0, 0, canvas.width, canvas.height);
  ctx.fillStyle = color;
  ctx.textBaseline = 'middle';
  ctx.fillText(text, 6, canvas.height / 2);
  const texture = new THREE.CanvasTexture(canvas);
  texture.colorSpace = THREE.SRGBColorSpace;
  const sprite = new THREE.Sprite(new THREE.SpriteMaterial({ map: texture, sizeAttenuation: false, depthTest: false }));
  sprite.scale.set((0.03 * canvas.width) / canvas.height, 0.03, 1);
  sprite.center.set(-0.15, -0.15);
  sprite.renderOrder = 10;
  return sprite;
}

let dotTexture = null;
/** A round sprite (a disc on a transparent square) for the points of a cloud. */
function dot() {
  if (dotTexture) return dotTexture;
  const canvas = document.createElement('canvas');
  canvas.width = canvas.height = 32;
  const ctx = canvas.getContext('2d');
  ctx.fillStyle = '#ffffff';
  ctx.beginPath();
  ctx.arc(16, 16, 15, 0, 2 * Math.PI);
  ctx.fill();
  dotTexture = new THREE.CanvasTexture(canvas);
  // no mipmaps: a point a pixel or two wide would sample the smallest level, whose alpha (the
  // disc's mean cover, 0.69) times a faint opacity falls under the alpha test and the whole
  // cloud vanishes; the full-size disc keeps its centre opaque at any size
  dotTexture.generateMipmaps = false;
  dotTexture.minFilter = THREE.LinearFilter;
  return dotTexture;
}

/** A cylinder of radius r from a to b (re-placed with place()). */
class Rod {
  constructor(group, color, r) {
    this.mesh = new THREE.Mesh(new THREE.CylinderGeometry(1, 1, 1, 20), new THREE.MeshStandardMaterial({ color, roughness: 0.5 }));
    this.r = r;
    group.add(this.mesh);
  }
  place(a, b) {
    const A = v3(a), B = v3(b), d = B.clone().sub(A), len = d.length();
    this.mesh.visible = len > 1e-9;
    if (!this.mesh.visible) return;
    this.mesh.position.copy(A).addScaledVector(d, 0.5);
    this.mesh.quaternion.setFromUnitVectors(UP, d.normalize());
    this.mesh.scale.set(this.r, len, this.r);
  }
}

export class Scene {
  constructor(canvas) {
    this.canvas = canvas;
    this.renderer = new THREE.WebGLRenderer({ canvas, antialias: true, preserveDrawingBuffer: true });
    this.renderer.setPixelRatio(Math.min(window.devicePixelRatio, 2));
    this.scene = new THREE.Scene();
    this.scene.background = new THREE.Color(0xffffff);
    this.camera = new THREE.PerspectiveCamera(40, 1, 0.01, 100);
    this.camera.up.set(0, 0, 1);
    this.camera.position.set(1.6, -1.1, 0.9);
    this.controls = new OrbitControls(this.camera, canvas);
    this.controls.addEventListener('change', () => this.render());
    this.scene.add(new THREE.HemisphereLight(0xffffff, 0x888888, 2.2));
    const sun = new THREE.DirectionalLight(0xffffff, 1.5);
    sun.position.set(2, -1, 3);
    this.scene.add(sun);
    this.robot = new THREE.Group();
    this.world = new THREE.Group();
    this.pathGroup = new THREE.Group();
    this.scene.add(this.world, this.robot, this.pathGroup);
    new ResizeObserver(() => this.resize()).observe(canvas);
    this.resize();
  }

  resize() {
    const w = this.canvas.clientWidth, h = this.canvas.clientHeight;
    if (!w || !h) return;
    this.renderer.setSize(w, h, false);
    this.camera.aspect = w / h;
    this.camera.updateProjectionMatrix();
    if (this.design) this.fit();
    this.render();
  }

  /** Put the camera where the ball of reach (every posture of the arm, the base AB, the
   * linkage plane) fits the canvas, whatever its aspect: the smaller of the two fields of
   * view decides the distance. */
  fit() {
    const radius = this.reach + this.design.L0 / 2 + 0.02;
    const vfov = THREE.MathUtils.degToRad(this.camera.fov);
    const hfov = 2 * Math.atan(Math.tan(vfov / 2) * this.camera.aspect);
    const dist = (1.08 * radius) / Math.sin(Math.min(vfov, hfov) / 2);
    const dir = this.camera.position.clone().sub(this.controls.target);
    if (dir.lengthSq() === 0) dir.set(0.8, -0.45, 0.5);
    this.camera.position.copy(this.controls.target).addScaledVector(dir.normalize(), dist);
    this.camera.near = Math.max(0.001, dist - 3 * radius);
    this.camera.far = dist + 3 * radius;
    this.camera.updateProjectionMatrix();
    this.controls.update();
  }

  /** Draw at the next frame (many changes in one task cost one drawing). */
  render() {
    if (this.pending) return;
    this.pending = true;
    requestAnimationFrame(() => {
      this.pending = false;
      this.renderer.render(this.scene, this.camera);
      this.canvas.dataset.renderedPoints = String(this.renderer.info.render.points);
      this.canvas.dataset.frames = String(Number(this.canvas.dataset.frames || 0) + 1);
    });
  }

  /** Build the robot and the static world for a design (call again when it changes). */
  setDesign(design) {
    this.design = design;
    for (const g of [this.robot, this.world]) g.clear();
    const R = design.L1 + design.L2, r = Math.max(design.link_radius, 0.006);
    this.reach = R;
    const half = design.L0 / 2;
    // floor grid (a reference only: the mechanism hangs in free space) and the axis AB
    const grid = new THREE.GridHelper(2 * (R + half) + 0.4, 20, 0xc7ccd6, 0xe3e6eb);
    grid.rotation.x = Math.PI / 2;
    grid.position.z = -R - 0.05;
    this.world.add(grid);
    const axis = new THREE.Line(
      new THREE.BufferGeometry().setFromPoints([v3([0, -half - R - 0.1, 0]), v3([0, half + R + 0.1, 0])]),
      new THREE.LineDashedMaterial({ color: 0x555555, dashSize: 0.03, gapSize: 0.02 }),
    );
    axis.computeLineDistances();
    this.world.add(axis);
    const yLabel = label('y (axis AB)', '#555');
    yLabel.position.set(0, half + R + 0.1, 0);
    this.world.add(yLabel);
    const axes = new THREE.AxesHelper(0.12);
    axes.position.set(0, 0, -R - 0.05);
    this.world.add(axes);
    // linkage plane: spanned by y and e(theta1), turned in place()
    const plane = new THREE.Mesh(
      new THREE.PlaneGeometry(2 * R, 2 * (R + half)),
      new THREE.MeshBasicMaterial({ color: COLORS.plane, transparent: true, opacity: 0.18, side: THREE.DoubleSide, depthWrite: false }),
    );
    const edge = new THREE.LineSegments(new THREE.EdgesGeometry(plane.geometry), new THREE.LineBasicMaterial({ color: 0x6baed6 }));
    plane.add(edge);
    this.plane = plane;
    this.robot.add(plane);
    this.rods = {
      AB: new Rod(this.robot, COLORS.base, r * 1.6), AC: new Rod(this.robot, COLORS.leg, r), BD: new Rod(this.robot, COLORS.leg, r),
      CP: new Rod(this.robot, COLORS.link, r), DP: new Rod(this.robot, COLORS.link, r),
    };
    this.joints = {};
    this.labels = {};
    for (const k of ['A', 'B', 'C', 'D', 'P']) {
      const color = k === 'P' ? COLORS.p : k < 'C' ? COLORS.base : 0x333333;
      const j = new THREE.Mesh(new THREE.SphereGeometry(r * (k === 'P' ? 1.9 : 1.5), 20, 14), new THREE.MeshStandardMaterial({ color }));
      this.joints[k] = j;
      this.labels[k] = label(k);
      this.robot.add(j, this.labels[k]);
    }
    this.camera.position.set(0.8, -0.45, 0.5);
    this.controls.target.set(0, 0, 0);
    this.fit();
    this.render();
  }

  /** Draw obstacles: the request's own (`list`) and, apart, a named scene's (`setSceneObstacles`). */
  setObstacles(list) {
    this.obstacles?.removeFromParent();
    this.obstacles = this.obstacleGroup(list, 0.45, 'own');
    this.scene.add(this.obstacles);
    this.countPoints();
  }

  /** The obstacles of the named scene chosen (drawn fainter than the request's own). */
  setSceneObstacles(list) {
    this.sceneObstacles?.removeFromParent();
    this.sceneObstacles = this.obstacleGroup(list || [], 0.3, 'scene');
    this.scene.add(this.sceneObstacles);
    this.countPoints();
  }

  /** A group of meshes (spheres, boxes, capsules) and, for each point cloud, one THREE.Points
   * (one BufferGeometry, its points sized by the cloud's radius: no mesh per point). A cloud's
   * Points is kept and reused while the same points array (the form's, never copied) and
   * radius come again, so a form change does not rebuild a 100,000-point buffer. */
  obstacleGroup(list, opacity, role) {
    const group = new THREE.Group();
    const mat = new THREE.MeshStandardMaterial({ color: COLORS.obstacle, transparent: true, opacity, roughness: 0.7 });
    const clouds = new Map();
    const ok = (a) => Array.isArray(a) && a.length === 3 && a.every((x) => typeof x === 'number');
    for (const o of list) {
      if (o.type === 'points') {
        const pts = this.cloud(o, opacity, this.cloudCache?.[role]);
        if (pts) { group.add(pts); clouds.set(o.points, pts); }
        continue;
      }
      let mesh = null;
      if (o.type === 'capsule' && ok(o.a) && ok(o.b) && typeof o.radius === 'number' && o.radius > 0) {
        const a = v3(o.a), d = v3(o.b).sub(a), len = d.length();
        mesh = new THREE.Mesh(new THREE.CapsuleGeometry(o.radius, len, 8, 16), mat);
        if (len > 1e-12) mesh.quaternion.setFromUnitVectors(UP, d.clone().normalize());
        mesh.position.copy(a).addScaledVector(d, 0.5);
        group.add(mesh);
        continue;
      }
      if (!ok(o.center)) continue;
      if (o.type === 'sphere' && typeof o.radius === 'number' && o.radius > 0) {
        mesh = new THREE.Mesh(new THREE.SphereGeometry(o.radius, 32, 20), mat);
      } else if (o.type === 'box' && o.size?.every((x) => typeof x === 'number' && x > 0)) {
        mesh = new THREE.Mesh(new THREE.BoxGeometry(...o.size), mat);
        const [w, x, y, z] = o.quaternion || [1, 0, 0, 0];
        mesh.quaternion.set(x, y, z, w).normalize();
      }
      if (!mesh) continue;
      mesh.position.copy(v3(o.center));
      group.add(mesh);
    }
    for (const [points, old] of this.cloudCache?.[role] || []) {  // clouds no longer drawn: freed
      if (clouds.get(points) !== old) { old.geometry.dispose(); old.material.dispose(); }
    }
    this.cloudCache = { ...this.cloudCache, [role]: clouds };
    return group;
  }

  /** One THREE.Points for a cloud {points: N x 3, radius}: a Float32Array of positions, a
   * round sprite of diameter 2 radius (world units, so it shrinks with distance as a ball
   * does). Points that are not three numbers are left out. */
  cloud(o, opacity, cache) {
    if (!Array.isArray(o.points) || !(typeof o.radius === 'number' && o.radius > 0)) return null;
    const hit = cache?.get(o.points);
    if (hit && hit.userData.radius === o.radius && hit.userData.opacity === opacity) return hit;
    const xyz = new Float32Array(3 * o.points.length);
    let n = 0;
    for (const p of o.points) {
      if (!Array.isArray(p) || p.length !== 3 || !Number.isFinite(p[0]) || !Number.isFinite(p[1]) || !Number.isFinite(p[2])) continue;
      xyz[3 * n] = p[0]; xyz[3 * n + 1] = p[1]; xyz[3 * n + 2] = p[2];
      n++;
    }
    const geometry = new THREE.BufferGeometry();
    geometry.setAttribute('position', new THREE.BufferAttribute(n === o.points.length ? xyz : xyz.slice(0, 3 * n), 3));
    geometry.computeBoundingSphere();
    // opaque sprites (the alpha test cuts the disc out); a fainter cloud (a named scene's) is
    // paler, not translucent, so no opacity can push its points under the alpha test
    const color = new THREE.Color(COLORS.obstacle).lerp(new THREE.Color(0xffffff), opacity < 0.4 ? 0.45 : 0);
    const material = new THREE.PointsMaterial({
      color, size: 2 * o.radius, sizeAttenuation: true, map: dot(), alphaTest: 0.5,
    });
    const pts = new THREE.Points(geometry, material);
    pts.userData = { radius: o.radius, opacity, count: n };
    this.canvas.dataset.cloudBuilds = String(Number(this.canvas.dataset.cloudBuilds || 0) + 1);
    return pts;
  }

  /** How many cloud points the scene holds (`data-points` of the canvas); the count drawn in
   * the last frame is `data-rendered-points` (three.js's renderer.info). */
  countPoints() {
    let n = 0;
    for (const g of [this.obstacles, this.sceneObstacles]) {
      g?.traverse((o) => { if (o.isPoints) n += o.geometry.getAttribute('position').count; });
    }
    this.canvas.dataset.points = String(n);
    this.render();
  }

  /** Put the mechanism in posture x (from kin.posture) at joint angle t1. */
  setPosture(x, t1) {
    if (!x || !this.rods) return;
    const { A, B, C, D, P } = x;
    this.rods.AB.place(A, B);
    this.rods.AC.place(A, C);
    this.rods.BD.place(B, D);
    this.rods.CP.place(C, P);
    this.rods.DP.place(D, P);
    for (const [k, p] of Object.entries({ A, B, C, D, P })) {
      this.joints[k].position.copy(v3(p));
      this.labels[k].position.copy(v3(p));
    }
    if (this.design.L0 === 0) this.labels.B.visible = false;  // A = B: one label
    const e = v3(planeDirection(t1)), y = new THREE.Vector3(0, 1, 0), n = e.clone().cross(y);
    this.plane.quaternion.setFromRotationMatrix(new THREE.Matrix4().makeBasis(e, y, n));
    this.render();
  }

  /** The path of P (one line per segment, coloured by its working mode), the transits, the
   * goal and, for a straight path stopped short, the rest of its polyline (dashed). */
  setPath(points, segmentOf, modes, transits, goalP, rest = null) {
    this.pathGroup.clear();
    let start = 0;
    for (let i = 1; i <= points.length; i++) {
      if (i === points.length || segmentOf[i] !== segmentOf[start]) {
        const pts = points.slice(start, Math.min(i + 1, points.length)).map(v3);
        const color = MODE_COLORS[modes[segmentOf[start]]] || '#333';
        if (pts.length >= 2) {  // a thin tube: WebGL draws lines one pixel wide
          const curve = new THREE.CurvePath();
          for (let k = 1; k < pts.length; k++) curve.add(new THREE.LineCurve3(pts[k - 1], pts[k]));
          const tube = new THREE.TubeGeometry(curve, Math.max(8, pts.length), 0.004, 6, false);
          this.pathGroup.add(new THREE.Mesh(tube, new THREE.MeshBasicMaterial({ color })));
        }
        start = i;
      }
    }
    transits.forEach((tr, i) => {
      const m = new THREE.Mesh(new THREE.OctahedronGeometry(0.018), new THREE.MeshStandardMaterial({ color: COLORS.transit }));
      m.position.copy(v3(tr.p));
      const l = label(`transit ${i + 1}: ${tr.kind}`, '#6a1b9a');
      l.position.copy(v3(tr.p));
      this.pathGroup.add(m, l);
    });
    if (rest && rest.length >= 2) {  // the part of a straight path not achieved: dashed
      const line = new THREE.Line(new THREE.BufferGeometry().setFromPoints(rest.map(v3)),
        new THREE.LineDashedMaterial({ color: 0x555555, dashSize: 0.02, gapSize: 0.015 }));
      line.computeLineDistances();
      this.pathGroup.add(line);
      for (const p of rest.slice(1)) {
        const m = new THREE.Mesh(new THREE.SphereGeometry(0.01, 12, 8), new THREE.MeshBasicMaterial({ color: 0x555555, wireframe: true }));
        m.position.copy(v3(p));
        this.pathGroup.add(m);
      }
    }
    if (goalP) {
      const g = new THREE.Mesh(new THREE.SphereGeometry(0.015, 16, 10), new THREE.MeshBasicMaterial({ color: 0x2e7d32, wireframe: true }));
      g.position.copy(v3(goalP));
      this.pathGroup.add(g);
    }
    this.render();
  }
}
