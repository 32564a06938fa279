// The fabrication panel: the job's [fabrication] table (sheet, scale or fit, margin, strategy,
// media preset, split, each layer's tool settings within the device's ranges) and the printable
// template.  Every change edits studio.job.fabrication, so the design request checks it as every
// command does; once that design is drawn, the server lays it out for the chosen device as
// `foldfab export` would (/api/fabrication): the sheets (and pieces, when split) are drawn over the
// crease-pattern view and the estimate is shown here.  Until that answer arrives the view draws the
// sheet from the design answer's fit (placed as the program will place it), so the placement
// follows every edit as fast as the views do.  One such request is in flight at a time.
// Each applied answer bumps <body data-fabrication-count>.

const $ = (selector) => document.querySelector(selector);
const SHEETS = ["A4", "A4 landscape", "A3", "A3 landscape", "Letter", "Letter landscape"];
const SETTINGS = { force: "force", speed: "speed mm/s", passes: "passes", power: "power" };
const PIECE_FILL = ["rgba(46, 125, 50, 0.10)", "rgba(31, 111, 235, 0.10)"];

const fmt = (value, digits = 1) => Number(value).toFixed(digits).replace(/\.0+$/, "");

export class FabricationPanel {
  constructor(studio, root) {
    this.studio = studio;
    this.root = root;
    this.settings = null;       // /api/device for the chosen device
    this.answer = null;         // the last /api/fabrication answer
    this.inflight = false;
    this.again = false;
    this.count = 0;
    this.printAuto = true;      // the print file name follows the job's name until typed
    root.innerHTML = `
      <details id="fabrication" open>
        <summary>fabrication <span id="fab-estimate" class="estimate"></span></summary>
        <div class="fab-row">
          <label title="[fabrication].sheet (empty: the device's own sheet)">sheet
            <select id="fab-sheet" data-field="fabrication.sheet"><option value="">device's</option>
              ${SHEETS.map((s) => `<option>${s}</option>`).join("")}<option value="custom">custom</option></select></label>
          <span id="fab-custom" hidden><input type="number" id="fab-sheet-w" min="1" step="any" class="short" title="width mm">
            × <input type="number" id="fab-sheet-h" min="1" step="any" class="short" title="height mm"> mm</span>
          <label title="[fabrication].scale: 1 is the design's own size; fit: the largest that fits">scale
            <input type="number" id="fab-scale" min="0" step="any" class="short" data-field="fabrication.scale"></label>
          <label><input type="checkbox" id="fab-fit"> fit</label>
          <label title="[fabrication].margin">margin <input type="number" id="fab-margin" min="0" step="any" class="short"
            data-field="fabrication.margin"> mm</label>
          <label title="[fabrication].strategy: how creases are made">strategy
            <select id="fab-strategy" data-field="fabrication.strategy"></select></label>
          <label title="[fabrication].media: a material preset of the device">media
            <select id="fab-media" data-field="fabrication.media"><option value="">none</option></select></label>
          <label title="[fabrication].split: cut a design larger than the sheet into pieces joined by glue tabs">split
            <select id="fab-split" data-field="fabrication.split"><option value="">none</option><option value="auto">auto</option></select></label>
        </div>
        <table id="fab-layers" class="points"></table>
        <div class="fab-row">
          <label>print on <select id="print-paper"><option>A4</option><option>Letter</option><option>A3</option></select></label>
          <input id="print-path" size="18" spellcheck="false" title="Template file: .pdf, or .svg for one file per page">
          <button id="print" title="Write the printable template: the crease pattern at true size for folding by hand">print template</button>
        </div>
        <div id="fab-info" class="info"></div>
      </details>`;
    this.bind();
    this.hookCreaseView();
  }

  // --- the job's table

  table() { return this.studio.job.fabrication || (this.studio.job.fabrication = {}); }

  /** Set (or, for undefined, remove) a key of [fabrication] and rebuild the design. */
  set(key, value) {
    const table = this.table();
    if (value === undefined) delete table[key]; else table[key] = value;
    if (!Object.keys(table).length) delete this.studio.job.fabrication;
    this.studio.edit();
  }

  setTool(layer, key, value) {
    const table = this.table();
    const layers = table.layers || (table.layers = {});
    const tool = layers[layer] || (layers[layer] = {});
    if (value === undefined) delete tool[key]; else tool[key] = value;
    if (!Object.keys(tool).length) delete layers[layer];
    if (!Object.keys(layers).length) delete table.layers;
    this.set("layers", table.layers);
  }

  bind() {
    const number = (selector, assign) => {
      const el = $(selector);
      el.addEventListener("input", () => {
        const text = el.value.trim(), value = parseFloat(text);
        el.classList.toggle("invalid", text !== "" && !Number.isFinite(value));
        if (text === "" || Number.isFinite(value)) assign(text === "" ? undefined : value);
      });
      el.addEventListener("change", () => this.studio.commit());
    };
    const choice = (selector, assign) => $(selector).addEventListener("change", (e) => {
      assign(e.target.value);
      this.studio.commit();
    });
    choice("#fab-sheet", (value) => {
      $("#fab-custom").hidden = value !== "custom";
      if (value === "custom") return this.customSheet();
      this.set("sheet", value || undefined);
    });
    for (const id of ["#fab-sheet-w", "#fab-sheet-h"]) number(id, () => this.customSheet());
    number("#fab-scale", (value) => { $("#fab-fit").checked = false; this.set("scale", value); });
    $("#fab-fit").addEventListener("change", (e) => {
      this.set("scale", e.target.checked ? "fit" : parseFloat($("#fab-scale").value) || undefined);
      this.studio.commit();
    });
    number("#fab-margin", (value) => this.set("margin", value));
    choice("#fab-strategy", (value) => this.set("strategy", value || undefined));
    choice("#fab-media", (value) => this.set("media", value || undefined));
    choice("#fab-split", (value) => this.set("split", value || undefined));
    $("#device").addEventListener("change", () => this.loadDevice());
    $("#fabrication").addEventListener("toggle", () => this.refresh());
    $("#print").addEventListener("click", () => this.print());
    $("#print-path").addEventListener("input", () => { this.printAuto = false; });
    $("#job-name").addEventListener("input", () => this.printPath());
    window.addEventListener("studio:rendered", () => {
      if ($("#device").value !== (this.settings ? this.settings.device : "")) this.loadDevice(); else this.refresh();
      this.printPath();
    });
  }

  customSheet() {
    const w = parseFloat($("#fab-sheet-w").value), h = parseFloat($("#fab-sheet-h").value);
    if (Number.isFinite(w) && Number.isFinite(h)) this.set("sheet", [w, h]);
  }

  /** Show the job's table in the fields (after open, undo, save). */
  sync() {
    const t = this.studio.job.fabrication || {};
    const set = (selector, value) => { const el = $(selector); if (document.activeElement !== el) el.value = value; };
    const custom = Array.isArray(t.sheet);
    set("#fab-sheet", custom ? "custom" : t.sheet || "");
    $("#fab-custom").hidden = !custom;
    if (custom) { set("#fab-sheet-w", t.sheet[0]); set("#fab-sheet-h", t.sheet[1]); }
    $("#fab-fit").checked = t.scale === "fit";
    set("#fab-scale", t.scale === "fit" || t.scale === undefined ? "" : t.scale);
    set("#fab-margin", t.margin ?? "");
    set("#fab-strategy", t.strategy || "force");
    set("#fab-media", t.media || "");
    set("#fab-split", t.split === "auto" ? "auto" : "");
    for (const input of this.root.querySelectorAll("#fab-layers input")) {
      const tool = (t.layers || {})[input.dataset.layer] || {};
      set(`#${input.id}`, tool[input.dataset.key] ?? "");
    }
  }

  // --- the device's fields

  async loadDevice() {
    const name = $("#device").value;
    this.settings = name ? { device: name } : null;
    this.answer = null;
    if (!name) {
      this.buildFields();
      this.show();
      return this.studio.creases.view.draw();
    }
    const r = await this.studio.post("/api/device", { device: name });
    if ($("#device").value !== name) return;
    if (r.status !== 200) return this.info(r.json.error, true);
    this.settings = r.json;
    this.buildFields();
    this.refresh();
  }

  buildFields() {
    const s = this.settings && this.settings.layers ? this.settings : null;
    const strategy = $("#fab-strategy");
    strategy.innerHTML = (s ? s.strategies : ["force"]).map((k) => `<option>${k}</option>`).join("");
    const media = $("#fab-media");
    media.innerHTML = `<option value="">none</option>` +
      (s ? s.media.map((m) => `<option value="${m.name}" title="${m.description}">${m.name}</option>`).join("") : "");
    const table = $("#fab-layers");
    table.innerHTML = "";
    if (s) {
      const head = table.insertRow();
      head.innerHTML = `<th>layer</th>` + s.settings.map((k) => `<th>${SETTINGS[k]}</th>`).join("");
      for (const layer of ["valley", "mountain", "cut"]) {
        const row = table.insertRow();
        row.insertCell().textContent = layer;
        for (const key of s.settings) {
          const input = document.createElement("input");
          Object.assign(input, { type: "number", id: `fab-${layer}-${key}`, step: s.steps[key] || "any" });
          const [low, high] = s.ranges[key];
          if (low !== null) input.min = low;
          if (high !== null) input.max = high;
          input.title = `[fabrication.layers.${layer}].${key}` + (high !== null ? `: ${low} to ${high}` : "");
          Object.assign(input.dataset, { layer, key, field: `fabrication.layers.${layer}.${key}` });
          input.addEventListener("input", () => {
            const text = input.value.trim(), value = key === "passes" ? parseInt(text, 10) : parseFloat(text);
            input.classList.toggle("invalid", text !== "" && !Number.isFinite(value));
            if (text === "" || Number.isFinite(value)) this.setTool(layer, key, text === "" ? undefined : value);
          });
          input.addEventListener("change", () => this.studio.commit());
          row.insertCell().appendChild(input);
        }
      }
    }
    this.sync();
  }

  // --- placement and estimate

  /** Ask for the layout once the design is valid and no edit is pending (a drag asks once it
   * rests); one request in flight, the latest state wins. */
  async refresh() {
    if (!this.settings || !this.settings.layers || !$("#fabrication").open || this.studio.error || !this.studio.shown ||
        document.body.dataset.status === "busy") return;
    if (this.inflight) { this.again = true; return; }
    this.inflight = true;
    this.again = false;
    const t0 = performance.now(), epoch = this.studio.epoch, device = this.settings.device, applied = this.studio.applied;
    document.body.dataset.fabrication = "busy";
    let r;
    try {
      r = await this.studio.post("/api/fabrication", this.studio.base());
    } catch (error) {
      r = { status: 0, json: { error: `the studio server does not answer (${error.message})` } };
    }
    this.inflight = false;
    if (this.again) return this.refresh();
    if (epoch !== this.studio.epoch || device !== $("#device").value) return;
    this.answer = r.status === 200 ? { ...r.json, applied } : null;
    this.show(r.status === 200 ? null : r.json);
    const creases = this.studio.creases;
    if (creases.view.auto) creases.fit(); else creases.view.draw();
    this.count++;
    document.body.dataset.fabricationCount = String(this.count);
    document.body.dataset.fabrication = this.answer ? "ok" : "error";
    window.dispatchEvent(new CustomEvent("studio:fabrication", { detail: { ms: performance.now() - t0 } }));
  }

  show(error = null) {
    for (const el of this.root.querySelectorAll(".invalid")) el.classList.remove("invalid");
    const a = this.answer;
    if (error) {
      $("#fab-estimate").textContent = "";
      const field = error.cause && error.cause.field;
      if (field) for (const el of document.querySelectorAll(`[data-field="${field}"]`)) el.classList.add("invalid");
      return this.info(this.studio.brief(error.error), true);
    }
    if (!a) {
      $("#fab-estimate").textContent = "";
      return this.info(this.settings ? "" : "choose a device (top bar) for the sheet, the tools and the estimate");
    }
    const e = a.estimate, minutes = e.time_s >= 120 ? `${fmt(e.time_s / 60)} min` : `${fmt(e.time_s)} s`;
    $("#fab-estimate").textContent = `· ${minutes} · ${fmt(e.drawn_mm / 1000, 2)} m drawn` +
      (a.sheets.length > 1 ? ` · ${a.sheets.length} sheets` : "");
    for (const input of this.root.querySelectorAll("#fab-layers input")) {
      const tool = a.tools[input.dataset.layer];
      input.placeholder = tool && tool[input.dataset.key] !== null ? fmt(tool[input.dataset.key], 3) : "";
    }
    const [w, h] = a.sheets[0].sheet;
    this.info(`${a.device}: ${a.sheets.length} × ${fmt(w)} × ${fmt(h)} mm sheet, scale ${fmt(a.scale, 4)}` +
      `${a.scale_fitted ? " (fit)" : ""}${a.rotated ? ", turned" : ""} · estimate ${fmt(e.time_s)} s, ` +
      `${fmt(e.drawn_mm)} mm drawn, ${fmt(e.travel_mm)} mm travel, ${e.pen_lifts} pen lifts` +
      (a.warnings.length ? ` · warning: ${a.warnings[0]}` : ""));
  }

  info(text, bad = false) {
    const el = $("#fab-info");
    el.textContent = text;
    el.title = text;
    el.classList.toggle("bad", bad);
  }

  /** The crease view draws the sheets over the pattern and fits them too. */
  hookCreaseView() {
    const creases = this.studio.creases;
    const draw = creases.draw.bind(creases), fit = creases.fit.bind(creases);
    creases.draw = (view, ctx) => { draw(view, ctx); this.drawSheets(view, ctx); };
    creases.fit = () => {
      const shown = this.studio.shown;
      const sheets = this.sheets();
      if (!shown || !sheets.length) return fit();
      const box = [...shown.cpBox];
      for (const sheet of sheets) for (const [x, y] of sheet.outline) {
        box[0] = Math.min(box[0], x); box[1] = Math.min(box[1], y);
        box[2] = Math.max(box[2], x); box[3] = Math.max(box[3], y);
      }
      creases.view.fit(box, 0.04);
    };
  }

  /** The sheets to draw: the layout's, unless the design shown is newer and its fit places it whole. */
  sheets() {
    const shown = this.studio.shown, fit = shown && shown.fit;
    if (!this.settings || (fit && fit.device !== this.settings.device)) return [];
    if (this.answer && this.answer.applied === this.studio.applied) return this.answer.sheets;
    if (fit && fit.outline) return [{ number: 1, sheet: fit.sheet, outline: fit.outline, margin_outline: fit.margin_outline, piece: null }];
    return fit && fit.pieces && this.answer ? this.answer.sheets : [];   // split: the last layout until the new one
  }

  drawSheets(view, ctx) {
    const sheets = this.sheets();
    if (!sheets.length || !this.studio.shown) return;
    const path = (points) => {
      ctx.beginPath();
      points.forEach(([x, y], i) => { const [sx, sy] = view.toScreen(x, y); if (i) ctx.lineTo(sx, sy); else ctx.moveTo(sx, sy); });
      ctx.closePath();
    };
    ctx.save();
    for (const sheet of sheets) {
      if (sheet.piece) {
        const [x0, y0, x1, y1] = sheet.piece;
        path([[x0, y0], [x1, y0], [x1, y1], [x0, y1]]);
        ctx.fillStyle = PIECE_FILL[sheet.number % 2];
        ctx.fill();
      }
      path(sheet.outline);
      ctx.strokeStyle = "#2e7d32";
      ctx.lineWidth = 1.5;
      ctx.setLineDash([]);
      ctx.stroke();
      if (sheet.margin_outline) {
        path(sheet.margin_outline);
        ctx.setLineDash([5, 4]);
        ctx.lineWidth = 1;
        ctx.stroke();
      }
      const [sx, sy] = view.toScreen(...sheet.outline[3]);
      ctx.fillStyle = "#2e7d32";
      ctx.font = "11px system-ui, sans-serif";
      ctx.fillText(sheets.length > 1 ? `sheet ${sheet.number}` : `${fmt(sheet.sheet[0])} × ${fmt(sheet.sheet[1])} mm`,
        sx + 4, sy - 4);
    }
    ctx.restore();
  }

  // --- the printable template

  printPath() {
    if (!this.printAuto || document.activeElement === $("#print-path")) return;
    const name = $("#job-name").value.replace(/[^A-Za-z0-9._-]+/g, "-").replace(/^[-.]+|-+$/g, "") || "untitled";
    const job = $("#job-path").value, folder = job.includes("/") ? job.slice(0, job.lastIndexOf("/") + 1) : "";
    $("#print-path").value = `${folder}${name}.pdf`;
  }

  async print() {
    this.studio.message("writing the template…");
    const r = await this.studio.write("/api/print", { ...this.studio.base(), target: $("#print-path").value, paper: $("#print-paper").value });
    if (r.status === 409) return this.studio.message("not printed", true);
    if (r.status !== 200) return this.studio.message(this.studio.brief(r.json.error), true);
    const files = r.json.written;
    this.studio.message(`printed ${r.json.pages} pages of ${r.json.paper} to ${files.length > 1 ? `${files[0]} …` : files[0]}`);
    document.body.dataset.printed = files[0];
  }
}
