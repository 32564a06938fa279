// Template edits that keep the design valid: before a new template or a moved slider is built,
// the server (foldfab.geometry.feasible.fit_template, the rule of the "meets ... before ..."
// error) grows the template just enough for the profile, or stops a size slider at its limit.

let ticket = 0;

/**
 * Ask the server for sizes that fit, apply them to the trajectory the user is editing, then build.
 * ``changed`` is what moved ("template" or a parameter), ``previous`` its last value.
 * An answer for an older edit, or for another trajectory, is dropped.
 */
export async function keepValid(trajectoryView, changed, previous) {
  const studio = trajectoryView.studio;
  const mine = ++ticket;
  const spec = studio.job.trajectory;
  const asked = JSON.stringify(spec);
  studio.fitting = true;
  let r;
  try {
    r = await studio.post("/api/fit-template", { job: studio.job, path: studio.path, changed, previous });
  } catch (error) {
    r = { status: 0 };
  }
  if (mine !== ticket) return;
  studio.fitting = false;
  if (studio.job.trajectory !== spec || JSON.stringify(spec) !== asked) return;   // edited meanwhile
  if (r.status === 200) {
    Object.assign(spec, r.json.trajectory);
    trajectoryView.lastFit = { ...r.json.trajectory };
    for (const [key, value] of Object.entries(r.json.trajectory)) {
      for (const input of trajectoryView.section.querySelectorAll(`[data-field="trajectory.${key}"]`)) {
        if (input.tagName === "INPUT") input.value = value;
      }
    }
    if (r.json.note) studio.message(r.json.note);
  }
  studio.edit();
  trajectoryView.render();
}
