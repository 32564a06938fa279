// The profile view: the profile polyline (u right, v up) and the trajectory seen end-on as a dot.
// Points are the job's [profile].points; the dot sits at -offset, so dragging it sets [profile].offset.

import { along, bounds, editorView, errorPoint, fmt, hintHeight, markError, nearestHandle, nearestSegment } from "./view2d.js";
import { PointTable } from "./table.js";
import { ProfileTools } from "./generators.js";

export const BAND_FILL = "rgba(46, 164, 78, 0.13)", BAND_EDGE = "#2da44e";

export class ProfileView {
  constructor(studio, section) {
    this.studio = studio;
    this.section = section;
    this.selected = -1;
    this.view = editorView(this, section, studio);
    section.querySelector(".fit").addEventListener("click", () => { this.view.auto = true; this.fit(); });
    this.tools = new ProfileTools(this);
    this.hint = section.querySelector(".hint");
    this.errorBox = section.querySelector(".error");
    this.table = new PointTable(section.querySelector("#profile-points"), ["u", "v"], {
      change: (i, values) => { this.editable()[i] = values; studio.edit(); this.view.draw(); },
      remove: (i) => this.remove(i),
      select: (i) => { this.selected = i; this.view.draw(); },
      commit: () => studio.commit(),
    });
  }

  points() { return this.studio.profilePoints(); }

  offset() { return this.studio.job.profile.offset || [0, 0]; }

  /** The job's point list, made from the drawn points first when the profile came from an SVG file. */
  editable() { return this.studio.editableProfile(); }

  handleAt(e) {
    const r = this.view.canvas.getBoundingClientRect();
    return nearestHandle(this.view, this.points(), e.clientX - r.left, e.clientY - r.top);
  }

  /** What a press at (sx, sy) grabs (``press``: it is one, not a hover). */
  hit(sx, sy, press) {
    const [ou, ov] = this.offset();
    const [dx, dy] = this.view.toScreen(-ou, -ov);
    const i = nearestHandle(this.view, this.points(), sx, sy);
    if (i >= 0) {
      if (press) {
        this.selected = i;
        this.view.draw();
      }
      return { point: i };
    }
    if (Math.hypot(dx - sx, dy - sy) <= 10) return { dot: true };
    return null;
  }

  drag(target, world) {
    const [x, y] = this.studio.snapped(world);
    if (target.dot) {
      const [u, v] = this.offset();
      if (u === -x && v === -y) return;   // snapped to where it was: nothing to rebuild
      this.studio.job.profile.offset = [-x + 0, -y + 0];
      this.studio.syncControls();
    } else {
      const [u, v] = this.points()[target.point];
      if (u === x && v === y) return;
      this.editable()[target.point] = [x, y];
    }
    this.studio.edit();
    this.render();
  }

  /** Double-click: on a segment, a point on it (the design does not change); elsewhere, a new end. */
  add(world) {
    const points = this.editable();
    const [sx, sy] = this.view.toScreen(...world);
    if (nearestHandle(this.view, points, sx, sy) >= 0) return;   // on a point: nothing to add
    const seg = nearestSegment(this.view, points, sx, sy);
    let at, p;
    if (seg) {
      at = seg.index + 1;
      p = along(points[seg.index], points[at], seg.t);
    } else {
      p = this.studio.snapped(world);
      const d0 = Math.hypot(points[0][0] - p[0], points[0][1] - p[1]);
      const d1 = Math.hypot(points.at(-1)[0] - p[0], points.at(-1)[1] - p[1]);
      at = d0 < d1 ? 0 : points.length;
    }
    points.splice(at, 0, p);
    this.selected = at;
    this.studio.edit();
    this.studio.commit();
    this.render();
  }

  remove(i) {
    if (i < 0) return;
    this.editable().splice(i, 1);
    this.selected = -1;
    this.studio.edit();
    this.studio.commit();
    this.render();
  }

  /** Pixels covered at the top (the axis label) and bottom (the hint, and the error box at its
   * tallest, so that an error never hides the lowest points). */
  insets() {
    const error = getComputedStyle(this.errorBox);
    const errorRoom = parseFloat(error.bottom) + parseFloat(error.maxHeight) + 2 * parseFloat(error.paddingTop) + 2;
    return { top: 18, bottom: Math.max(hintHeight(this.view.canvas), errorRoom || 0) + 4 };
  }

  fit() {
    if (!this.studio.job) return;
    const [ou, ov] = this.offset();
    const box = bounds([...this.points(), [-ou, -ov]]);
    if (box) this.view.fit(box, 0.1);
  }

  render() {
    if (!this.view.fitted) this.fit();
    this.view.draw();
    this.table.update(this.points(), this.selected, this.errorPoint());
  }

  errorPoint() {
    return errorPoint(this.studio, "profile");
  }

  /** The region where points may go (the server's polygon, offset included), or null. */
  band() {
    const { error, shown } = this.studio;
    return (error ? error.feasible : shown && shown.feasible) || null;
  }

  /** Shade the region where points may go: the same rule as the "meets ... before ..." error. */
  drawBand(view, ctx, [ou, ov]) {
    const band = this.band();
    if (!band || band.length < 3) return;
    view.path(ctx, band.map(([u, v]) => [u - ou, v - ov]), true);
    ctx.fillStyle = BAND_FILL;
    ctx.fill();
    ctx.save();
    ctx.setLineDash([4, 3]);
    ctx.strokeStyle = BAND_EDGE;
    ctx.lineWidth = 1;
    ctx.stroke();
    ctx.restore();
  }

  draw(view, ctx) {
    view.drawGrid(ctx);
    if (!this.studio.job) return;
    const points = this.points();
    const [ou, ov] = this.offset();
    this.drawBand(view, ctx, [ou, ov]);
    const [dx, dy] = view.toScreen(-ou, -ov);
    // The trajectory's level (v = 0) and line (u = 0), then the trajectory itself, end-on.
    ctx.save();
    ctx.setLineDash([5, 4]);
    ctx.strokeStyle = "#8fb3de";
    ctx.beginPath();
    ctx.moveTo(dx, 0); ctx.lineTo(dx, view.height);
    ctx.moveTo(0, dy); ctx.lineTo(view.width, dy);
    ctx.stroke();
    ctx.restore();
    ctx.fillStyle = "#57606a";
    ctx.font = "11px system-ui, sans-serif";
    // u's label right-aligned just above the hint line, so the two never overlap
    const label = "u →  (right of travel)", width = ctx.measureText(label).width;
    const y = Math.min(view.height, this.hint.offsetTop) - 5;
    ctx.fillText(label, view.width - width - 8, y);
    this.uLabel = { x: view.width - width - 8, y: y - 11, w: width, h: 13 };
    ctx.fillText("v ↑", 8, 16);
    if (points.length) {
      ctx.lineWidth = 2;
      ctx.strokeStyle = this.studio.error && this.studio.error.cause && this.studio.error.cause.view === "profile" ? "#c62828" : "#24292f";
      view.path(ctx, points);
      ctx.stroke();
      const small = points.length > 150;
      points.forEach(([x, y], i) => {
        const [sx, sy] = view.toScreen(x, y);
        const r = small ? 2 : 4;
        ctx.fillStyle = i === this.selected ? "#1f6feb" : "#fff";
        ctx.strokeStyle = "#24292f";
        ctx.lineWidth = 1.2;
        ctx.fillRect(sx - r, sy - r, 2 * r, 2 * r);
        ctx.strokeRect(sx - r, sy - r, 2 * r, 2 * r);
      });
      markError(view, ctx, points, this.errorPoint());
      if (this.selected >= 0 && this.selected < points.length) {
        const [x, y] = points[this.selected];
        const [sx, sy] = view.toScreen(x, y);
        ctx.fillStyle = "#1f6feb";
        ctx.fillText(`point ${this.selected}: (${fmt(x)}, ${fmt(y)})`, sx + 8, sy - 8);
      }
    }
    ctx.fillStyle = "#1f6feb";
    ctx.beginPath(); ctx.arc(dx, dy, 6, 0, 2 * Math.PI); ctx.fill();
    ctx.strokeStyle = "#fff"; ctx.lineWidth = 2; ctx.stroke();
    ctx.fillText("trajectory", dx + 9, dy + 14);
  }
}
