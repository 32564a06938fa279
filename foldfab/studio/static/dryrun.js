// The dry run's stroke order: a step slider (and play button) over the program's strokes as the
// server read them back from the program (programs/interpret), in the order the device draws
// them.  At step k the strokes before k are drawn in their layer's colour, stroke k thick in
// orange with the pen-up move that leads to it dashed, and the strokes still to come faint.

const COLOURS = { valley: "#1e63d6", mountain: "#e53935", cut: "#000000" };
const OTHER = "#8e44ad";
const CURRENT = "#ff8c00";
const TO_COME = "#d6dae0";
const PLAY_MS = 60;           // a step per frame interval while playing

export class DryRun {
  constructor(studio) {
    this.studio = studio;
    this.strokes = null;
    this.sheet = [1, 1];
    this.timer = null;
  }

  /** Show the stroke slider for a /api/preview answer above its SVG in ``body``. */
  show(answer, body) {
    this.stop();
    const s = answer.strokes;
    this.sheet = answer.sheet;
    this.strokes = s;
    const count = s.starts.length - 1;
    const wrap = document.createElement("div");
    wrap.id = "dryrun";
    wrap.innerHTML = `
      <div class="dryrun-controls">
        <button id="dryrun-play" title="Play the strokes in the order the device draws them">play</button>
        <input type="range" id="dryrun-step" min="0" max="${Math.max(count - 1, 0)}" value="0" ${count ? "" : "disabled"}>
        <span id="dryrun-info"></span>
      </div>
      <canvas id="dryrun-canvas" aria-label="stroke order"></canvas>`;
    body.prepend(wrap);
    this.canvas = wrap.querySelector("canvas");
    this.slider = wrap.querySelector("#dryrun-step");
    this.slider.addEventListener("input", () => { this.stop(); this.draw(); });
    wrap.querySelector("#dryrun-play").addEventListener("click", () => (this.timer ? this.stop() : this.play()));
    if (s.omitted) wrap.querySelector("#dryrun-info").textContent = s.omitted;
    requestAnimationFrame(() => this.draw());
  }

  play() {
    if (+this.slider.value >= +this.slider.max) this.slider.value = 0;
    document.querySelector("#dryrun-play").textContent = "pause";
    this.timer = setInterval(() => {
      this.slider.value = +this.slider.value + 1;
      if (+this.slider.value >= +this.slider.max) this.stop();
      this.draw();
    }, PLAY_MS);
  }

  stop() {
    if (this.timer) clearInterval(this.timer);
    this.timer = null;
    const button = document.querySelector("#dryrun-play");
    if (button) button.textContent = "play";
  }

  /** Canvas pixels (CSS) of a sheet point (mm, y down). */
  toCanvas(x, y) { return [this.pad + x * this.scale, this.pad + y * this.scale]; }

  /** Page coordinates of a sheet point (for tests and tools). */
  toPage(x, y) {
    const r = this.canvas.getBoundingClientRect(), [cx, cy] = this.toCanvas(x, y);
    return [r.left + cx, r.top + cy];
  }

  /** The points of stroke ``k`` as [x, y] pairs (sheet mm). */
  stroke(k) {
    const s = this.strokes, out = [];
    for (let i = s.starts[k]; i < s.starts[k + 1]; i++) out.push([s.points[2 * i], s.points[2 * i + 1]]);
    return out;
  }

  draw() {
    const s = this.strokes, canvas = this.canvas;
    if (!s || !canvas.isConnected) return;
    const dpr = window.devicePixelRatio || 1;
    const width = Math.max(200, canvas.parentElement.clientWidth);
    this.pad = 8;
    this.scale = (width - 2 * this.pad) / this.sheet[0];
    const height = this.sheet[1] * this.scale + 2 * this.pad;
    canvas.style.width = `${width}px`;
    canvas.style.height = `${height}px`;
    canvas.width = Math.round(width * dpr);
    canvas.height = Math.round(height * dpr);
    const ctx = canvas.getContext("2d");
    ctx.setTransform(dpr, 0, 0, dpr, 0, 0);
    ctx.fillStyle = "#fff";
    ctx.fillRect(0, 0, width, height);
    ctx.strokeStyle = "#8c959f";
    ctx.lineWidth = 1;
    ctx.strokeRect(this.pad, this.pad, this.sheet[0] * this.scale, this.sheet[1] * this.scale);
    const count = s.starts.length - 1;
    const k = Math.min(+this.slider.value, count - 1);
    const line = (points, colour, widthPx) => {
      ctx.beginPath();
      points.forEach(([x, y], i) => { const [cx, cy] = this.toCanvas(x, y); if (i) ctx.lineTo(cx, cy); else ctx.moveTo(cx, cy); });
      if (points.length === 1) { const [cx, cy] = this.toCanvas(...points[0]); ctx.lineTo(cx + 0.5, cy); }
      ctx.strokeStyle = colour;
      ctx.lineWidth = widthPx;
      ctx.stroke();
    };
    ctx.lineCap = "round";
    ctx.lineJoin = "round";
    for (let i = k + 1; i < count; i++) line(this.stroke(i), TO_COME, 1);
    for (let i = 0; i < k; i++) line(this.stroke(i), COLOURS[s.layers[s.layer[i]]] || OTHER, 1.4);
    if (k < 0) return;
    const current = this.stroke(k);
    if (k > 0) {
      ctx.setLineDash([4, 4]);
      line([this.stroke(k - 1).at(-1), current[0]], CURRENT, 1);
      ctx.setLineDash([]);
    }
    line(current, CURRENT, 3.5);
    const info = document.querySelector("#dryrun-info");
    info.textContent = `stroke ${k + 1} of ${count} · ${s.layers[s.layer[k]]}`;
    document.body.dataset.dryrunStep = String(k);
  }
}
