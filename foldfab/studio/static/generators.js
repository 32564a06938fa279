// Profile tools: sine, arc and spline generators and smoothing.  The points are made on the server
// (foldfab.geometry.profiles, the same code for every caller) and clamped there into the band where
// the trajectory leaves them room, so a generated profile is always a valid design.

const KINDS = {
  sine: "sine wave", arc: "arcs", spline: "spline through the points", smooth: "smooth the points",
};

export class ProfileTools {
  constructor(profileView) {
    this.view = profileView;
    this.studio = profileView.studio;
    const footer = profileView.section.querySelector("footer");
    const details = document.createElement("details");
    details.className = "tools";
    details.innerHTML = `<summary>generate</summary>
      <div class="generator">
        <select id="gen-kind" title="What to make">${Object.entries(KINDS).map(([k, name]) => `<option value="${k}">${name}</option>`).join("")}</select>
        <label title="How far the wave or arc reaches from u = 0 (mm; negative: inwards)">amplitude <input type="number" id="gen-amplitude" value="5" step="any" class="short"></label>
        <label title="Height of one wave or arc (mm)">period <input type="number" id="gen-period" value="20" min="0" step="any" class="short"></label>
        <label title="Number of points to make">points <input type="number" id="gen-points" value="41" min="2" max="2000" step="1" class="short"></label>
        <label title="Height of the profile (mm); empty: the current profile's">height <input type="number" id="gen-height" min="0" step="any" class="short" placeholder="same"></label>
        <label title="Smoothing rounds (smooth)">rounds <input type="number" id="gen-passes" value="3" min="1" max="1000" step="1" class="short"></label>
        <button id="gen-make">make</button>
      </div>`;
    footer.appendChild(details);
    details.querySelector("#gen-make").addEventListener("click", () => this.make());
  }

  value(id) { return this.view.section.querySelector(id).value; }

  /** Replace the profile's points with the generator's (an undoable edit). */
  async make() {
    const number = (id, fallback) => { const v = parseFloat(this.value(id)); return Number.isFinite(v) ? v : fallback; };
    const body = {
      job: this.studio.job, path: this.studio.path, kind: this.value("#gen-kind"),
      amplitude: number("#gen-amplitude", 5), period: number("#gen-period", 20),
      points: Math.round(number("#gen-points", 41)), passes: Math.round(number("#gen-passes", 3)),
    };
    const height = parseFloat(this.value("#gen-height"));
    if (Number.isFinite(height)) body.height = height;
    const r = await this.studio.post("/api/generate-profile", body);
    if (r.status !== 200) return this.studio.message(this.studio.brief(r.json.error), true);
    this.studio.editableProfile();
    this.studio.job.profile.points = r.json.points;
    this.view.selected = -1;
    this.view.view.fitted = false;   // show the whole new profile
    this.studio.edit();
    this.studio.commit();
    this.view.render();
    this.studio.message(`made a ${KINDS[body.kind]} of ${r.json.points.length} points, kept inside the shaded band`);
  }
}
