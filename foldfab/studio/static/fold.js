// The fold slider of the 3D view: the model from the flat sheet (0%) to folded (100%), every fold
// angle scaled (foldfab.geometry.fold on the server), faces reddened where the part-way state is
// not isometric: the relative change of their sides against the crease pattern, as Origami
// Simulator shows strain.

import * as THREE from "three";
import { unpack } from "./pack.js";

/** Strain (relative length change) drawn fully red; less is blended from the paper's colour. */
export const STRAIN_FULL = 0.05;

export class FoldSlider {
  constructor(model) {
    this.model = model;
    this.studio = model.studio;
    this.t = 1;
    this.state = null;       // {t, vertices, strain, maxStrain} for the shown design, or null at 100%
    this.ticket = 0;
    const header = model.section.querySelector("header");
    const label = document.createElement("label");
    label.title = "Fold from the flat sheet (0%) to the folded model (100%): every fold angle scaled. " +
      "Red: the paper would have to stretch there (strain against the crease pattern).";
    label.innerHTML = `fold <input type="range" id="fold" min="0" max="100" step="1" value="100">` +
      `<output id="fold-value">100%</output>`;
    header.insertBefore(label, header.querySelector(".fit"));
    this.input = label.querySelector("input");
    this.output = label.querySelector("output");
    this.input.addEventListener("input", () => this.set(Number(this.input.value) / 100));
    window.addEventListener("studio:rendered", () => { if (this.t < 1 && !this.studio.error) this.request(); });
    document.body.dataset.fold = "1";
  }

  /** The part-way vertices when the slider is below 100% (and they belong to the shown design), else null. */
  vertices() {
    const shown = this.studio.shown;
    return this.state && shown && this.state.vertices.length === shown.modelVertices.length ? this.state.vertices : null;
  }

  set(t) {
    this.t = t;
    this.output.textContent = `${Math.round(100 * t)}%`;
    if (t >= 1) {
      this.ticket++;
      this.state = null;
      this.apply();
    } else {
      this.request();
    }
  }

  /** Ask the server for the state at ``t`` (an answer for an older position is dropped). */
  async request() {
    const mine = ++this.ticket;
    document.body.dataset.fold = "busy";
    const r = await this.studio.post("/api/fold", { ...this.studio.base(), t: this.t });
    if (mine !== this.ticket) return;
    if (r.buffer) {
      const { header, arrays } = unpack(r.buffer);
      this.state = { t: header.t, vertices: arrays.vertices, strain: arrays.strain, maxStrain: header.max_strain };
    }
    this.apply();
  }

  /** Show the state on the model's geometry (or the folded model at 100%); ``show``: draw it now. */
  apply(show = true) {
    const m = this.model, shown = this.studio.shown;
    if (!m.position || !shown) return;
    const vertices = this.vertices();
    m.position.array = vertices || shown.modelVertices;
    m.position.needsUpdate = true;
    const materials = [m.materials.front, m.materials.back];
    if (vertices) {
      const colour = new Float32Array(vertices.length);
      this.state.strain.forEach((s, i) => {
        const red = Math.min(1, s / STRAIN_FULL);
        colour.set([1, 1 - red, 1 - red], 3 * i);
      });
      m.surface.setAttribute("color", new THREE.BufferAttribute(colour, 3));
    } else if (m.surface.getAttribute("color")) {
      m.surface.deleteAttribute("color");
    }
    for (const material of materials) {
      if (material.vertexColors !== Boolean(vertices)) {
        material.vertexColors = Boolean(vertices);
        material.needsUpdate = true;
      }
    }
    m.objects.traverse((o) => { if (o.geometry) o.geometry.computeBoundingSphere(); });
    const info = vertices ? ` · fold ${Math.round(100 * this.state.t)}%, strain up to ${(100 * this.state.maxStrain).toFixed(1)}%` : "";
    m.foldInfo = info;
    if (!show) return;
    if (m.auto) m.fit(true, false);
    m.render();
    document.body.dataset.fold = vertices ? String(this.state.t) : "1";
  }
}
