// A 2D canvas view in millimetres (y up): pan, zoom, grid, hit-testing and dragging of handles.

const DPR = () => window.devicePixelRatio || 1;

export class View2D {
  /**
   * @param {HTMLCanvasElement} canvas
   * @param {{draw: (view: View2D, ctx: CanvasRenderingContext2D) => void,
   *          hit?: (sx: number, sy: number, press: boolean) => object | null,
   *          drag?: (target: object, world: number[], event: PointerEvent) => void,
   *          drop?: (target: object) => void,
   *          dblclick?: (world: number[], event: MouseEvent) => void,
   *          context?: (world: number[], event: MouseEvent) => void,
   *          fit?: () => void, insets?: () => {top: number, bottom: number}}} handlers
   */
  constructor(canvas, handlers) {
    this.canvas = canvas;
    this.ctx = canvas.getContext("2d");
    this.h = handlers;
    this.scale = 4;          // pixels per mm
    this.center = [0, 0];    // world point at the canvas centre
    this.width = 1;
    this.height = 1;
    this.fitted = false;
    this.auto = true;        // views may refit to new content until the user pans or zooms
    this.pending = 0;
    new ResizeObserver(() => this.resize()).observe(canvas);
    this.resize();
    this.bindPointer();
  }

  /** The canvas changed size: a view that follows its content (``auto``) fits it again. */
  resize() {
    const r = this.canvas.getBoundingClientRect();
    this.width = Math.max(1, r.width);
    this.height = Math.max(1, r.height);
    this.canvas.width = Math.round(this.width * DPR());
    this.canvas.height = Math.round(this.height * DPR());
    if (this.auto && this.fitted && this.h.fit) this.h.fit(); else this.draw();
  }

  toScreen(x, y) {
    return [(x - this.center[0]) * this.scale + this.width / 2, this.height / 2 - (y - this.center[1]) * this.scale];
  }

  toWorld(sx, sy) {
    return [(sx - this.width / 2) / this.scale + this.center[0], (this.height / 2 - sy) / this.scale + this.center[1]];
  }

  /** Page coordinates of a world point (for tests and tools). */
  toPage(x, y) {
    const r = this.canvas.getBoundingClientRect();
    const [sx, sy] = this.toScreen(x, y);
    return [r.left + sx, r.top + sy];
  }

  /** Show the box [x0, y0, x1, y1] with a margin, clear of what covers the canvas (``insets``, px). */
  fit(box, margin = 0.12) {
    const w = Math.max(box[2] - box[0], 1e-6), h = Math.max(box[3] - box[1], 1e-6);
    const { top, bottom } = this.h.insets ? this.h.insets() : { top: 0, bottom: hintHeight(this.canvas) };
    const free = Math.max(this.height - top - bottom, 0.3 * this.height);
    this.scale = Math.min(this.width * (1 - 2 * margin) / w, free * (1 - 2 * margin) / h);
    if (!isFinite(this.scale) || this.scale <= 0) this.scale = 1;
    this.center = [(box[0] + box[2]) / 2, (box[1] + box[3]) / 2 + (top - bottom) / 2 / this.scale];   // mid free part
    this.fitted = true;
    this.draw();
  }

  /** Refit (while ``auto``) when the box leaves the view or shrinks to a small part of it. */
  keepInView(box) {
    const m = 0.05 * Math.min(this.width, this.height);
    const [x0, y1] = this.toWorld(m, m), [x1, y0] = this.toWorld(this.width - m, this.height - m);
    const outside = box[0] < x0 || box[1] < y0 || box[2] > x1 || box[3] > y1;
    const small = box[2] - box[0] < 0.3 * (x1 - x0) && box[3] - box[1] < 0.3 * (y1 - y0);
    if (this.auto && (outside || small)) this.fit(box, 0.12);
  }

  /** Redraw now. */
  draw() {
    const ctx = this.ctx;
    ctx.setTransform(DPR(), 0, 0, DPR(), 0, 0);
    ctx.clearRect(0, 0, this.width, this.height);
    this.h.draw(this, ctx);
  }

  /** Redraw at the next frame (pan, zoom). */
  drawSoon() {
    if (this.pending) return;
    this.pending = requestAnimationFrame(() => { this.pending = 0; this.draw(); });
  }

  /** Grid lines every 1, 2 or 5 x 10^n mm (at least 12 px apart), major lines every fifth or tenth. */
  drawGrid(ctx) {
    const minor = niceStep(12 / this.scale);
    const major = minor * (String(minor).includes("2") ? 5 : 10);
    const m = 0.05 * Math.min(this.width, this.height);
    const [x0, y1] = this.toWorld(m, m), [x1, y0] = this.toWorld(this.width - m, this.height - m);
    for (const [step, colour] of [[minor, "#f0f2f4"], [major, "#dde1e6"]]) {
      ctx.beginPath();
      for (let x = Math.ceil(x0 / step) * step; x <= x1; x += step) {
        const sx = Math.round(this.toScreen(x, 0)[0]) + 0.5;
        ctx.moveTo(sx, 0); ctx.lineTo(sx, this.height);
      }
      for (let y = Math.ceil(y0 / step) * step; y <= y1; y += step) {
        const sy = Math.round(this.toScreen(0, y)[1]) + 0.5;
        ctx.moveTo(0, sy); ctx.lineTo(this.width, sy);
      }
      ctx.strokeStyle = colour;
      ctx.lineWidth = 1;
      ctx.stroke();
    }
    ctx.fillStyle = "#8c959f";
    ctx.font = "10px system-ui, sans-serif";
    ctx.fillText(`grid ${fmt(minor)} mm`, this.width - 70, 12);
    return minor;
  }

  /** Polyline through world points (array of [x, y]). */
  path(ctx, points, closed = false) {
    ctx.beginPath();
    points.forEach(([x, y], i) => {
      const [sx, sy] = this.toScreen(x, y);
      if (i) ctx.lineTo(sx, sy); else ctx.moveTo(sx, sy);
    });
    if (closed) ctx.closePath();
  }

  bindPointer() {
    const c = this.canvas;
    let drag = null;      // {target} or {pan: [sx, sy, cx, cy]}
    const local = (e) => { const r = c.getBoundingClientRect(); return [e.clientX - r.left, e.clientY - r.top]; };
    c.addEventListener("pointerdown", (e) => {
      if (e.button === 2) return;
      c.focus();
      const [sx, sy] = local(e);
      const target = e.button === 0 && !e.shiftKey && this.h.hit ? this.h.hit(sx, sy, true) : null;
      drag = target ? { target } : { pan: [sx, sy, ...this.center] };
      if (!target) this.auto = false;
      c.setPointerCapture(e.pointerId);
      e.preventDefault();
    });
    c.addEventListener("pointermove", (e) => {
      if (!drag) {
        const [sx, sy] = local(e);
        c.style.cursor = this.h.hit && this.h.hit(sx, sy, false) ? "grab" : "crosshair";
        return;
      }
      const [sx, sy] = local(e);
      if (drag.target) {
        this.h.drag(drag.target, this.toWorld(sx, sy), e);
      } else {
        const [px, py, cx, cy] = drag.pan;
        this.center = [cx - (sx - px) / this.scale, cy + (sy - py) / this.scale];
        this.drawSoon();
      }
    });
    const end = (e) => {
      if (drag && drag.target && this.h.drop) this.h.drop(drag.target);
      drag = null;
      if (c.hasPointerCapture(e.pointerId)) c.releasePointerCapture(e.pointerId);
    };
    c.addEventListener("pointerup", end);
    c.addEventListener("pointercancel", end);
    c.addEventListener("wheel", (e) => {
      e.preventDefault();
      this.auto = false;
      const [sx, sy] = local(e);
      const before = this.toWorld(sx, sy);
      this.scale *= Math.exp(-e.deltaY * 0.0015);
      const after = this.toWorld(sx, sy);
      this.center = [this.center[0] + before[0] - after[0], this.center[1] + before[1] - after[1]];
      this.drawSoon();
    }, { passive: false });
    c.addEventListener("dblclick", (e) => { if (this.h.dblclick) this.h.dblclick(this.toWorld(...local(e)), e); });
    c.addEventListener("contextmenu", (e) => {
      e.preventDefault();
      if (this.h.context) this.h.context(this.toWorld(...local(e)), e);
    });
  }
}

/** Pixels the hint line (if any) covers at the bottom of ``canvas``'s wrapper. */
export function hintHeight(canvas) {
  const hint = canvas.parentElement && canvas.parentElement.querySelector(".hint");
  return hint ? Math.max(0, canvas.parentElement.clientHeight - hint.offsetTop) : 0;
}

export function niceStep(raw) {
  const p = Math.pow(10, Math.floor(Math.log10(raw)));
  for (const m of [1, 2, 5, 10]) if (m * p >= raw) return m * p;
  return 10 * p;
}

export function fmt(x, digits = 3) {
  return Number.isFinite(x) ? String(+x.toFixed(digits)) : "–";
}

/** Index of the handle within `radius` px of screen point (sx, sy), or -1. */
export function nearestHandle(view, points, sx, sy, radius = 9) {
  let best = -1, bestD = radius * radius;
  points.forEach(([x, y], i) => {
    const [px, py] = view.toScreen(x, y);
    const d = (px - sx) ** 2 + (py - sy) ** 2;
    if (d <= bestD) { best = i; bestD = d; }
  });
  return best;
}

/**
 * The segment (i, i+1) within `radius` px of screen point (sx, sy): {index, t} with the point at
 * points[i] + t (points[i+1] - points[i]), or null.
 */
export function nearestSegment(view, points, sx, sy, radius = 10) {
  let best = null, bestD = radius;
  for (let i = 0; i + 1 < points.length; i++) {
    const a = view.toScreen(points[i][0], points[i][1]), b = view.toScreen(points[i + 1][0], points[i + 1][1]);
    const dx = b[0] - a[0], dy = b[1] - a[1];
    const t = Math.max(0, Math.min(1, ((sx - a[0]) * dx + (sy - a[1]) * dy) / (dx * dx + dy * dy || 1)));
    const d = Math.hypot(a[0] + t * dx - sx, a[1] + t * dy - sy);
    if (d <= bestD) { best = { index: i, t }; bestD = d; }
  }
  return best;
}

/** The point at parameter t of the segment a-b (any dimension): on the line, so it adds no turn. */
export function along(a, b, t) {
  return a.map((value, k) => value + t * (b[k] - value));
}

/** Bounding box [x0, y0, x1, y1] of [x, y] points (or null). */
export function bounds(points) {
  if (!points.length) return null;
  const box = [Infinity, Infinity, -Infinity, -Infinity];
  for (const [x, y] of points) {
    box[0] = Math.min(box[0], x); box[1] = Math.min(box[1], y);
    box[2] = Math.max(box[2], x); box[3] = Math.max(box[3], y);
  }
  return box;
}


/** The index of the point the studio's error blames in view ``name`` ("profile",
 * "trajectory"), or -1. */
export function errorPoint(studio, name) {
  const cause = studio.error && studio.error.cause;
  return cause && cause.view === name && cause.point !== undefined ? cause.point : -1;
}

/** A red ring round point ``index`` of ``points`` (world coordinates), where the studio's
 * error points; nothing for -1 or an index past the end. */
export function markError(view, ctx, points, index) {
  if (index < 0 || index >= points.length) return;
  const [sx, sy] = view.toScreen(...points[index]);
  ctx.strokeStyle = "#c62828";
  ctx.lineWidth = 2.5;
  ctx.beginPath(); ctx.arc(sx, sy, 10, 0, 2 * Math.PI); ctx.stroke();
}

/**
 * The canvas of a point editor (profile or trajectory): drag, drop, double-click to add,
 * right-click or Delete to remove.  ``editor`` provides draw, hit, drag, add, remove,
 * handleAt and ``selected``; ``onKey`` handles the editor's own extra keys.
 */
export function editorView(editor, section, studio, onKey = () => {}) {
  const view = new View2D(section.querySelector("canvas"), {
    fit: () => editor.fit(),
    insets: editor.insets ? () => editor.insets() : undefined,
    draw: (view, ctx) => editor.draw(view, ctx),
    hit: (sx, sy, press) => editor.hit(sx, sy, press),
    drag: (target, world) => editor.drag(target, world),
    drop: () => studio.commit(),
    dblclick: (world) => editor.add(world),
    context: (world, e) => editor.remove(editor.handleAt(e)),
  });
  view.canvas.addEventListener("keydown", (e) => {
    if ((e.key === "Delete" || e.key === "Backspace") && editor.selected >= 0) { e.preventDefault(); editor.remove(editor.selected); }
    onKey(e);
  });
  return view;
}
