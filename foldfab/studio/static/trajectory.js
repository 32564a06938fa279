// The trajectory view, seen from above: templates with their parameters, or a free polyline;
// the reflection planes dashed, the line elements' paths in grey, the start and travel direction.

import { along, bounds, editorView, errorPoint, markError, nearestHandle, nearestSegment } from "./view2d.js";
import { PointTable } from "./table.js";
import { keepValid } from "./keepvalid.js";

const PARAMS = {
  regular: [["corners", "corners", 4, 40, 2], ["radius", "radius", 5, 300, 0.5]],   // odd corners cannot close
  star: [["points", "points", 2, 20, 1], ["outer_radius", "outer r", 5, 300, 0.5], ["inner_radius", "inner r", 5, 300, 0.5]],
};
const MAX_PATHS = 48;

export class TrajectoryView {
  constructor(studio, section) {
    this.studio = studio;
    this.section = section;
    this.selected = -1;
    this.template = section.querySelector("#template");
    this.params = section.querySelector("#template-params");
    this.view = editorView(this, section, studio, (e) => {
      if (e.key === "Escape" && this.drawing) this.stopDrawing();
    });
    this.template.addEventListener("change", () => this.setTemplate(this.template.value));
    section.querySelector("#to-polyline").addEventListener("click", () => this.setTemplate("polyline"));
    this.drawButton = section.querySelector("#draw");
    this.drawButton.addEventListener("click", () => (this.drawing ? this.stopDrawing() : this.startDrawing()));
    this.drawing = false;
    section.querySelector(".fit").addEventListener("click", () => { this.view.auto = true; this.fit(); });
    this.table = new PointTable(section.querySelector("#trajectory-points"), ["x", "y", "z"], {
      change: (i, values) => { this.move(i, values); this.view.draw(); },
      remove: (i) => this.remove(i),
      select: (i) => { this.selected = i; this.view.draw(); },
      commit: () => studio.commit(),
    });
  }

  spec() { return this.studio.job.trajectory; }

  isPolyline() { return Array.isArray(this.spec().points); }

  points() { return this.studio.trajectoryPoints(); }

  closed(points = this.points()) {
    if (points.length < 3) return false;
    const a = points[0], b = points.at(-1);
    return a.every((v, k) => v === b[k]);
  }

  /** Build the parameter controls of the current template (sliders with number fields). */
  syncControls() {
    const spec = this.spec();
    if (this.drawing && !this.isPolyline()) {   // another file or template: drawing is over
      this.drawing = false;
      this.drawButton.classList.remove("active");
      this.drawButton.textContent = "draw new";
    }
    this.template.value = spec.template;
    this.section.querySelector("#to-polyline").hidden = spec.template === "polyline";
    this.params.innerHTML = "";
    if (spec.template === "polyline") {
      if (!this.isPolyline()) return;
      const label = document.createElement("label");
      label.className = "param";
      label.innerHTML = `<input type="checkbox" id="closed"> closed`;
      const box = label.firstChild;
      box.checked = this.closed();
      box.addEventListener("change", () => this.setClosed(box.checked));
      this.params.appendChild(label);
      return;
    }
    for (const [key, name, low, high, step] of PARAMS[spec.template]) {
      const label = document.createElement("label");
      label.className = "param";
      label.innerHTML = `${name} <input type="range" min="${low}" max="${high}" step="${step}" data-field="trajectory.${key}">` +
        `<input type="number" step="${Number.isInteger(step) ? 1 : "any"}" data-field="trajectory.${key}" id="param-${key}">`;
      const [range, number] = label.querySelectorAll("input");
      range.value = number.value = spec[key];
      const integer = Number.isInteger(step);
      const set = (source, other) => {
        const value = integer ? Number(source.value) : parseFloat(source.value);
        const ok = Number.isFinite(value) && (!integer || Number.isInteger(value));
        source.classList.toggle("invalid", !ok);
        if (!ok) return;
        other.value = value;
        const fitted = this.lastFit && this.lastFit.template === spec.template ? this.lastFit : spec;
        const previous = fitted[key];   // the last value that was known to fit
        spec[key] = value;
        keepValid(this, key, previous);
      };
      range.addEventListener("input", () => set(range, number));
      number.addEventListener("input", () => set(number, range));
      range.addEventListener("change", () => this.studio.commit());
      number.addEventListener("change", () => this.studio.commit());
      this.params.appendChild(label);
    }
  }

  /** Switch template, carrying the size over; "polyline" takes the drawn trajectory's points. */
  setTemplate(template) {
    const job = this.studio.job;
    const old = job.trajectory;
    const points = this.points();
    const radius = old.radius || old.outer_radius ||
      Math.max(10, ...points.map(([x, y]) => Math.hypot(x, y)));
    if (template === "polyline") {
      if (!points.length) return;
      job.trajectory = { template, points: points.map((p) => [...p]) };
    } else if (template === "regular") {
      job.trajectory = { template, corners: old.corners || (old.points > 1 ? 2 * old.points : 6), radius: +radius.toFixed(3) };
    } else {
      job.trajectory = { template, points: Math.max(2, Math.round((old.corners || 8) / 2)),
                         outer_radius: +radius.toFixed(3), inner_radius: +(0.7 * radius).toFixed(3) };
    }
    this.selected = -1;
    this.syncControls();
    if (template === "polyline") this.studio.edit(); else keepValid(this, "template");
    this.studio.commit();
    this.render();
  }

  setClosed(closed) {
    const points = this.spec().points;
    if (closed && !this.closed(points)) points.push([...points[0]]);
    if (!closed && this.closed(points)) points.pop();
    this.studio.edit();
    this.studio.commit();
    this.render();
  }

  handleAt(e) {
    if (!this.isPolyline()) return -1;
    const r = this.view.canvas.getBoundingClientRect();
    return this.handle(e.clientX - r.left, e.clientY - r.top);
  }

  handle(sx, sy) {
    const points = this.points();
    const handles = this.closed(points) ? points.slice(0, -1) : points;
    return nearestHandle(this.view, handles, sx, sy);
  }

  /** Draw mode: every click on the view places the next point (and can drag it at once). */
  startDrawing() {
    this.studio.job.trajectory = { template: "polyline", points: [] };
    this.drawing = true;
    this.selected = -1;
    this.drawButton.classList.add("active");
    this.drawButton.textContent = "drawing… (Esc ends)";
    this.syncControls();
    this.view.canvas.focus();
    this.render();
  }

  stopDrawing() {
    this.drawing = false;
    this.drawButton.classList.remove("active");
    this.drawButton.textContent = "draw new";
    this.syncControls();
    this.studio.commit();
  }

  place(sx, sy) {
    const points = this.spec().points;
    if (points.length >= 3 && nearestHandle(this.view, [points[0]], sx, sy) === 0) {
      points.push([...points[0]]);        // back at the start: closed, and done
      this.stopDrawing();
      this.studio.edit();
      this.render();
      return null;
    }
    if (points.length && nearestHandle(this.view, [points.at(-1)], sx, sy) === 0) {
      this.stopDrawing();                 // the last point again (or a double-click): done
      this.studio.edit();
      return null;
    }
    points.push(this.studio.snapped(this.view.toWorld(sx, sy)));
    this.selected = points.length - 1;
    if (points.length >= 2) this.studio.edit();   // one point is no trajectory yet: no error while drawing
    this.render();
    return { point: this.selected };
  }

  /** What a press at (sx, sy) grabs (``press``: it is one, not a hover). */
  hit(sx, sy, press) {
    if (this.drawing) return press ? this.place(sx, sy) : { draw: true };
    if (!this.isPolyline()) return null;
    const i = this.handle(sx, sy);
    if (i < 0) return null;
    if (press) {
      this.selected = i;
      this.view.draw();
    }
    return { point: i };
  }

  /** Move point i to (x, y[, z]); the closing point of a closed polyline follows point 0. */
  move(i, values) {
    const points = this.spec().points;
    const closed = this.closed(points);
    const point = [...values, ...points[i].slice(values.length)];
    points[i] = point;
    if (closed && i === 0) points[points.length - 1] = [...point];
    if (closed && i === points.length - 1) points[0] = [...point];
    this.studio.edit();
  }

  drag(target, world) {
    const [x, y] = this.studio.snapped(world);
    const [px, py] = this.spec().points[target.point];
    if (x === px && y === py) return;
    this.move(target.point, [x, y]);
    this.render();
  }

  /** Double-click: on a segment, a point on it (the design does not change); elsewhere, a new end. */
  add(world) {
    if (!this.isPolyline()) return;
    const points = this.spec().points;
    const [sx, sy] = this.view.toScreen(...world);
    if (nearestHandle(this.view, points, sx, sy) >= 0) return;   // on a point: nothing to add
    const seg = nearestSegment(this.view, points, sx, sy);
    let at;
    if (seg) {
      at = seg.index + 1;
      points.splice(at, 0, along(points[seg.index], points[at], seg.t));
    } else if (!this.closed(points)) {
      const d0 = Math.hypot(points[0][0] - world[0], points[0][1] - world[1]);
      const d1 = Math.hypot(points.at(-1)[0] - world[0], points.at(-1)[1] - world[1]);
      at = d0 < d1 ? 0 : points.length;
      const end = points[at === 0 ? 0 : points.length - 1];
      points.splice(at, 0, [...this.studio.snapped(world), ...end.slice(2)]);   // a 3D path keeps its end's height
    } else {
      return;
    }
    this.selected = at;
    this.studio.edit();
    this.studio.commit();
    this.render();
  }

  remove(i) {
    if (i < 0 || !this.isPolyline()) return;
    const points = this.spec().points;
    const closed = this.closed(points);
    points.splice(i, 1);
    if (closed && i === 0) points[points.length - 1] = [...points[0]];
    this.selected = -1;
    this.studio.edit();
    this.studio.commit();
    this.render();
  }

  /** The trajectory and, when shown, the line elements' paths around it (they reach past it). */
  box() {
    const box = bounds(this.points());
    const shown = this.studio.shown;
    if (!box || !shown || this.studio.error) return box;
    const p = shown.paths;
    for (let i = 0; i < p.length; i += 3) {
      box[0] = Math.min(box[0], p[i]); box[2] = Math.max(box[2], p[i]);
      box[1] = Math.min(box[1], p[i + 1]); box[3] = Math.max(box[3], p[i + 1]);
    }
    return box;
  }

  fit() {
    const box = this.box();
    if (box) this.view.fit(box, 0.08);
  }

  render() {
    // A template that outgrows the view (or shrinks in it) is refitted; a polyline being edited stays put.
    const box = this.box();
    if (!this.view.fitted) this.fit();
    else if (box && !this.isPolyline()) this.view.keepInView(box);
    this.view.draw();
    this.table.update(this.points(), this.selected, this.errorPoint(), this.isPolyline());
  }

  errorPoint() {
    return errorPoint(this.studio, "trajectory");
  }

  draw(view, ctx) {
    view.drawGrid(ctx);
    if (!this.studio.job) return;
    const shown = this.studio.shown;
    const failing = this.studio.error !== null;
    if (shown) {
      ctx.globalAlpha = failing || this.drawing ? 0.35 : 1;
      this.drawPaths(view, ctx, shown);
      this.drawPlanes(view, ctx, shown);
      if (failing) {
        ctx.strokeStyle = "#8c959f";
        ctx.lineWidth = 2;
        view.path(ctx, shown.trajectoryPoints);
        ctx.stroke();
      }
      ctx.globalAlpha = 1;
    }
    const points = this.points();
    if (!points.length) return;
    ctx.lineWidth = 2;
    ctx.strokeStyle = failing && this.studio.error.cause && this.studio.error.cause.view === "trajectory" ? "#c62828" : "#24292f";
    view.path(ctx, points);
    ctx.stroke();
    const editable = this.isPolyline();
    const many = points.length > 120;
    points.forEach(([x, y], i) => {
      const [sx, sy] = view.toScreen(x, y);
      ctx.beginPath();
      ctx.arc(sx, sy, many ? 2 : editable ? 4.5 : 3, 0, 2 * Math.PI);
      ctx.fillStyle = i === this.selected ? "#1f6feb" : "#fff";
      ctx.fill();
      ctx.strokeStyle = "#24292f";
      ctx.lineWidth = 1.2;
      ctx.stroke();
    });
    // The start and the direction of travel (u is to its right).
    const [x0, y0] = points[0], [x1, y1] = points[1] || points[0];
    const [a, b] = view.toScreen(x0, y0);
    const len = Math.hypot(x1 - x0, y1 - y0) || 1;
    const ux = (x1 - x0) / len, uy = -(y1 - y0) / len;
    ctx.strokeStyle = ctx.fillStyle = "#2da44e";
    ctx.lineWidth = 2;
    ctx.beginPath(); ctx.arc(a, b, 6, 0, 2 * Math.PI); ctx.stroke();
    ctx.beginPath(); ctx.moveTo(a, b); ctx.lineTo(a + 28 * ux, b + 28 * uy); ctx.stroke();
    ctx.beginPath();
    ctx.moveTo(a + 34 * ux, b + 34 * uy);
    ctx.lineTo(a + 24 * ux - 5 * uy, b + 24 * uy + 5 * ux);
    ctx.lineTo(a + 24 * ux + 5 * uy, b + 24 * uy - 5 * ux);
    ctx.fill();
    ctx.font = "11px system-ui, sans-serif";
    ctx.fillText("start", a + 8, b + 16);
    markError(view, ctx, points, this.errorPoint());
  }

  drawPaths(view, ctx, shown) {
    const { paths, pathShape: [J, C] } = shown;
    const step = Math.max(1, Math.ceil(J / MAX_PATHS));
    ctx.lineWidth = 1;
    ctx.strokeStyle = "#c4c9d0";
    ctx.beginPath();
    for (let j = 0; j < J; j += step) {
      for (let k = 0; k < C; k++) {
        const o = (j * C + k) * 3;
        const [sx, sy] = view.toScreen(paths[o], paths[o + 1]);
        if (k) ctx.lineTo(sx, sy); else ctx.moveTo(sx, sy);
      }
    }
    ctx.stroke();
  }

  drawPlanes(view, ctx, shown) {
    const planes = shown.planes;
    const count = planes.length / 6;
    const box = bounds(shown.trajectoryPoints);
    const reach = box ? 0.6 * Math.max(box[2] - box[0], box[3] - box[1], 10) : 50;
    ctx.save();
    ctx.setLineDash([6, 4]);
    ctx.lineWidth = 1;
    for (let k = 0; k < count; k++) {
      const [px, py, , nx, ny] = planes.subarray(6 * k, 6 * k + 5);
      const n = Math.hypot(nx, ny);
      if (n < 1e-9) continue;
      const dx = -ny / n, dy = nx / n;
      const ends = k === 0 || k === count - 1;
      ctx.strokeStyle = ends ? "#2da44e" : "#6e7781";
      view.path(ctx, [[px - reach * dx, py - reach * dy], [px + reach * dx, py + reach * dy]]);
      ctx.stroke();
    }
    ctx.restore();
  }
}
