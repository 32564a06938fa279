// The crease-pattern view: mountain red, valley blue, flat grey, outline black; sheet size and fit.

import { View2D, fmt } from "./view2d.js";

const STYLE = { F: ["#b0b4ba", 1], V: ["#1e63d6", 1.3], M: ["#e53935", 1.3], B: ["#000000", 1.6] };

export class CreaseView {
  constructor(studio, section) {
    this.studio = studio;
    this.section = section;
    this.info = section.querySelector("#cp-info");
    this.fitInfo = section.querySelector("#fit-info");
    this.view = new View2D(section.querySelector("canvas"), { draw: (view, ctx) => this.draw(view, ctx), fit: () => this.fit() });
    section.querySelector(".fit").addEventListener("click", () => { this.view.auto = true; this.fit(); });
  }

  fit() {
    const shown = this.studio.shown;
    if (shown) this.view.fit(shown.cpBox, 0.06);
  }

  render() {
    const shown = this.studio.shown;
    if (shown && (this.view.auto || !this.view.fitted)) this.fit(); else this.view.draw();
    if (!shown) return;
    const s = shown.summary;
    const c = s.creases;
    this.info.textContent = `sheet ${fmt(s.sheet_mm[0], 1)} × ${fmt(s.sheet_mm[1], 1)} mm · ${s.faces} faces · ` +
      ["mountain", "valley", "flat", "border"].map((k) => `${k === "border" ? "outline" : k} ${c[k].count} (${fmt(c[k].length_mm, 1)} mm)`).join(" · ");
    const fit = shown.fit;
    this.fitInfo.classList.toggle("bad", Boolean(fit && !fit.ok));
    this.fitInfo.textContent = fit ? fit.message : "choose a device (top bar) to check that the sheet fits";
    this.section.querySelector(".stale").hidden = !this.studio.error;
  }

  draw(view, ctx) {
    const shown = this.studio.shown;
    if (!shown) return;
    const v = shown.cpVertices, e = shown.edges;
    const s = view.scale, cx = view.center[0], cy = view.center[1], hw = view.width / 2, hh = view.height / 2;
    const X = (i) => (v[2 * i] - cx) * s + hw, Y = (i) => hh - (v[2 * i + 1] - cy) * s;
    const quads = shown.penetrating;
    if (quads.length) {
      ctx.fillStyle = "rgba(229, 57, 53, 0.35)";
      ctx.beginPath();
      for (let q = 0; q < quads.length; q += 4) {
        ctx.moveTo(X(quads[q]), Y(quads[q]));
        for (let k = 1; k < 4; k++) ctx.lineTo(X(quads[q + k]), Y(quads[q + k]));
        ctx.closePath();
      }
      ctx.fill();
    }
    ctx.lineCap = "round";
    for (const kind of ["F", "V", "M", "B"]) {
      const [start, count] = shown.edgeGroups[kind];
      if (!count) continue;
      ctx.beginPath();
      for (let k = start; k < start + count; k++) {
        const a = e[2 * k], b = e[2 * k + 1];
        ctx.moveTo(X(a), Y(a));
        ctx.lineTo(X(b), Y(b));
      }
      [ctx.strokeStyle, ctx.lineWidth] = STYLE[kind];
      ctx.stroke();
    }
  }
}
