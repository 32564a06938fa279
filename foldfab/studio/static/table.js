// Numeric entry of polyline points: one row per point, drawn only while its <details> is open.

const MAX_ROWS = 400;

export class PointTable {
  /**
   * @param {HTMLTableElement} table
   * @param {string[]} columns
   * @param {{change: (i: number, values: number[]) => void, remove: (i: number) => void,
   *          select: (i: number) => void, commit: () => void}} handlers
   */
  constructor(table, columns, handlers) {
    this.table = table;
    this.columns = columns;
    this.h = handlers;
    this.last = { points: [], selected: -1, bad: -1, editable: true };
    this.details = table.closest("details");
    this.details.addEventListener("toggle", () => this.draw());
  }

  update(points, selected, bad, editable = true) {
    this.last = { points, selected, bad, editable };
    if (this.details.open) this.draw();
  }

  draw() {
    const { points, selected, bad, editable } = this.last;
    const width = points.length ? points[0].length : this.columns.length;
    const rows = Math.min(points.length, MAX_ROWS);
    if (this.table.rows.length !== rows + 1 || this.width !== width || this.editable !== editable) {
      this.build(rows, width, editable, points.length);
    }
    for (let i = 0; i < rows; i++) {
      const row = this.table.rows[i + 1];
      row.classList.toggle("selected", i === selected);
      row.classList.toggle("bad", i === bad);
      points[i].forEach((value, k) => {
        const input = row.cells[k + 1].firstChild;
        if (document.activeElement !== input) input.value = String(+value.toFixed(6));
      });
    }
  }

  build(rows, width, editable, total) {
    this.width = width;
    this.editable = editable;
    const head = `<tr><th>#</th>${this.columns.slice(0, width).map((c) => `<th>${c}</th>`).join("")}<th>${
      total > rows ? `first ${rows} of ${total}` : ""}</th></tr>`;
    this.table.innerHTML = head;
    for (let i = 0; i < rows; i++) {
      const row = this.table.insertRow();
      row.insertCell().textContent = i;
      for (let k = 0; k < width; k++) {
        const input = document.createElement("input");
        input.type = "number";
        input.step = "any";
        input.disabled = !editable;
        input.addEventListener("focus", () => this.h.select(i));
        input.addEventListener("change", () => this.h.commit());
        input.addEventListener("input", () => {
          const values = [...row.querySelectorAll("input")].map((el) => parseFloat(el.value));
          const ok = values.every(Number.isFinite);
          input.classList.toggle("invalid", !ok);
          if (ok) this.h.change(i, values);
        });
        row.insertCell().appendChild(input);
      }
      const cell = row.insertCell();
      if (editable) {
        const remove = document.createElement("button");
        remove.textContent = "✕";
        remove.title = "remove this point";
        remove.addEventListener("click", () => this.h.remove(i));
        cell.appendChild(remove);
      }
    }
  }
}
