// The 3-D view of a run: the stock (the run's final stock from GET /runs/{id}/stock, or the
// in-process stock at the plot cursor), the tool and its holder at the cursor, and the tool path
// coloured by load against the limit. Orbit (drag), zoom (wheel), pan (right drag), preset views,
// a measuring tool (two clicks on the stock or the path), a click on the path picks its time.
//
// The in-process stock is a display approximation: the final stock's height field plus what the
// tool had not yet removed at the cursor, found by sweeping the tool's profile along the logged
// path over the starting top surface (the box top, or the base run's final stock) and never
// shown below the final stock. It sees the top surface only, like the height field.
//
// The tool stands along the stock's +Z, or along the run's fixed tilt (summary.kinematics, 3+2
// machining): the path points are its tip, and the tilted tool is drawn and swept turned about it.
// A tool that turned while it cut (simultaneous five-axis) comes with its axis per path point
// (path.axis, from /motion): the tool is drawn on the axis of the point it stands at, and short
// strokes up the axis along the path show how it leans. Its in-process stock is not swept: the
// sweep's table of a tilted cutter's lowest points (tiltedLift) holds for one orientation only, so
// the view shows the engine's final stock at every time, see-through before the end.
//
// Three.js renders on demand (a changed view or cursor), never in a loop.
import * as THREE from 'three';
import { OrbitControls } from 'three/addons/controls/OrbitControls.js';
import { h, lowerBound, num } from './dom.js';
import { toolAxis, axisQuaternion, tiltedLift, pointAxis, axisTicks } from './tool_axis.js';

// Load classes against the limit: colour, dash and markers (pixels), so colour alone never tells.
export const LOAD_CLASSES = [
  { key: 'air', label: 'not cutting', colour: '#9ca3af', dashed: false, marker: 0 },
  { key: 'low', label: 'under 80 % of the limit', colour: '#005b8f', dashed: false, marker: 0 },
  { key: 'near', label: '80–100 % of the limit', colour: '#8a5a00', dashed: true, marker: 0 },
  { key: 'over', label: 'over the limit', colour: '#a50f15', dashed: false, marker: 5 },
];
// Continuous scale, 0 to 120 % of the limit; every stop at 3:1 or more against the stock's grey.
export const CONTINUOUS_STOPS = ['#08306b', '#6a3d9a', '#b35806', '#a50f15'];
// The strokes up a turning tool's axis along the path: none of the load colours, dark on the stock.
export const TOOL_AXIS_COLOUR = '#1f2937';
const CONTINUOUS_MAX = 1.2;
const STOCK_COLOUR = 0xc8cdd4;
const SELECT_COLOUR = '#1d4ed8';
const CHECKPOINT_EVERY = 200;   // path points between saved in-process stocks

export function loadClass(ratio) {
  if (!(ratio > 0)) return 0;
  if (ratio < 0.8) return 1;
  if (ratio <= 1) return 2;
  return 3;
}

export function continuousColour(ratio) {
  const f = Math.min(1, Math.max(0, ratio / CONTINUOUS_MAX)) * (CONTINUOUS_STOPS.length - 1);
  const i = Math.min(CONTINUOUS_STOPS.length - 2, Math.floor(f));
  const a = new THREE.Color(CONTINUOUS_STOPS[i]);
  return a.lerp(new THREE.Color(CONTINUOUS_STOPS[i + 1]), f - i);
}

// The canvas height for a width: wide but not taller than a laptop screen can show with its controls.
function viewHeight(width) {
  return Math.max(260, Math.min(540, Math.round(width * 0.55)));
}

export function webglAvailable() {
  try {
    const c = document.createElement('canvas');
    return Boolean(c.getContext('webgl2') || c.getContext('webgl'));
  } catch {
    return false;
  }
}

// A barrel tool (document 003; docs/run_spec.md): tip ball r2 centred on the axis, flank arc r1
// centred across the axis at R - r1 and at the height zB of the barrel's widest point, the two
// meeting where the line between their centres crosses the ball (kJoint from straight down).
function barrelGeometry(tool) {
  const R = tool.diameter_mm / 2, r1 = tool.barrel_radius_mm, r2 = tool.tip_radius_mm;
  const zB = r2 + Math.sqrt((R - r2) * (2 * r1 - R - r2));
  const kJoint = Math.asin((r1 - R) / (r1 - r2));
  return { R, r1, r2, zB, kJoint, rJoint: r2 * Math.sin(kJoint) };
}

// Height of the tool's lower surface above its tip at distance r from its axis (flat, ball, bull,
// barrel, and the cones of drills and chamfer tools).
export function toolProfile(tool) {
  const R = tool.diameter_mm / 2;
  if (tool.shape === 'barrel') {
    const b = barrelGeometry(tool);
    return (r) => {
      if (r > R) return Infinity;
      if (r <= b.rJoint) return b.r2 - Math.sqrt(Math.max(0, b.r2 * b.r2 - r * r));
      const u = r - (R - b.r1);
      return b.zB - Math.sqrt(Math.max(0, b.r1 * b.r1 - u * u));
    };
  }
  if (tool.shape === 'drill' || tool.shape === 'chamfer') {
    const tip = tool.shape === 'chamfer' ? (tool.tip_diameter_mm || 0) / 2 : 0;
    const slope = 1 / Math.tan(((tool.point_angle_deg || 118) / 2) * Math.PI / 180);
    return (r) => (r > R ? Infinity : r <= tip ? 0 : (r - tip) * slope);
  }
  const rc = tool.shape === 'ball' ? R : tool.shape === 'bull' ? Math.min(R, tool.corner_radius_mm || 0) : 0;
  const flat = R - rc;
  return (r) => {
    if (r > R) return Infinity;
    if (r <= flat || rc <= 0) return 0;
    const d = r - flat;
    return rc - Math.sqrt(Math.max(0, rc * rc - d * d));
  };
}

// The part of the tool that cuts, from its tip up its axis: the flutes, else as drawn.
function cutterLength(tool) {
  const R = tool.diameter_mm / 2;
  return tool.flute_length_mm || tool.stickout_mm || 4 * R;
}

// The tool (cutting part and shank) and holder as lathe profiles around +z from the tip.
function toolMeshes(tool) {
  const R = tool.diameter_mm / 2;
  const profile = toolProfile(tool);
  const pts = [new THREE.Vector2(0, 0)];
  if (tool.shape === 'barrel') {
    // Along the arcs rather than over r: the flank arc rises steeply where it nears its widest point.
    const b = barrelGeometry(tool);
    for (let k = 1; k <= 4; k++) {
      const a = (b.kJoint * k) / 4;
      pts.push(new THREE.Vector2(b.r2 * Math.sin(a), b.r2 * (1 - Math.cos(a))));
    }
    for (let k = 1; k <= 16; k++) {
      const a = b.kJoint + ((Math.PI / 2 - b.kJoint) * k) / 16;
      pts.push(new THREE.Vector2(R - b.r1 + b.r1 * Math.sin(a), b.zB - b.r1 * Math.cos(a)));
    }
  } else {
    for (let k = 1; k <= 12; k++) {
      const r = (R * k) / 12;
      pts.push(new THREE.Vector2(r, Math.min(profile(r), Math.max(R, tool.flute_length_mm || R))));
    }
  }
  const stickout = tool.stickout_mm || tool.flute_length_mm || 4 * R;
  // A tapered end mill (diameter_mm at the tip) widens along its flutes from the top of its
  // end profile; drawn as a straight flank (the corner's tangent blend is not drawn).
  const tanTaper = Math.tan(((tool.taper_deg || 0) * Math.PI) / 180);
  let rTop = R;
  if (tanTaper > 0) {
    const z0 = pts[pts.length - 1].y;
    const flute = Math.max(z0, tool.flute_length_mm || stickout);
    rTop = R + (flute - z0) * tanTaper;
    pts.push(new THREE.Vector2(rTop, flute));
  }
  pts.push(new THREE.Vector2(rTop, stickout));
  pts.push(new THREE.Vector2(0, stickout));
  const cutter = new THREE.LatheGeometry(pts, 24);
  cutter.rotateX(Math.PI / 2);   // lathe axis y -> z
  const group = new THREE.Group();
  group.add(new THREE.Mesh(cutter, litMaterial(cutter, 0x52525b)));
  const flute = tool.flute_length_mm || stickout;
  const band = new THREE.CylinderGeometry(rTop * 1.01, rTop * 1.01, 0.6, 24, 1, true);
  band.rotateX(Math.PI / 2);
  band.translate(0, 0, flute);
  group.add(new THREE.Mesh(band, new THREE.MeshBasicMaterial({ color: 0xf59e0b })));
  const holder = tool.holder || {};
  if (holder.diameter_mm > 0 && holder.length_mm > 0) {
    const g = new THREE.CylinderGeometry(holder.diameter_mm / 2, holder.diameter_mm / 2, holder.length_mm, 32);
    g.rotateX(Math.PI / 2);
    g.translate(0, 0, stickout + holder.length_mm / 2);
    group.add(new THREE.Mesh(g, litMaterial(g, 0x7c8594, { transparent: true, opacity: 0.45 })));
  }
  return group;
}

// Vertex colours of a triangle soup lit by a fixed key light (from above, the front and the
// left) and a fill light, each triangle by its own normal (either side: both are seen).
const KEY_LIGHT = new THREE.Vector3(-0.45, -0.6, 0.66).normalize();
const FILL_LIGHT = new THREE.Vector3(0.6, 0.3, 0.2).normalize();
const BASE = new THREE.Color(STOCK_COLOUR);
function shade(pos, length, col) {
  for (let t = 0; t < length; t += 9) {
    const ux = pos[t + 3] - pos[t], uy = pos[t + 4] - pos[t + 1], uz = pos[t + 5] - pos[t + 2];
    const vx = pos[t + 6] - pos[t], vy = pos[t + 7] - pos[t + 1], vz = pos[t + 8] - pos[t + 2];
    let nx = uy * vz - uz * vy, ny = uz * vx - ux * vz, nz = ux * vy - uy * vx;
    const len = Math.hypot(nx, ny, nz) || 1;
    nx /= len; ny /= len; nz /= len;
    const key = nx * KEY_LIGHT.x + ny * KEY_LIGHT.y + nz * KEY_LIGHT.z;
    if (nz < 0 || (nz === 0 && key < 0)) {
      nx = -nx; ny = -ny; nz = -nz;
    }
    const keyUp = nx * KEY_LIGHT.x + ny * KEY_LIGHT.y + nz * KEY_LIGHT.z;
    const fill = nx * FILL_LIGHT.x + ny * FILL_LIGHT.y + nz * FILL_LIGHT.z;
    const light = Math.min(1.12, 0.62 + 0.4 * Math.max(0, keyUp) + 0.12 * Math.abs(fill));
    for (let k = 0; k < 9; k += 3) {
      col[t + k] = BASE.r * light;
      col[t + k + 1] = BASE.g * light;
      col[t + k + 2] = BASE.b * light;
    }
  }
  return col;
}

// An unlit material whose vertex colours carry the key light (a shaded look without lights:
// the scene has no lit material, so no lighting shader to compile or run in software).
function litMaterial(geometry, colour, extra = {}) {
  const base = new THREE.Color(colour);
  const nrm = geometry.attributes.normal;
  const col = new Float32Array(nrm.count * 3);
  const n = new THREE.Vector3();
  for (let i = 0; i < nrm.count; i++) {
    n.fromBufferAttribute(nrm, i);
    const light = 0.55 + 0.45 * Math.max(0, n.dot(KEY_LIGHT)) + 0.15 * Math.abs(n.dot(FILL_LIGHT));
    col[3 * i] = base.r * light;
    col[3 * i + 1] = base.g * light;
    col[3 * i + 2] = base.b * light;
  }
  geometry.setAttribute('color', new THREE.BufferAttribute(col, 3));
  return new THREE.MeshBasicMaterial({ vertexColors: true, ...extra });
}

// The scene's three materials (three shaders in all): the stock (baked light in vertex colours,
// both sides), the lines (vertex colours, dashes through the line distance) and the
// over-the-limit markers. Software rendering pays for each shader and each draw call the first
// time it draws with it.
function stockMaterial() {
  return new THREE.MeshBasicMaterial({ vertexColors: true, side: THREE.DoubleSide });
}
function lineMaterial() {
  return new THREE.LineDashedMaterial({ vertexColors: true, dashSize: 1.5, gapSize: 1 });
}
function markerMaterial() {
  const over = LOAD_CLASSES.find((c) => c.marker);
  return new THREE.PointsMaterial({ color: over.colour, size: over.marker, sizeAttenuation: false });
}

// The height field answer of /stock as heights per cell centre (NaN: no material).
export function fieldHeights(field) {
  return Float32Array.from(field.top_mm, (v) => (v == null ? NaN : v));
}

export class View3D {
  // field: /stock answer (final stock); startTop: Float32Array of the starting heights on the same
  // grid (null: the box top); path: {t, x, y, z} in stock coordinates; ratio: load / limit per
  // path point (Float32Array), relative: true when no limit was set (ratio is load / peak);
  // path.axis (optional): a turning tool's axis per point (tool_axis.js motionAxes);
  // tool: the run spec's tool; toolAt(t): the tool in the spindle at time t (runs with a tool
  // table), null where none is known (the default tool is shown); kinematics: the run's
  // summary.kinematics (a fixed tilt turns the tool; absent: along +Z); onPick(t).
  constructor(container, { field, startTop = null, path, ratio, relative = false, tool, toolAt = null, kinematics = null, onPick, onMeasure }) {
    this.container = container;
    this.field = field;
    this.path = path;
    this.ratio = ratio;
    this.relative = relative;
    this.tool = tool;
    this.onPick = onPick;
    this.onMeasure = onMeasure;
    this.finalTop = fieldHeights(field);
    const boxTop = field.box_mm.max[2];
    this.startTop = startTop || new Float32Array(this.finalTop.length).fill(boxTop);
    this.profile = toolProfile(tool);
    this.toolAxis = toolAxis(kinematics);   // null: along +Z, the three-axis view
    // A turning tool: its axis per path point, which wins over a fixed one; null: none.
    this.pathAxis = path.axis || null;
    // Per path point, the tool that walks it (an index into this.tools), for the in-process stock
    // and the tool drawn at the cursor.
    this.tools = [{ tool, profile: this.profile }];
    this.pointTool = new Uint16Array(path.t.length);
    if (toolAt) {
      const seen = new Map([[tool, 0]]);
      for (let i = 0; i < path.t.length; i++) {
        const t = toolAt(path.t[i]) || tool;
        if (!seen.has(t)) {
          seen.set(t, this.tools.length);
          this.tools.push({ tool: t, profile: toolProfile(t) });
        }
        this.pointTool[i] = seen.get(t);
      }
    }
    this.mode = 'classes';
    this.time = null;          // cursor time; null: the final stock, no tool
    this.measuring = false;
    this.measurePoints = [];
    this.frames = 0;

    const width = Math.max(320, container.clientWidth);
    const height = viewHeight(width);
    this.renderer = new THREE.WebGLRenderer({ antialias: false, preserveDrawingBuffer: true });
    this.renderer.setPixelRatio(Math.min(2, devicePixelRatio || 1));
    this.renderer.setSize(width, height);
    this.renderer.setClearColor(0xf3f4f6);
    this.canvas = this.renderer.domElement;
    this.canvas.setAttribute('role', 'img');
    this.canvas.setAttribute('aria-label', '3-D view of the stock, the tool and the tool path coloured by load; the worst blocks panel and the block table list the same data');
    this.canvas.tabIndex = 0;
    this.overlay = h('div', { class: 'view3d-overlay' });
    this.scaleBar = h('div', { class: 'scale-bar' }, h('span', { class: 'bar' }), h('span', { class: 'label' }));
    this.measureText = h('div', { class: 'measure-text', 'aria-live': 'polite', id: 'measure-result' });
    this.wrap = h('div', { class: 'view3d-canvas' }, this.canvas, this.overlay, this.scaleBar, this.measureText);
    container.append(this.wrap);

    this.scene = new THREE.Scene();
    const b = field.box_mm;
    this.centre = new THREE.Vector3((b.min[0] + b.max[0]) / 2, (b.min[1] + b.max[1]) / 2, (b.min[2] + b.max[2]) / 2);
    this.size = Math.max(b.max[0] - b.min[0], b.max[1] - b.min[1], b.max[2] - b.min[2]);
    this.camera = new THREE.PerspectiveCamera(35, width / height, this.size / 100, this.size * 40);
    this.camera.up.set(0, 0, 1);
    this.scene.add(this.camera);

    this.buildStock();
    this.buildPath();
    this.buildAxes();
    // The tool is built when the cursor first places it (the final stock is drawn without it).
    this.toolGroup = null;
    this.shownTool = -1;
    this.selectionLine = null;
    this.measureGroup = new THREE.Group();
    this.scene.add(this.measureGroup);

    this.cutBox = this.cutRegion();
    this.frame = 'cut';
    this.controls = new OrbitControls(this.camera, this.canvas);
    this.controls.target.copy(this.centre);
    this.controls.addEventListener('change', () => this.requestRender());
    this.controls.addEventListener('start', () => this.interacting());
    this.setView('iso');

    this.canvas.addEventListener('pointerdown', (e) => {
      this.downAt = [e.clientX, e.clientY];
    });
    this.canvas.addEventListener('pointerup', (e) => {
      if (!this.downAt || Math.hypot(e.clientX - this.downAt[0], e.clientY - this.downAt[1]) > 4) return;
      this.click(e);
    });
    this.resizeObserver = new ResizeObserver(() => this.resize());
    this.resizeObserver.observe(container);
  }

  destroy() {
    cancelAnimationFrame(this.raf);
    this.resizeObserver.disconnect();
    this.controls.dispose();
    this.renderer.dispose();
    this.scene.traverse((o) => {
      o.geometry?.dispose();
      o.material?.dispose?.();
    });
  }

  resize() {
    const width = Math.max(320, this.container.clientWidth);
    if (Math.abs(width - this.renderer.domElement.clientWidth) < 2) return;
    const height = viewHeight(width);
    this.renderer.setSize(width, height);
    this.camera.aspect = width / height;
    this.camera.updateProjectionMatrix();
    this.requestRender();
  }

  requestRender() {
    if (this.raf) return;
    this.raf = requestAnimationFrame(() => {
      this.raf = 0;
      this.render();
    });
  }

  // Draws now; a render still queued for the next frame would draw the same picture again.
  render() {
    if (this.raf) {
      cancelAnimationFrame(this.raf);
      this.raf = 0;
    }
    this.renderer.render(this.scene, this.camera);
    this.frames += 1;
    this.updateOverlay();
  }

  // ---- stock ----------------------------------------------------------------------------------

  // The stock: its top from the height field and the box's four sides down to its bottom, as
  // triangles with their lighting baked into vertex colours (a fixed light from above and the
  // front left). Software rendering pays per shaded pixel, and the stock fills most of the view:
  // an unlit material with baked colours costs a fraction of a lit one.
  buildStock() {
    const f = this.field;
    const { nx, ny } = f;
    this.cx = Float32Array.from({ length: nx }, (_, i) => f.x0_mm + (i + 0.5) * f.cell_mm);
    this.cy = Float32Array.from({ length: ny }, (_, j) => f.y0_mm + (j + 0.5) * f.cell_mm);
    this.stockGeometry = new THREE.BufferGeometry();
    this.stockMesh = new THREE.Mesh(this.stockGeometry, stockMaterial());
    this.scene.add(this.stockMesh);
    this.showHeights(this.finalTop);
  }

  // Puts heights (per cell, NaN: empty) on the stock mesh. Between cell centres, flat
  // rectangles (all corners at one height) are merged greedily, first along X, then with the same
  // run in the next row, into one quad each; anything else is two triangles per cell. Most of a
  // stock's top and a pocket's floor are flat, and software rendering pays per triangle set up as
  // well as per pixel.
  showHeights(top) {
    const f = this.field;
    const { nx, ny } = f;
    const { cx, cy } = this;
    const bottom = f.box_mm.min[2];
    // Triangles into a scratch array as large as the grid can need (kept for the next call).
    const capacity = 9 * (2 * (nx - 1) * (ny - 1) + 4 * (nx + ny));
    if (!this.scratch || this.scratch.length < capacity) this.scratch = new Float32Array(capacity);
    const pos = this.scratch;
    let n = 0;
    const tri = (x0, y0, z0, x1, y1, z1, x2, y2, z2) => {
      pos[n] = x0; pos[n + 1] = y0; pos[n + 2] = z0;
      pos[n + 3] = x1; pos[n + 4] = y1; pos[n + 5] = z1;
      pos[n + 6] = x2; pos[n + 7] = y2; pos[n + 8] = z2;
      n += 9;
    };
    const quad = (i0, j0, i1, j1, zz) => {
      tri(cx[i0], cy[j0], zz, cx[i1], cy[j0], zz, cx[i1], cy[j1], zz);
      tri(cx[i0], cy[j0], zz, cx[i1], cy[j1], zz, cx[i0], cy[j1], zz);
    };
    const z = (k) => (Number.isNaN(top[k]) ? bottom : top[k]);
    // Flat rectangles still open: key "i0,i1,z" -> first row j0; rebuilt row by row.
    let open = new Map();
    for (let j = 0; j + 1 < ny; j++) {
      const next = new Map();
      let i = 0;
      while (i + 1 < nx) {
        const a = j * nx + i;
        const d = a + nx;
        const za = top[a];
        if (Number.isNaN(za) || Number.isNaN(top[a + 1]) || Number.isNaN(top[d]) || Number.isNaN(top[d + 1])) {
          i += 1;
          continue;
        }
        if (za === top[a + 1] && za === top[d] && za === top[d + 1]) {
          let k = i + 1;
          while (k + 1 < nx && top[j * nx + k + 1] === za && top[(j + 1) * nx + k + 1] === za) k += 1;
          const key = `${i},${k},${za}`;
          next.set(key, open.has(key) ? open.get(key) : j);
          i = k;
          continue;
        }
        const e = a + 1;
        tri(cx[i], cy[j], za, cx[i + 1], cy[j], z(e), cx[i + 1], cy[j + 1], z(e + nx));
        tri(cx[i], cy[j], za, cx[i + 1], cy[j + 1], z(e + nx), cx[i], cy[j + 1], z(d));
        i += 1;
      }
      // Rectangles that do not go on into this row end below it.
      for (const [key, j0] of open) {
        if (next.get(key) === j0) continue;
        const [i0, i1, zz] = key.split(',').map(Number);
        quad(i0, j0, i1, j, zz);
      }
      open = next;
    }
    for (const [key, j0] of open) {
      const [i0, i1, zz] = key.split(',').map(Number);
      quad(i0, j0, i1, ny - 1, zz);
    }
    const topCount = n / 9;
    // The sides: from the edge cells' heights down to the box bottom, at the box's faces.
    const b = f.box_mm;
    const side = (count, cell, coord, fixed, alongX) => {
      for (let q = 0; q + 1 < count; q++) {
        const k0 = cell(q);
        const k1 = cell(q + 1);
        const c0 = coord[q];
        const c1 = coord[q + 1];
        if (alongX) {
          tri(c0, fixed, bottom, c1, fixed, bottom, c1, fixed, z(k1));
          tri(c0, fixed, bottom, c1, fixed, z(k1), c0, fixed, z(k0));
        } else {
          tri(fixed, c0, bottom, fixed, c1, bottom, fixed, c1, z(k1));
          tri(fixed, c0, bottom, fixed, c1, z(k1), fixed, c0, z(k0));
        }
      }
    };
    side(nx, (i) => i, cx, b.min[1], true);
    side(nx, (i) => (ny - 1) * nx + i, cx, b.max[1], true);
    side(ny, (j) => j * nx, cy, b.min[0], false);
    side(ny, (j) => j * nx + nx - 1, cy, b.max[0], false);
    // The GPU buffers: reused while the triangles fit, else replaced by ones a quarter larger
    // than needed (the in-process stock changes its count with the cursor). Uploading only what
    // is drawn: the first frame pays for every byte sent to the GPU.
    let g = this.stockGeometry;
    if (!g.attributes.position || g.attributes.position.array.length < n) {
      const size = g.attributes.position ? Math.min(capacity, Math.ceil((n * 1.25) / 9) * 9) : n;
      g.dispose();
      g = new THREE.BufferGeometry();
      g.setAttribute('position', new THREE.BufferAttribute(new Float32Array(size), 3));
      g.setAttribute('color', new THREE.BufferAttribute(new Float32Array(size), 3));
      this.stockGeometry = g;
      this.stockMesh.geometry = g;
    }
    g.attributes.position.array.set(pos.subarray(0, n));
    shade(pos, n, g.attributes.color.array);
    for (const attr of [g.attributes.position, g.attributes.color]) {
      attr.clearUpdateRanges();
      attr.addUpdateRange(0, n);
      attr.needsUpdate = true;
    }
    g.setDrawRange(0, n / 3);
    // The stock box bounds every vertex (the buffer past the draw range holds stale ones).
    const box = new THREE.Box3(new THREE.Vector3(...b.min), new THREE.Vector3(...b.max));
    g.boundingBox = box;
    g.boundingSphere = box.getBoundingSphere(new THREE.Sphere());
    this.container.dataset.stockTriangles = String(topCount);
  }

  // ---- in-process stock -----------------------------------------------------------------------

  // Lowers `top` where the tool's lower surface at path points [from, to) passes below it;
  // segments are stepped at half a cell so a sparse path still sweeps continuously.
  sweep(top, from, to) {
    const f = this.field;
    const { nx, ny } = f;
    const c = f.cell_mm;
    const { x, y, z } = this.path;
    let R = 0, rc = 0, profile = this.profile, cutter = null;
    const use = (i) => {
      const k = this.tools[this.pointTool[i]];
      R = k.tool.diameter_mm / 2;
      rc = Math.ceil(R / c);
      profile = k.profile;
      if (this.toolAxis && !k.lift) {
        // Built on the first sweep, once per tool: the view opens on the final stock, which needs none.
        k.lift = tiltedLift({ profile, radius_mm: R, length_mm: cutterLength(k.tool), axis: this.toolAxis, step_mm: c / 4 });
      }
      cutter = k.lift;
    };
    // A tilted cutter reaches past its tip's disc (toward its top), and its lowest point at an
    // offset is no longer a function of the distance alone.
    const stampTilted = (px, py, pz) => {
      const i0 = Math.max(0, Math.ceil((px + cutter.x0_mm - f.x0_mm) / c - 0.5));
      const i1 = Math.min(nx - 1, Math.floor((px + cutter.x1_mm - f.x0_mm) / c - 0.5));
      const j0 = Math.max(0, Math.ceil((py + cutter.y0_mm - f.y0_mm) / c - 0.5));
      const j1 = Math.min(ny - 1, Math.floor((py + cutter.y1_mm - f.y0_mm) / c - 0.5));
      for (let j = j0; j <= j1; j++) {
        const dy = f.y0_mm + (j + 0.5) * c - py;
        for (let i = i0; i <= i1; i++) {
          const up = cutter.at(f.x0_mm + (i + 0.5) * c - px, dy);
          if (up === Infinity) continue;
          const k = j * nx + i;
          if (pz + up < top[k]) top[k] = pz + up;
        }
      }
    };
    const stampVertical = (px, py, pz) => {
      const ci = Math.floor((px - f.x0_mm) / c);
      const cj = Math.floor((py - f.y0_mm) / c);
      for (let j = Math.max(0, cj - rc); j <= Math.min(ny - 1, cj + rc); j++) {
        const dy = f.y0_mm + (j + 0.5) * c - py;
        for (let i = Math.max(0, ci - rc); i <= Math.min(nx - 1, ci + rc); i++) {
          const dx = f.x0_mm + (i + 0.5) * c - px;
          const lift = profile(Math.hypot(dx, dy));
          if (lift === Infinity) continue;
          const k = j * nx + i;
          if (pz + lift < top[k]) top[k] = pz + lift;
        }
      }
    };
    const stamp = (px, py, pz) => (cutter ? stampTilted(px, py, pz) : stampVertical(px, py, pz));
    for (let i = Math.max(1, from); i < to; i++) {
      use(i - 1);
      const len = Math.hypot(x[i] - x[i - 1], y[i] - y[i - 1], z[i] - z[i - 1]);
      const steps = Math.max(1, Math.ceil(len / (c / 2)));
      if (steps > 4000) continue;   // a jump in the log (a new session), not a move
      for (let s = 1; s <= steps; s++) {
        const u = s / steps;
        stamp(x[i - 1] + u * (x[i] - x[i - 1]), y[i - 1] + u * (y[i] - y[i - 1]), z[i - 1] + u * (z[i] - z[i - 1]));
      }
    }
    if (from === 0 && to > 0) {
      use(0);
      stamp(x[0], y[0], z[0]);
    }
  }

  // The in-process heights after path point `upto` (exclusive), from the nearest saved state.
  heightsAt(upto) {
    // A turning tool: the final stock (see the top of this file).
    if (this.pathAxis) return Float32Array.from(this.finalTop);
    if (!this.checkpoints) this.checkpoints = [{ at: 0, top: this.startTop }];
    let cp = this.checkpoints[0];
    for (const c of this.checkpoints) if (c.at <= upto) cp = c;
    const top = Float32Array.from(cp.top);
    let at = cp.at;
    while (at < upto) {
      const next = Math.min(upto, (Math.floor(at / CHECKPOINT_EVERY) + 1) * CHECKPOINT_EVERY);
      this.sweep(top, at, next);
      at = next;
      if (at % CHECKPOINT_EVERY === 0 && !this.checkpoints.some((c) => c.at === at)) {
        this.checkpoints.push({ at, top: Float32Array.from(top) });
        this.checkpoints.sort((a, b) => a.at - b.at);
      }
    }
    // Never below the engine's final stock: the sweep is the display's, the final stock the engine's.
    for (let k = 0; k < top.length; k++) {
      const fin = this.finalTop[k];
      if (Number.isNaN(fin)) continue;
      if (Number.isNaN(top[k]) || top[k] < fin) top[k] = fin;
    }
    return top;
  }

  // Cursor time: the in-process stock and the tool there; null: the final stock without the tool.
  setTime(t) {
    this.time = t;
    const { path } = this;
    // Material not yet removed is see-through, so the path still to come shows inside it.
    const ghost = t != null && t < path.t[path.t.length - 1];
    for (const m of [this.stockMesh.material]) {
      if (m.transparent !== ghost) {
        m.transparent = ghost;
        m.opacity = ghost ? 0.55 : 1;
        m.depthWrite = !ghost;
        m.needsUpdate = true;
      }
    }
    if (t == null || t >= path.t[path.t.length - 1]) {
      this.showHeights(this.finalTop);
      this.placeTool(t == null ? null : path.t.length - 1);
    } else {
      const i = Math.max(0, lowerBound(path.t, t));
      this.showHeights(this.heightsAt(i));
      this.placeTool(i);
    }
    this.container.dataset.time = t == null ? '' : String(t);
    this.requestRender();
  }

  placeTool(i) {
    if (i == null) {
      if (this.toolGroup) this.toolGroup.visible = false;
      return;
    }
    const { x, y, z } = this.path;
    if (this.pointTool[i] !== this.shownTool) {
      // A tool change: the mesh of the tool in the spindle there.
      this.shownTool = this.pointTool[i];
      if (this.toolGroup) {
        this.scene.remove(this.toolGroup);
        this.toolGroup.traverse((o) => {
          o.geometry?.dispose();
          o.material?.dispose?.();
        });
      }
      this.toolGroup = toolMeshes(this.tools[this.shownTool].tool);
      // Built around +Z from its tip, so turning the group about the tip stands the tool, its
      // shank and holder on the run's axis.
      if (this.toolAxis) this.toolGroup.quaternion.set(...axisQuaternion(this.toolAxis));
      this.scene.add(this.toolGroup);
    }
    // A turning tool stands on the axis of the point it is at.
    const axis = pointAxis(this.path, i);
    if (axis) this.toolGroup.quaternion.set(...axisQuaternion(axis));
    this.toolIndex = i;
    this.toolGroup.position.set(x[i], y[i], z[i]);
    this.toolGroup.visible = true;
  }

  // ---- path -------------------------------------------------------------------------------------

  // The path, the stock box's edges and the axes as one LineSegments (one draw call, one
  // shader): a colour per vertex, and a dash pattern per class through the line distance: dashed
  // classes carry their distance along the path, solid ones zero (always inside a dash). GL lines
  // are one pixel wide, so a class is told by its dash and its markers as well as its colour:
  // dashed 80-100 %, square markers over the limit. (Screen-space wide lines cost software
  // rendering several times the whole scene.)
  buildPath() {
    const { x, y, z } = this.path;
    const n = x.length;
    const b = this.field.box_mm;
    const [x0, y0, z0] = b.min;
    const [x1, y1, z1] = b.max;
    const len = this.size * 0.25;
    // Box edges, then the axes from the box's min corner.
    const fixed = [
      [x0, y0, z0, x1, y0, z0], [x1, y0, z0, x1, y1, z0], [x1, y1, z0, x0, y1, z0], [x0, y1, z0, x0, y0, z0],
      [x0, y0, z1, x1, y0, z1], [x1, y0, z1, x1, y1, z1], [x1, y1, z1, x0, y1, z1], [x0, y1, z1, x0, y0, z1],
      [x0, y0, z0, x0, y0, z1], [x1, y0, z0, x1, y0, z1], [x1, y1, z0, x1, y1, z1], [x0, y1, z0, x0, y1, z1],
    ].map((seg) => [seg, new THREE.Color(0x4b5563)]);
    fixed.push([[x0, y0, z0, x0 + len, y0, z0], new THREE.Color(0xa50f15)]);
    fixed.push([[x0, y0, z0, x0, y0 + len, z0], new THREE.Color(0x047857)]);
    fixed.push([[x0, y0, z0, x0, y0, z0 + len], new THREE.Color(0x1d4ed8)]);
    // A turning tool's axis along the path: a stroke up it every fortieth of the view's size
    // (at most 400), a twentieth of that size long.
    const ticks = axisTicks(this.path, { spacing_mm: this.size / 40, length_mm: this.size / 20 });
    const tickColour = new THREE.Color(TOOL_AXIS_COLOUR);
    for (let k = 0; k < ticks.points.length; k++) fixed.push([ticks.segments.subarray(6 * k, 6 * k + 6), tickColour]);
    this.axisTicks = ticks;
    this.container.dataset.axisTicks = String(ticks.points.length);
    const segments = (n - 1) + fixed.length;
    const pos = new Float32Array(6 * segments);
    const col = new Float32Array(6 * segments);
    const dist = new Float32Array(2 * segments);
    this.segmentClass = new Uint8Array(n - 1);
    const classColours = LOAD_CLASSES.map((c) => new THREE.Color(c.colour));
    const dashedTravel = LOAD_CLASSES.map(() => 0);
    const markers = [];
    const over = LOAD_CLASSES.findIndex((c) => c.marker);
    for (let i = 1; i < n; i++) {
      const k = loadClass(Math.max(this.ratio[i - 1], this.ratio[i]));
      const s = i - 1;
      this.segmentClass[s] = k;
      pos[6 * s] = x[i - 1]; pos[6 * s + 1] = y[i - 1]; pos[6 * s + 2] = z[i - 1];
      pos[6 * s + 3] = x[i]; pos[6 * s + 4] = y[i]; pos[6 * s + 5] = z[i];
      const c = classColours[k];
      col[6 * s] = col[6 * s + 3] = c.r;
      col[6 * s + 1] = col[6 * s + 4] = c.g;
      col[6 * s + 2] = col[6 * s + 5] = c.b;
      if (LOAD_CLASSES[k].dashed) {
        // Each dashed class measures its own distance, as its own dashed line would.
        const d0 = dashedTravel[k];
        dashedTravel[k] = d0 + Math.hypot(x[i] - x[i - 1], y[i] - y[i - 1], z[i] - z[i - 1]);
        dist[2 * s] = d0;
        dist[2 * s + 1] = dashedTravel[k];
      }
      if (k === over) markers.push(x[i - 1], y[i - 1], z[i - 1], x[i], y[i], z[i]);
    }
    fixed.forEach(([seg, c], q) => {
      const s = n - 1 + q;
      pos.set(seg, 6 * s);
      col.set([c.r, c.g, c.b, c.r, c.g, c.b], 6 * s);
    });
    this.classColourArray = col.slice();
    this.classDistArray = dist.slice();
    const g = new THREE.BufferGeometry();
    g.setAttribute('position', new THREE.BufferAttribute(pos, 3));
    g.setAttribute('color', new THREE.BufferAttribute(col, 3));
    g.setAttribute('lineDistance', new THREE.BufferAttribute(dist, 1));
    this.lines = new THREE.LineSegments(g, lineMaterial());
    this.scene.add(this.lines);
    this.pathGroup = new THREE.Group();
    this.scene.add(this.pathGroup);
    this.markers = null;
    if (markers.length) {
      const mg = new THREE.BufferGeometry();
      mg.setAttribute('position', new THREE.BufferAttribute(Float32Array.from(markers), 3));
      this.markers = new THREE.Points(mg, markerMaterial());
      this.pathGroup.add(this.markers);
    }
  }

  // Continuous: the same lines with a colour per segment on the 0-120 % scale and no dashes,
  // computed when first shown.
  continuousArrays() {
    if (this.contColourArray) return;
    const n = this.path.x.length;
    const col = this.classColourArray.slice();
    const air = new THREE.Color(LOAD_CLASSES[0].colour);
    for (let i = 1; i < n; i++) {
      const r = Math.max(this.ratio[i - 1], this.ratio[i]);
      const cc = r > 0 ? continuousColour(r) : air;
      const s = i - 1;
      col[6 * s] = col[6 * s + 3] = cc.r;
      col[6 * s + 1] = col[6 * s + 4] = cc.g;
      col[6 * s + 2] = col[6 * s + 5] = cc.b;
    }
    this.contColourArray = col;
    this.contDistArray = new Float32Array(this.classDistArray.length);
  }

  setColourMode(mode) {
    this.mode = mode;
    if (mode === 'continuous') this.continuousArrays();
    const g = this.lines.geometry;
    g.attributes.color.array.set(mode === 'continuous' ? this.contColourArray : this.classColourArray);
    g.attributes.lineDistance.array.set(mode === 'continuous' ? this.contDistArray : this.classDistArray);
    g.attributes.color.needsUpdate = true;
    g.attributes.lineDistance.needsUpdate = true;
    if (this.markers) this.markers.visible = mode === 'classes';
    this.requestRender();
  }

  // The selected block's path: its points as large blue squares drawn over everything, and its
  // line.
  select(block) {
    if (this.selectionLine) {
      this.pathGroup.remove(this.selectionLine);
      this.selectionLine.traverse((o) => o.geometry?.dispose());
      this.selectionLine = null;
    }
    this.container.dataset.selectedSegments = '0';
    if (block) {
      const { t, x, y, z } = this.path;
      const pos = [];
      for (let i = 1; i < t.length; i++) {
        if (t[i] < block.t_start_s || t[i - 1] > block.t_end_s) continue;
        pos.push(x[i - 1], y[i - 1], z[i - 1], x[i], y[i], z[i]);
      }
      if (pos.length) {
        const g = new THREE.BufferGeometry();
        g.setAttribute('position', new THREE.Float32BufferAttribute(pos, 3));
        this.selectionLine = new THREE.Group();
        const points = new THREE.Points(g, new THREE.PointsMaterial({ color: SELECT_COLOUR, size: 7, sizeAttenuation: false, depthTest: false, transparent: true, opacity: 0.6 }));
        const line = new THREE.LineSegments(g, new THREE.LineBasicMaterial({ color: SELECT_COLOUR, depthTest: false }));
        points.renderOrder = 1;
        line.renderOrder = 1;
        this.selectionLine.add(points, line);
        this.pathGroup.add(this.selectionLine);
        this.container.dataset.selectedSegments = String(pos.length / 6);
      }
    }
    this.requestRender();
  }

  // ---- camera, axes, scale ------------------------------------------------------------------------

  // The box around the path where the tool cuts (and a tool diameter around it): what the view
  // frames first. The whole stock when nothing cuts.
  cutRegion() {
    const { x, y, z } = this.path;
    const box = new THREE.Box3();
    const b = this.field.box_mm;
    const stock = new THREE.Box3(new THREE.Vector3(...b.min), new THREE.Vector3(...b.max));
    // Loaded points inside the stock (the load of a point comes from buckets that may reach
    // past the end of a cut, so a point of the approach can carry some).
    const p = new THREE.Vector3();
    for (let i = 0; i < x.length; i++) {
      if (this.ratio[i] > 0 && stock.containsPoint(p.set(x[i], y[i], z[i]))) box.expandByPoint(p);
    }
    if (box.isEmpty()) return stock;
    box.expandByScalar(this.tool.diameter_mm);
    box.max.z = Math.max(box.max.z, b.max[2]);
    return box.intersect(stock).isEmpty() ? stock : box;
  }

  // which: iso, top, front, side; frame: 'cut' (the region the tool cuts) or 'stock' (all of it).
  setView(which, frame = this.frame) {
    this.frame = frame;
    const b = this.field.box_mm;
    const box = frame === 'stock' ? new THREE.Box3(new THREE.Vector3(...b.min), new THREE.Vector3(...b.max)) : this.cutBox;
    const centre = box.getCenter(new THREE.Vector3());
    const radius = box.getSize(new THREE.Vector3()).length() / 2;
    const fov = THREE.MathUtils.degToRad(this.camera.fov);
    const fit = Math.min(fov, 2 * Math.atan(Math.tan(fov / 2) * this.camera.aspect));
    const d = (radius / Math.sin(fit / 2)) * 1.05;
    const dirs = { iso: [-0.9, -1.3, 1.1], top: [0, -0.001, 1], front: [0, -1, 0.001], side: [1, 0, 0.001] };
    const v = new THREE.Vector3(...(dirs[which] || dirs.iso)).normalize().multiplyScalar(d);
    this.camera.position.copy(centre).add(v);
    this.controls.target.copy(centre);
    this.camera.lookAt(centre);
    this.controls.update();
    this.requestRender();
  }

  // Rotates the camera about the target by `radians` (the orbit benchmark and the keyboard).
  // While the view moves it is drawn at half resolution (software rendering pays per pixel), and
  // sharp again once it has stood still for a moment.
  interacting() {
    const full = Math.min(2, devicePixelRatio || 1);
    if (this.renderer.getPixelRatio() !== full / 2) this.renderer.setPixelRatio(full / 2);
    clearTimeout(this.sharpTimer);
    this.sharpTimer = setTimeout(() => {
      this.renderer.setPixelRatio(full);
      this.requestRender();
    }, 200);
  }

  orbit(radians) {
    this.interacting();
    const off = this.camera.position.clone().sub(this.controls.target);
    off.applyAxisAngle(new THREE.Vector3(0, 0, 1), radians);
    this.camera.position.copy(this.controls.target).add(off);
    this.camera.lookAt(this.controls.target);
    this.controls.update();
  }

  // The axes' and the box corners' labels (their lines are part of this.lines).
  buildAxes() {
    const b = this.field.box_mm;
    const len = this.size * 0.25;
    const o = new THREE.Vector3(...b.min);
    // Labels in HTML over the canvas: the axis names and the box corners' coordinates.
    this.labels = [
      { at: o.clone().add(new THREE.Vector3(len * 1.1, 0, 0)), text: 'X' },
      { at: o.clone().add(new THREE.Vector3(0, len * 1.1, 0)), text: 'Y' },
      { at: o.clone().add(new THREE.Vector3(0, 0, len * 1.1)), text: 'Z' },
      { at: new THREE.Vector3(...b.min), text: `(${num(b.min[0])}, ${num(b.min[1])}, ${num(b.min[2])})`, small: true },
      { at: new THREE.Vector3(...b.max), text: `(${num(b.max[0])}, ${num(b.max[1])}, ${num(b.max[2])})`, small: true },
    ].map((l) => ({ ...l, el: h('span', { class: l.small ? 'axis-label small' : 'axis-label' }, l.text) }));
    this.overlay.append(...this.labels.map((l) => l.el));
  }

  project(v) {
    const p = v.clone().project(this.camera);
    const w = this.canvas.clientWidth;
    const hh = this.canvas.clientHeight;
    return [(p.x + 1) / 2 * w, (1 - p.y) / 2 * hh, p.z];
  }

  updateOverlay() {
    for (const l of this.labels) {
      const [sx, sy, sz] = this.project(l.at);
      l.el.style.transform = `translate(${sx.toFixed(1)}px, ${sy.toFixed(1)}px)`;
      l.el.hidden = sz > 1;
    }
    // Scale bar: a round length that spans about 80-160 px at the target's distance.
    const dist = this.camera.position.distanceTo(this.controls.target);
    const pxPerMm = this.canvas.clientHeight / (2 * dist * Math.tan(THREE.MathUtils.degToRad(this.camera.fov / 2)));
    const want = 120 / pxPerMm;
    const pow = 10 ** Math.floor(Math.log10(want));
    const mm = [1, 2, 5, 10].map((m) => m * pow).find((m) => m * pxPerMm >= 80) || 10 * pow;
    this.scaleBar.querySelector('.bar').style.width = `${(mm * pxPerMm).toFixed(0)}px`;
    this.scaleBar.querySelector('.label').textContent = `${num(mm)} mm (at the centre)`;
  }

  // ---- picking and measuring -----------------------------------------------------------------------

  // The path point nearest to the pointer within 12 px, or null.
  nearestPathPoint(px, py) {
    const { x, y, z } = this.path;
    let best = -1;
    let bestD = 12 * 12;
    const v = new THREE.Vector3();
    const w = this.canvas.clientWidth;
    const hh = this.canvas.clientHeight;
    const m = new THREE.Matrix4().multiplyMatrices(this.camera.projectionMatrix, this.camera.matrixWorldInverse);
    for (let i = 0; i < x.length; i++) {
      v.set(x[i], y[i], z[i]).applyMatrix4(m);
      if (v.z > 1) continue;
      const sx = (v.x + 1) / 2 * w;
      const sy = (1 - v.y) / 2 * hh;
      const d = (sx - px) ** 2 + (sy - py) ** 2;
      if (d < bestD) {
        bestD = d;
        best = i;
      }
    }
    return best >= 0 ? best : null;
  }

  click(e) {
    const rect = this.canvas.getBoundingClientRect();
    const px = e.clientX - rect.left;
    const py = e.clientY - rect.top;
    if (!this.measuring) {
      const i = this.nearestPathPoint(px, py);
      if (i != null) this.onPick?.(this.path.t[i]);
      return;
    }
    const i = this.nearestPathPoint(px, py);
    let point = null;
    if (i != null) point = new THREE.Vector3(this.path.x[i], this.path.y[i], this.path.z[i]);
    else {
      const ray = new THREE.Raycaster();
      ray.setFromCamera(new THREE.Vector2((px / rect.width) * 2 - 1, -(py / rect.height) * 2 + 1), this.camera);
      const hit = ray.intersectObject(this.stockMesh, false)[0];
      if (hit) point = hit.point;
    }
    if (point) this.addMeasurePoint(point);
  }

  setMeasuring(on) {
    this.measuring = on;
    this.controls.enabled = true;
    this.clearMeasure();
    this.measureText.textContent = on ? 'Click two points on the stock or the path.' : '';
  }

  clearMeasure() {
    this.measurePoints = [];
    this.measureGroup.clear();
    this.requestRender();
  }

  addMeasurePoint(p) {
    if (this.measurePoints.length >= 2) this.clearMeasure();
    this.measurePoints.push(p);
    const dot = new THREE.Mesh(new THREE.SphereGeometry(this.size / 150, 12, 8), new THREE.MeshBasicMaterial({ color: 0x111111, depthTest: false }));
    dot.position.copy(p);
    dot.renderOrder = 2;
    this.measureGroup.add(dot);
    if (this.measurePoints.length === 2) {
      const [a, b] = this.measurePoints;
      const g = new THREE.BufferGeometry().setFromPoints([a, b]);
      const line = new THREE.Line(g, new THREE.LineBasicMaterial({ color: 0x111111, depthTest: false }));
      line.renderOrder = 2;
      this.measureGroup.add(line);
      const d = b.clone().sub(a);
      // Picked points carry float noise (1e-14 mm on a 30 mm distance): a component that small is 0.
      const part = (v) => num(Math.abs(v) < 1e-9 * Math.max(1, d.length()) ? 0 : v, 4);
      const text = `Distance ${num(d.length(), 4)} mm (ΔX ${part(d.x)}, ΔY ${part(d.y)}, ΔZ ${part(d.z)} mm)`;
      this.measureText.textContent = text;
      this.onMeasure?.(d.length(), d);
    } else {
      this.measureText.textContent = `First point (${num(p.x, 4)}, ${num(p.y, 4)}, ${num(p.z, 4)}) mm; click the second.`;
    }
    this.requestRender();
  }
}
