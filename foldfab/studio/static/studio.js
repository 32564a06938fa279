// foldfab studio: the job's tables are edited here and built by foldfab's core on the server.
// One design request is in flight at a time; edits made meanwhile are sent together when it
// returns, and a response for an older state (or an older file) is dropped.  Every applied
// response redraws all four views, then bumps <body data-render-count>.

import { ProfileView } from "./profile.js";
import { TrajectoryView } from "./trajectory.js";
import { CreaseView } from "./creases.js";
import { ModelView } from "./model.js";
import { FabricationPanel } from "./fabrication.js";
import { DryRun } from "./dryrun.js";
import { exportPath } from "./names.js";
import { unpack } from "./pack.js";

const TOKEN = document.querySelector('meta[name="foldfab-token"]').content;
const $ = (selector) => document.querySelector(selector);
const HISTORY = 200;

/** The binary design answer: magic, header length, JSON header, 8-byte aligned arrays. */
export function decode(buffer) {
  const { header, arrays: a } = unpack(buffer);
  const rows = (flat, width) => Array.from({ length: flat.length / width }, (_, i) => Array.from(flat.subarray(i * width, i * width + width)));
  const v = a.cp_vertices;
  const box = [Infinity, Infinity, -Infinity, -Infinity];
  for (let i = 0; i < v.length; i += 2) {
    if (v[i] < box[0]) box[0] = v[i]; if (v[i] > box[2]) box[2] = v[i];
    if (v[i + 1] < box[1]) box[1] = v[i + 1]; if (v[i + 1] > box[3]) box[3] = v[i + 1];
  }
  return {
    summary: header.summary, fit: header.fit, closed: header.closed, server: header.server_ms,
    edgeGroups: header.edge_groups,
    profile: rows(a.profile, 2), trajectoryPoints: rows(a.trajectory, 3), planes: a.planes,
    paths: a.paths, pathShape: header.arrays.paths.shape.slice(0, 2),
    cpVertices: v, cpBox: box, modelVertices: a.model_vertices, edges: a.edges, triangles: a.triangles,
    penetrating: a.penetrating, feasible: header.feasible,
  };
}

class Studio {
  constructor() {
    this.job = null;
    this.path = "";
    this.shown = null;        // the last valid design, decoded
    this.error = null;        // the current error answer, or null
    this.current = { profile: null, trajectory: null };   // polylines the core read for the current state
    this.version = 0;
    this.applied = 0;
    this.epoch = 0;
    this.inflight = false;
    this.dirty = false;
    this.editTimes = new Map();
    this.renderCount = 0;
    this.lastUpdate = null;
    this.history = [];
    this.at = -1;
    this.profile = new ProfileView(this, $("#view-profile"));
    this.trajectory = new TrajectoryView(this, $("#view-trajectory"));
    this.creases = new CreaseView(this, $("#view-creases"));
    this.model = new ModelView(this, $("#view-model"));
    this.fabrication = new FabricationPanel(this, $("#fabrication-panel"));
    this.dryrun = new DryRun(this);
    this.bind();
  }

  // --- the server

  async post(url, body) {
    const response = await fetch(url, {
      method: "POST", headers: { "Content-Type": "application/json", "X-Foldfab-Token": TOKEN },
      body: JSON.stringify(body),
    });
    const type = response.headers.get("Content-Type") || "";
    if (type.startsWith("application/octet-stream")) return { status: response.status, buffer: await response.arrayBuffer() };
    let json;
    try { json = await response.json(); } catch { json = { error: `${url}: HTTP ${response.status}` }; }
    return { status: response.status, json };
  }

  base() { return { job: this.job, path: this.path, device: $("#device").value, allow_penetration: $("#allow-penetration").checked }; }

  async start() {
    const response = await fetch("/api/state", { headers: { "X-Foldfab-Token": TOKEN } });
    const state = await response.json();
    if (!response.ok) throw new Error(state.error);
    const select = $("#device");
    for (const name of state.devices) select.add(new Option(name, name));
    const remembered = localStorage.getItem("foldfab-studio-device");
    if (remembered && state.devices.includes(remembered)) select.value = remembered;
    this.startDir = state.start_dir;
    this.load(state.job, state.path, state.display);
  }

  /** Show a job (a new file): fresh history, views refitted. */
  load(job, path, display) {
    this.job = job;
    this.path = path;
    this.epoch++;
    this.shown = null;
    this.error = null;
    this.current = { profile: null, trajectory: null };
    $("#job-path").value = display;
    this.exportTyped = false;
    this.setExportPath();
    this.history = [];
    this.at = -1;
    this.commit();
    for (const view of [this.profile.view, this.trajectory.view, this.creases.view]) {
      view.fitted = false;
      view.auto = true;
    }
    this.model.fitted = false;
    this.syncControls();
    this.edit();
  }

  /** The job changed: ask for the design (at most one request in flight). */
  edit() {
    this.version++;
    this.editTimes.set(this.version, performance.now());
    document.body.dataset.status = "busy";
    if (this.inflight) this.dirty = true; else this.send();
  }

  async send() {
    this.inflight = true;
    this.dirty = false;
    const version = this.version, epoch = this.epoch;
    let result;
    try {
      result = await this.post("/api/design", { ...this.base(), seq: version });
    } catch (error) {
      result = { status: 0, json: { error: `the studio server does not answer (${error.message}); is foldfab studio still running?`, cause: { view: "file" } } };
    }
    this.inflight = false;
    try {
      if (epoch === this.epoch && version > this.applied) this.apply(result, version);
    } catch (error) {
      console.error(error);
      this.message(`could not show the design: ${error.message}`, true);
    }
    for (const v of this.editTimes.keys()) if (v <= version) this.editTimes.delete(v);
    if (this.dirty) this.send();
  }

  apply(result, version) {
    const t0 = this.editTimes.get(version);
    this.applied = version;
    if (result.buffer) {
      this.shown = decode(result.buffer);
      this.error = null;
      this.current = { profile: this.shown.profile, trajectory: this.shown.trajectoryPoints };
    } else {
      this.error = result.json;
      if (!this.error.cause) this.error.cause = { view: "file" };
      if (result.json.polylines) this.current = { ...result.json.polylines };
    }
    this.renderAll();
    const drawn = performance.now() - t0;
    this.lastUpdate = { version, drawn, server: this.shown && !this.error ? this.shown.server : null };
    this.renderCount++;
    const body = document.body.dataset;
    body.renderCount = String(this.renderCount);
    body.status = this.error ? "error" : this.version === version ? "ok" : "busy";
    body.errorView = this.error ? this.error.cause.view : "";
    body.shownFaces = this.shown ? String(this.shown.summary.faces) : "";
    const update = this.lastUpdate;
    requestAnimationFrame(() => { update.frame = performance.now() - t0; });
    this.status(drawn);
    window.dispatchEvent(new CustomEvent("studio:rendered", { detail: update }));
  }

  renderAll() {
    this.profile.render();
    this.trajectory.render();
    this.creases.render();
    this.model.render();
    this.showError();
  }

  // --- what the views read

  profilePoints() { return this.job.profile.points || this.current.profile || []; }

  /** The profile's points to edit; a profile read from an SVG file becomes its drawn points. */
  editableProfile() {
    const profile = this.job.profile;
    if (!profile.points) {
      this.job.profile = { points: (this.current.profile || []).map((p) => [...p]), offset: profile.offset || [0, 0] };
    }
    return this.job.profile.points;
  }

  trajectoryPoints() {
    const t = this.job.trajectory;
    return Array.isArray(t.points) ? t.points : this.current.trajectory || [];
  }

  snapped([x, y]) {
    const step = parseFloat($("#snap-step").value);
    if (!$("#snap").checked || !(step > 0)) return [x, y];
    const s = (value) => +(Math.round(value / step) * step).toFixed(9) + 0;
    return [s(x), s(y)];
  }

  // --- undo

  commit() {
    const text = JSON.stringify(this.job);
    if (text === this.history[this.at]) return;
    this.history = this.history.slice(Math.max(0, this.at + 2 - HISTORY), this.at + 1);
    this.history.push(text);
    this.at = this.history.length - 1;
  }

  restore(step) {
    const at = this.at + step;
    if (at < 0 || at >= this.history.length) return;
    this.at = at;
    this.job = JSON.parse(this.history[at]);
    this.syncControls();
    this.profile.render();
    this.trajectory.render();
    this.edit();
  }

  // --- controls

  syncControls() {
    const job = this.job;
    const set = (selector, value) => { const el = $(selector); if (document.activeElement !== el) el.value = value; };
    set("#job-name", job.design.name || "");
    const [u, v] = job.profile.offset || [0, 0];
    set("#offset-u", u);
    set("#offset-v", v);
    const crease = job.crease || (job.crease = { flat_angle: 1, glue_tab: 0 });
    set("#flat-range", crease.flat_angle);
    set("#flat-angle", crease.flat_angle);
    set("#glue-tab", crease.glue_tab);
    this.trajectory.syncControls();
    this.fabrication.sync();
  }

  bindNumber(selectors, assign) {
    const elements = selectors.map((s) => $(s));
    for (const el of elements) {
      el.addEventListener("input", () => {
        const value = parseFloat(el.value);
        el.classList.toggle("invalid", !Number.isFinite(value));
        if (!Number.isFinite(value)) return;
        assign(value, el);
        for (const other of elements) if (other !== el && other.type === el.type) other.value = el.value;
        this.syncControls();
        this.edit();
      });
      el.addEventListener("change", () => this.commit());
    }
  }

  bind() {
    $("#job-name").addEventListener("input", (e) => { this.job.design.name = e.target.value; this.setExportPath(); this.edit(); });
    $("#export-path").addEventListener("input", () => { this.exportTyped = true; });
    $("#job-name").addEventListener("change", () => this.commit());
    this.bindNumber(["#offset-u", "#offset-v"], () => {
      this.job.profile.offset = [parseFloat($("#offset-u").value) || 0, parseFloat($("#offset-v").value) || 0];
      this.profile.render();
    });
    this.bindNumber(["#flat-range", "#flat-angle"], (value) => { this.job.crease.flat_angle = value; });
    this.bindNumber(["#glue-tab"], (value) => { this.job.crease.glue_tab = value; });
    $("#device").addEventListener("change", (e) => { localStorage.setItem("foldfab-studio-device", e.target.value); this.edit(); });
    $("#allow-penetration").addEventListener("change", () => this.edit());
    $("#export-kind").addEventListener("change", () => this.setExportPath());
    $("#open").addEventListener("click", () => this.open());
    $("#save").addEventListener("click", () => this.save());
    $("#save-anyway").addEventListener("click", () => this.save(true));
    $("#export").addEventListener("click", () => this.exportFile());
    $("#preview").addEventListener("click", () => this.preview());
    $("#queue").addEventListener("click", () => this.queue());
    $("#preview-close").addEventListener("click", () => $("#preview-dialog").close());
    $("#job-path").addEventListener("focus", () => this.listFiles());
    $("#job-path").addEventListener("keydown", (e) => { if (e.key === "Enter") this.open(); });
    window.addEventListener("keydown", (e) => {
      const key = e.key.toLowerCase();
      const typing = e.target.matches && e.target.matches("input, select, textarea");
      if ((e.ctrlKey || e.metaKey) && key === "s") { e.preventDefault(); this.save(); }
      else if ((e.ctrlKey || e.metaKey) && !typing && key === "z") { e.preventDefault(); this.restore(e.shiftKey ? 1 : -1); }
      else if ((e.ctrlKey || e.metaKey) && !typing && key === "y") { e.preventDefault(); this.restore(1); }
    });
  }

  /** The export field follows the job's name (and folder) until the user types a path of their own. */
  setExportPath() {
    const kind = $("#export-kind").value, field = $("#export-path");
    if (this.exportTyped) field.value = field.value.replace(/\.[^./]*$/, "") + kind;
    else field.value = exportPath($("#job-path").value, this.job && this.job.design.name, kind);
  }

  // --- status and errors

  status(drawn) {
    const text = $("#status-text");
    if (this.error) {
      text.textContent = `error: ${this.brief(this.error.error)}`;
    } else {
      const s = this.shown.summary;
      text.textContent = `${s.name}: ${s.corners} corners, ${s.line_elements} line elements, ${s.faces} faces` +
        (s.warnings.length ? ` · warning: ${s.warnings[0]}` : "");
    }
    text.title = text.textContent;
    const server = this.lastUpdate.server;
    $("#timing").textContent = `updated in ${drawn.toFixed(0)} ms` + (server ? ` (core ${server.total.toFixed(0)} ms)` : "");
  }

  brief(message) { return (message || "").replace(`${this.path}: `, ""); }

  showError() {
    for (const section of document.querySelectorAll(".view")) {
      section.classList.remove("has-error");
      section.querySelector(".error").textContent = "";
    }
    for (const el of document.querySelectorAll("[data-field].invalid")) el.classList.remove("invalid");
    if (!this.error) return;
    const cause = this.error.cause;
    const section = document.querySelector(`.view[data-view="${cause.view}"]`);
    if (section) {
      section.classList.add("has-error");
      section.querySelector(".error").textContent = this.brief(this.error.error);
    } else {
      this.message(this.brief(this.error.error), true);
    }
    if (cause.field) for (const el of document.querySelectorAll(`[data-field="${cause.field}"]`)) el.classList.add("invalid");
  }

  message(text, error = false) {
    const el = $("#file-message");
    el.textContent = text;
    el.title = text;
    el.classList.toggle("error", error);
  }

  // --- files, dry run, queue

  async listFiles() {
    const r = await this.post("/api/files", { path: this.path });
    if (r.status !== 200) return;
    const list = $("#job-files");
    list.innerHTML = "";
    for (const name of r.json.files) list.appendChild(new Option(name));
  }

  /** POST with the file rule's question: an existing file is replaced only after the user agrees. */
  async write(url, body) {
    let r = await this.post(url, { ...body, overwrite: false });
    if (r.status === 409 && window.confirm(r.json.error)) r = await this.post(url, { ...body, overwrite: true });
    return r;
  }

  async open() {
    const r = await this.post("/api/open", { target: $("#job-path").value, path: this.path });
    if (r.status !== 200) return this.message(this.brief(r.json.error), true);
    this.load(r.json.job, r.json.path, r.json.display);
    this.message(`opened ${r.json.display}`);
  }

  /** Save; a job `foldfab design` refuses is saved only ``anyway`` (with the reason in a comment). */
  async save(anyway = false) {
    $("#save-anyway").hidden = true;
    const r = await this.write("/api/save", { job: this.job, path: this.path, target: $("#job-path").value, anyway });
    if (r.status === 409) return this.message("not saved", true);
    if (r.status !== 200) {
      $("#save-anyway").hidden = !r.json.refused;
      return this.message(this.brief(r.json.error), true);
    }
    this.path = r.json.path;
    this.job = r.json.job;
    this.commit();
    $("#job-path").value = r.json.display;
    this.setExportPath();
    this.message(`saved ${r.json.written}` + (r.json.refused ? " although 'foldfab design' refuses it" : ""));
    document.body.dataset.saved = r.json.written;
    this.syncControls();
    this.edit();
  }

  async exportFile() {
    const r = await this.write("/api/export", { ...this.base(), target: $("#export-path").value });
    if (r.status === 409) return this.message("not exported", true);
    if (r.status !== 200) return this.message(this.brief(r.json.error), true);
    this.message(`exported ${r.json.kind.toUpperCase()} to ${r.json.written}`);
  }

  async preview() {
    this.message("building the program…");
    const r = await this.post("/api/preview", this.base());
    if (r.status !== 200) return this.message(this.brief(r.json.error), true);
    const d = r.json;
    const url = URL.createObjectURL(new Blob([d.svg], { type: "image/svg+xml" }));
    const body = $("#preview-body");
    for (const img of body.querySelectorAll("img")) URL.revokeObjectURL(img.src);
    body.innerHTML = "";
    const img = new Image();
    img.alt = "dry-run preview";
    img.src = url;
    body.appendChild(img);
    this.dryrun.show(d, body);
    $("#preview-info").textContent = `${d.device} · ${d.strategy} · sheet ${d.sheet[0]} × ${d.sheet[1]} mm · program ${d.program_bytes} bytes`;
    $("#preview-dialog").showModal();
    this.message(`dry run for ${d.device}`);
  }

  async queue() {
    const copies = parseInt($("#copies").value, 10) || 1;
    const r = await this.post("/api/queue", { ...this.base(), port: $("#port").value, copies });
    if (r.status !== 200) return this.message(this.brief(r.json.error), true);
    const ids = r.json.ids;
    this.message(`queued ${ids.length > 1 ? `jobs ${ids[0]}–${ids.at(-1)}` : `job ${ids[0]}`} on ${r.json.device} ${r.json.where} (${r.json.queue})`);
  }
}

const studio = new Studio();
window.studio = studio;
studio.start().catch((error) => {
  document.body.dataset.status = "error";
  $("#status-text").textContent = `the studio could not start: ${error.message}`;
});
