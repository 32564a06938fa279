// File names the studio proposes: an export is named after the job's current name, in the job file's folder.

/** ``name`` as a file name: letters, digits, dots and dashes ("hexagon relief, Fig. 8" -> "hexagon-relief-Fig.-8"). */
export function fileStem(name) {
  return String(name || "").trim().replace(/[^\p{L}\p{N}._-]+/gu, "-").replace(/^[-.]+|-+$/g, "");
}

/** The export path for a job saved at ``jobPath`` and named ``name``, with suffix ``kind`` (".fold"). */
export function exportPath(jobPath, name, kind) {
  const path = jobPath || "untitled.toml";
  const slash = path.lastIndexOf("/");
  const folder = path.slice(0, slash + 1);
  const stem = fileStem(name) || path.slice(slash + 1).replace(/\.toml$/i, "") || "untitled";
  return folder + stem + kind;
}
