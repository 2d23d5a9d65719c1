// The 3-D view (three.js): the fjord's land as a relief derived from the coastline (no
// elevation model is bundled: the height grows with the distance inland, see
// asvtwin.geo.LandMask.terrain_height_m), water at sea level, hulls to scale, the filter's
// plan, and a camera that follows the own ship from astern.
// Scene axes: x = east [m], y = up [m], z = -north [m].
import * as THREE from 'three';

const toV = (n, e, up = 0) => new THREE.Vector3(e, up, -n);

function hullGeometry() {
  // unit hull: length 1 along -z (bow at z = -0.5), beam 1, freeboard 1; scaled per vessel
  const s = new THREE.Shape();
  s.moveTo(0, -0.5); s.lineTo(0.5, -0.3); s.lineTo(0.5, 0.5); s.lineTo(-0.5, 0.5); s.lineTo(-0.5, -0.3); s.closePath();
  const g = new THREE.ExtrudeGeometry(s, { depth: 1, bevelEnabled: false });
  g.rotateX(Math.PI / 2);      // shape plane (x, y) -> (x, z); extrude along +y... then
  g.translate(0, 1, 0);        // deck at y = 1, keel at y = 0
  return g;
}

export class View3D {
  constructor(el, scene) {
    this.el = el;
    this.stats = { frames: 0, hulls: 0, terrainVertices: 0, planPoints: 0 };
    const w = el.clientWidth || 400, h = el.clientHeight || 280;
    this.renderer = new THREE.WebGLRenderer({ antialias: false, preserveDrawingBuffer: false, powerPreference: 'high-performance' });
    this.renderer.setPixelRatio(1);
    this.renderer.setSize(w, h);
    el.appendChild(this.renderer.domElement);
    this.scene = new THREE.Scene();
    this.scene.background = new THREE.Color('#a9c8e0');
    this.scene.fog = new THREE.Fog('#a9c8e0', 4000, 16000);
    this.camera = new THREE.PerspectiveCamera(50, w / h, 5, 40000);
    this.scene.add(new THREE.HemisphereLight('#ffffff', '#40506a', 1.6));
    const sun = new THREE.DirectionalLight('#ffffff', 1.5);
    sun.position.set(3000, 5000, 2000);
    this.scene.add(sun);
    this._terrain(scene.relief);
    this.hullGeom = hullGeometry();
    this.ownMesh = new THREE.Mesh(this.hullGeom, new THREE.MeshLambertMaterial({ color: '#e06a10' }));
    this.scene.add(this.ownMesh);
    this.maxTargets = 0;
    this.targets = null;
    this.planLine = null;
    this.distance = 6;   // camera distance in own-ship lengths
    this.dirty = true;   // render only when something changed (new data, zoom, resize)
    el.addEventListener('wheel', (e) => {
      e.preventDefault();
      this.distance = Math.min(60, Math.max(2, this.distance * (e.deltaY > 0 ? 1.15 : 0.87)));
      if (this.last) this._follow(...this.last);
      this.markDirty();
    }, { passive: false });
    // drag sideways to look around the own ship (the camera stays on it)
    let dragX = null;
    el.addEventListener('pointerdown', (e) => { dragX = e.clientX; el.setPointerCapture(e.pointerId); });
    el.addEventListener('pointermove', (e) => { if (dragX !== null) { this.orbitBy(0.01 * (e.clientX - dragX)); dragX = e.clientX; } });
    el.addEventListener('pointerup', () => { dragX = null; });
    new ResizeObserver(() => this.resize()).observe(el);
  }

  _terrain(r) {
    const [n0, n1] = r.north_m, [e0, e1] = r.east_m;
    const g = new THREE.PlaneGeometry(e1 - e0, n1 - n0, r.cols - 1, r.rows - 1);
    g.rotateX(-Math.PI / 2);                       // plane in x (east), z (-north)
    g.translate((e0 + e1) / 2, 0, -(n0 + n1) / 2);
    const pos = g.attributes.position, col = new Float32Array(pos.count * 3);
    const low = new THREE.Color('#6f8f4e'), high = new THREE.Color('#a89a80'), shore = new THREE.Color('#c8b98a');
    const c = new THREE.Color();
    for (let i = 0; i < pos.count; i++) {
      // PlaneGeometry vertices run row by row from +y (here: north max) to -y
      const row = r.rows - 1 - Math.floor(i / r.cols), colIdx = i % r.cols;
      const h = r.heights_m[row * r.cols + colIdx];
      pos.setY(i, h > 0 ? h : -3);
      if (h <= 0) c.copy(shore); else c.copy(low).lerp(high, Math.min(1, h / r.peak_m));
      col.set([c.r, c.g, c.b], i * 3);
    }
    g.setAttribute('color', new THREE.BufferAttribute(col, 3));
    g.computeVertexNormals();
    this.scene.add(new THREE.Mesh(g, new THREE.MeshLambertMaterial({ vertexColors: true })));
    const water = new THREE.Mesh(new THREE.PlaneGeometry(e1 - e0, n1 - n0), new THREE.MeshLambertMaterial({ color: '#3f6f95' }));
    water.rotateX(-Math.PI / 2);
    water.position.set((e0 + e1) / 2, 0, -(n0 + n1) / 2);
    this.scene.add(water);
    this.stats.terrainVertices = pos.count;
  }

  resize() {
    const w = this.el.clientWidth, h = this.el.clientHeight;
    if (!w || !h) return;
    this.renderer.setSize(w, h);
    this.camera.aspect = w / h;
    this.camera.updateProjectionMatrix();
    this.markDirty();
  }

  // Something changed: draw in the next frame (main.js sets onDirty to ask for one).
  markDirty() {
    this.dirty = true;
    if (this.onDirty) this.onDirty();
  }

  _ensureTargets(n) {
    if (n <= this.maxTargets) return;
    if (this.targets) this.scene.remove(this.targets);
    this.maxTargets = Math.max(64, 2 * n);
    this.targets = new THREE.InstancedMesh(this.hullGeom, new THREE.MeshLambertMaterial({ color: '#f2f2f2' }), this.maxTargets);
    this.targets.instanceColor = new THREE.InstancedBufferAttribute(new Float32Array(this.maxTargets * 3), 3);
    this.scene.add(this.targets);
  }

  // Vessels to scale: own ship from the snapshot, others from the derived target list.
  update(s, targets) {
    const own = s.own, [n, e, psi] = own.state;
    const L = own.length_m || 10, B = own.beam_m || 3;
    this.ownMesh.position.copy(toV(n, e, 0));
    this.ownMesh.rotation.set(0, -psi, 0);
    this.ownMesh.scale.set(B, 0.12 * L, L);
    this._ensureTargets(targets.length);
    const m = new THREE.Matrix4(), q = new THREE.Quaternion(), sc = new THREE.Vector3(), up = new THREE.Vector3(0, 1, 0);
    const white = new THREE.Color('#f2f2f2'), red = new THREE.Color('#e0141e'), grey = new THREE.Color('#8a8a8a');
    targets.forEach((t, i) => {
      const len = t.length || 30, beam = t.beam || len / 5;
      q.setFromAxisAngle(up, -(t.heading ?? t.cogRad ?? 0));
      sc.set(beam, 0.12 * len, len);
      m.compose(toV(t.pos[0], t.pos[1], 0), q, sc);
      this.targets.setMatrixAt(i, m);
      this.targets.setColorAt(i, t.danger ? red : t.lost ? grey : white);
    });
    this.targets.count = targets.length;
    this.targets.instanceMatrix.needsUpdate = true;
    this.targets.instanceColor.needsUpdate = true;
    this.stats.hulls = targets.length + 1;
    // the filter's plan slightly above the water: green, critical stages red
    if (this.planLine) { this.scene.remove(this.planLine); this.planLine.geometry.dispose(); }
    const plan = s.filter.enabled ? (s.filter.plan || []) : [];
    if (plan.length > 1) {
      const crit = new Set(s.filter.critical_stages || []);
      const pts = [], cols = [];
      for (let i = 0; i + 1 < plan.length; i++) {
        const c = crit.has(i) || crit.has(i + 1) ? [0.88, 0.08, 0.12] : [0.1, 0.6, 0.16];
        pts.push(...toV(plan[i][0], plan[i][1], 2).toArray(), ...toV(plan[i + 1][0], plan[i + 1][1], 2).toArray());
        cols.push(...c, ...c);
      }
      const g = new THREE.BufferGeometry();
      g.setAttribute('position', new THREE.Float32BufferAttribute(pts, 3));
      g.setAttribute('color', new THREE.Float32BufferAttribute(cols, 3));
      this.planLine = new THREE.LineSegments(g, new THREE.LineBasicMaterial({ vertexColors: true }));
      this.scene.add(this.planLine);
    }
    this.stats.planPoints = plan.length;
    this.last = [n, e, psi, L];
    this._follow(n, e, psi, L);
    this.dirty = true;
  }

  // The camera follows from astern and above (orbit: `this.orbit` [rad] around the own
  // ship from astern), looking a little ahead of the bow.
  _follow(n, e, psi, L) {
    const d = this.distance * L, a = psi + (this.orbit || 0);
    const back = toV(n - d * Math.cos(a), e - d * Math.sin(a), 0.45 * d + 0.3 * L);
    this.camera.position.copy(back);
    this.camera.lookAt(toV(n + 1.5 * L * Math.cos(psi), e + 1.5 * L * Math.sin(psi), 0));
  }

  // Turn the camera around the own ship by `rad` (a drag, the benchmark's orbit).
  orbitBy(rad) {
    this.orbit = ((this.orbit || 0) + rad) % (2 * Math.PI);
    if (this.last) this._follow(...this.last);
    this.markDirty();
  }

  render() {
    if (!this.dirty) return false;
    this.renderer.render(this.scene, this.camera);
    this.dirty = false;
    this.stats.frames += 1;
    return true;
  }
}
