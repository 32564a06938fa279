// The 3D view (WebGL, three.js): the folded model, front and back of the paper in different
// colours, creases as lines, penetrating faces red.  Orbit, zoom and pan; z is up.

import * as THREE from "three";
import { OrbitControls } from "./vendor/OrbitControls.js";
import { hintHeight } from "./view2d.js";
import { FoldSlider } from "./fold.js";

const FRONT = 0xf1e4c3, BACK = 0x8fb3de, HIT = 0xe53935;
const LINES = { V: 0x1e63d6, M: 0xe53935, B: 0x24292f };
const MARGIN = 0.92;   // the fitted model fills this fraction of the panel's smaller extent

/** WebGL drawn on the CPU (SwiftShader, llvmpipe): multisampling there costs more than the frame itself. */
function softwareRenderer() {
  const gl = document.createElement("canvas").getContext("webgl2");
  if (!gl) return false;
  const info = gl.getExtension("WEBGL_debug_renderer_info");
  const name = info ? gl.getParameter(info.UNMASKED_RENDERER_WEBGL) : "";
  const lose = gl.getExtension("WEBGL_lose_context");
  if (lose) lose.loseContext();
  return /swiftshader|llvmpipe|software/i.test(name);
}

export class ModelView {
  constructor(studio, section) {
    this.studio = studio;
    this.section = section;
    this.canvas = section.querySelector("canvas");
    this.info = section.querySelector("#model-info");
    this.showCreases = section.querySelector("#show-creases");
    this.renderer = new THREE.WebGLRenderer({ canvas: this.canvas, antialias: !softwareRenderer() });
    this.renderer.setPixelRatio(window.devicePixelRatio || 1);
    this.renderer.setClearColor(0xffffff);
    this.scene = new THREE.Scene();
    this.camera = new THREE.PerspectiveCamera(35, 1, 0.1, 1e5);
    this.camera.up.set(0, 0, 1);
    this.camera.position.set(200, -300, 200);
    this.scene.add(new THREE.HemisphereLight(0xffffff, 0x8a8f98, 1.4));
    this.light = new THREE.DirectionalLight(0xffffff, 1.6);
    this.camera.add(this.light, this.light.target);   // a head light, a little above and left of the eye
    this.light.position.set(-0.3, 0.6, 0);
    this.light.target.position.set(0, 0, -1);
    this.scene.add(this.camera);
    this.controls = new OrbitControls(this.camera, this.canvas);
    this.controls.addEventListener("change", () => { if (!this.silent) this.draw(); });
    this.objects = new THREE.Group();
    this.scene.add(this.objects);
    this.materials = {
      front: new THREE.MeshLambertMaterial({ color: FRONT, side: THREE.FrontSide, flatShading: true,
                                             polygonOffset: true, polygonOffsetFactor: 1, polygonOffsetUnits: 1 }),
      back: new THREE.MeshLambertMaterial({ color: BACK, side: THREE.BackSide, flatShading: true,
                                            polygonOffset: true, polygonOffsetFactor: 1, polygonOffsetUnits: 1 }),
      hit: new THREE.MeshBasicMaterial({ color: HIT, side: THREE.DoubleSide }),
      rejected: new THREE.MeshBasicMaterial({ color: HIT, side: THREE.DoubleSide, transparent: true, opacity: 0.55,
                                              depthTest: false }),
      lines: Object.fromEntries(Object.entries(LINES).map(([k, c]) => [k, new THREE.LineBasicMaterial({ color: c })])),
    };
    this.fitted = false;
    this.auto = true;          // refit on resize and on every new design until the user zooms or pans
    this.shownDesign = null;
    new ResizeObserver(() => this.resize()).observe(this.canvas);
    this.showCreases.addEventListener("change", () => { this.shownDesign = null; this.render(); });
    section.querySelector(".fit").addEventListener("click", () => { this.auto = true; this.fit(); });
    this.canvas.addEventListener("wheel", () => { this.auto = false; }, { passive: true });
    this.fold = new FoldSlider(this);
    this.canvas.addEventListener("pointerdown", (e) => { if (e.button === 2 || e.shiftKey) this.auto = false; });
  }

  resize() {
    const r = this.canvas.getBoundingClientRect();
    if (!r.width || !r.height) return;
    this.renderer.setSize(r.width, r.height, false);
    this.camera.aspect = r.width / r.height;
    this.camera.updateProjectionMatrix();
    if (this.auto && this.fitted) this.fit(true); else this.draw();
  }

  /** The vertices the view shows (the fold slider's state when it is not at 100%). */
  vertices() {
    return (this.fold && this.fold.vertices()) || (this.studio.shown && this.studio.shown.modelVertices);
  }

  /**
   * Frame the model so that every vertex is inside the panel with a margin, in both directions:
   * the camera distance is the least at which each vertex projects inside the frustum.
   * ``keep``: look from the current direction (after the user turned the model), else the default;
   * ``draw``: draw now (a caller that draws next anyway passes false: one frame, not two).
   */
  fit(keep = false, draw = true) {
    const v = this.vertices();
    if (!v || !v.length) return;
    const direction = keep && this.fitted
      ? this.camera.position.clone().sub(this.controls.target).normalize()
      : new THREE.Vector3(0.6, -0.8, 0.3).normalize();
    const up = new THREE.Vector3(0, 0, 1);
    const right = new THREE.Vector3().crossVectors(up, direction);
    if (right.lengthSq() < 1e-12) right.set(1, 0, 0);
    right.normalize();
    const top = new THREE.Vector3().crossVectors(direction, right).normalize();
    const height = this.canvas.clientHeight || 1;   // the hint line at the bottom is not free room
    const tanV = Math.tan(THREE.MathUtils.degToRad(this.camera.fov / 2)) * MARGIN * (1 - 2 * hintHeight(this.canvas) / height);
    const tanH = tanV * this.camera.aspect;
    const centre = new THREE.Box3().setFromArray(v).getCenter(new THREE.Vector3());
    let distance = 0;
    for (let pass = 0; pass < 2; pass++) {   // the second pass centres the projected extent
      distance = 0;
      for (let i = 0; i < v.length; i += 3) {
        const x = v[i] - centre.x, y = v[i + 1] - centre.y, z = v[i + 2] - centre.z;
        const a = x * right.x + y * right.y + z * right.z, b = x * top.x + y * top.y + z * top.z;
        const c = x * direction.x + y * direction.y + z * direction.z;
        distance = Math.max(distance, c + Math.abs(a) / tanH, c + Math.abs(b) / tanV);
      }
      if (pass) break;
      const box = [Infinity, -Infinity, Infinity, -Infinity];
      for (let i = 0; i < v.length; i += 3) {
        const x = v[i] - centre.x, y = v[i + 1] - centre.y, z = v[i + 2] - centre.z;
        const depth = distance - (x * direction.x + y * direction.y + z * direction.z);
        const a = (x * right.x + y * right.y + z * right.z) / depth, b = (x * top.x + y * top.y + z * top.z) / depth;
        box[0] = Math.min(box[0], a); box[1] = Math.max(box[1], a); box[2] = Math.min(box[2], b); box[3] = Math.max(box[3], b);
      }
      centre.addScaledVector(right, (box[0] + box[1]) / 2 * distance).addScaledVector(top, (box[2] + box[3]) / 2 * distance);
    }
    distance = Math.max(distance, 1e-3);
    this.camera.position.copy(centre).addScaledVector(direction, distance);
    this.camera.near = distance / 100;
    this.camera.far = distance * 100;
    this.camera.updateProjectionMatrix();
    this.controls.target.copy(centre);
    this.silent = !draw;   // the controls' change event draws unless told not to
    this.controls.update();
    this.silent = false;
    this.fitted = true;
    if (draw) this.draw();
  }

  /** The projected extent of the shown vertices, [x0, y0, x1, y1] in normalized device coordinates (for tests). */
  screenBox() {
    const v = this.vertices(), p = new THREE.Vector3(), box = [Infinity, Infinity, -Infinity, -Infinity];
    this.camera.updateMatrixWorld();
    for (let i = 0; i < v.length; i += 3) {
      p.set(v[i], v[i + 1], v[i + 2]).project(this.camera);
      box[0] = Math.min(box[0], p.x); box[1] = Math.min(box[1], p.y);
      box[2] = Math.max(box[2], p.x); box[3] = Math.max(box[3], p.y);
    }
    return box;
  }

  /** Rebuild the scene when the shown design changed; always redraw. */
  render() {
    const shown = this.studio.shown;
    if (shown && shown !== this.shownDesign) {
      this.build(shown);
      this.shownDesign = shown;
      if (this.fold.vertices()) this.fold.apply(false);   // the slider's state, until the new design's arrives
      if (!this.fitted) this.fit(false, false); else if (this.auto) this.fit(true, false);
    }
    this.buildRejected(this.studio.error && this.studio.error.penetrating);
    this.section.querySelector(".stale").hidden = !(this.studio.error && shown);
    if (shown) {
      const s = shown.summary;
      this.info.textContent = `${s.faces} faces · ${s.vertices} vertices · ${s.corners} corners · ` +
        `${s.closed ? "closed" : "open"} · penetrations ${s.penetrations}${this.foldInfo || ""}`;
    }
    this.draw();
  }

  clear(group) {
    for (const child of [...group.children]) {
      group.remove(child);
      if (child.geometry && !child.userData.shared) child.geometry.dispose();
    }
  }

  build(shown) {
    this.clear(this.objects);
    const position = new THREE.BufferAttribute(shown.modelVertices, 3);
    const surface = new THREE.BufferGeometry();
    surface.setAttribute("position", position);
    this.position = position;
    this.surface = surface;
    surface.setIndex(new THREE.BufferAttribute(shown.triangles, 1));
    this.objects.add(new THREE.Mesh(surface, this.materials.front));
    const back = new THREE.Mesh(surface, this.materials.back);
    back.userData.shared = true;
    this.objects.add(back);
    const quads = shown.penetrating;
    if (quads.length) {
      const tris = new Uint32Array(quads.length / 4 * 6);
      for (let q = 0, t = 0; q < quads.length; q += 4, t += 6) {
        tris.set([quads[q], quads[q + 1], quads[q + 2], quads[q], quads[q + 2], quads[q + 3]], t);
      }
      const hit = new THREE.BufferGeometry();
      hit.setAttribute("position", position);
      hit.setIndex(new THREE.BufferAttribute(tris, 1));
      this.objects.add(new THREE.Mesh(hit, this.materials.hit));
    }
    if (this.showCreases.checked) {
      for (const kind of ["V", "M", "B"]) {
        const [start, count] = shown.edgeGroups[kind];
        if (!count) continue;
        const lines = new THREE.BufferGeometry();
        lines.setAttribute("position", position);
        lines.setIndex(new THREE.BufferAttribute(shown.edges.subarray(2 * start, 2 * (start + count)), 1));
        this.objects.add(new THREE.LineSegments(lines, this.materials.lines[kind]));
      }
    }
  }

  /** The penetrating faces of a design the studio refused, over the last valid one. */
  buildRejected(flat) {
    if (this.rejected) {
      this.scene.remove(this.rejected);
      this.rejected.geometry.dispose();
      this.rejected = null;
    }
    if (!flat || !flat.length) return;
    const quads = new Float32Array(flat);
    const tris = [];
    for (let q = 0; q < quads.length / 12; q++) tris.push(4 * q, 4 * q + 1, 4 * q + 2, 4 * q, 4 * q + 2, 4 * q + 3);
    const geometry = new THREE.BufferGeometry();
    geometry.setAttribute("position", new THREE.BufferAttribute(quads, 3));
    geometry.setIndex(tris);
    this.rejected = new THREE.Mesh(geometry, this.materials.rejected);
    this.rejected.renderOrder = 2;
    this.scene.add(this.rejected);
  }

  draw() {
    this.renderer.render(this.scene, this.camera);
  }
}
